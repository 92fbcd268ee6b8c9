// The right to publish on a single-publisher topic (TopicOptions::single_publisher).
#pragma once

#include <cstdint>

#include "horus/detail/ring.hpp"

namespace horus::detail {

/// Held by at most one Topic handle of a single-publisher topic at a time; released when the
/// handle is destroyed. The handle of a process that died (kill -9) loses it to the next handle
/// that asks, which continues the topic's tickets where the dead one stopped.
class PublisherLease {
 public:
  PublisherLease() = default;
  PublisherLease(PublisherLease&& other) noexcept;
  PublisherLease& operator=(PublisherLease&& other) noexcept;
  PublisherLease(const PublisherLease&) = delete;
  PublisherLease& operator=(const PublisherLease&) = delete;
  ~PublisherLease();

  /// Only in the process that took it: a forked child's copy of the handle holds nothing.
  bool held() const noexcept {
    return control_ != nullptr && static_cast<std::uint32_t>(token_ >> 32) == this_pid();
  }
  /// Takes the lease of `ring` unless a handle in a live process holds it; on success also
  /// marks `ring` fence-free when this process is covered by the sleepers' membarrier.
  bool acquire(RingView& ring) noexcept;
  /// The ticket to write next (only while held).
  std::uint64_t take_ticket() noexcept { return next_ticket_++; }

 private:
  void release() noexcept;

  RingControl* control_ = nullptr;
  std::uint64_t token_ = 0;
  std::uint64_t next_ticket_ = 0;
};

}  // namespace horus::detail
