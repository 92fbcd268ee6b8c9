// The publisher lease: while one handle publishes on a topic, it numbers the tickets itself.
#pragma once

#include <atomic>
#include <cstdint>

#include "horus/detail/ring.hpp"

namespace horus::detail {

/// Registers this process for the sleepers' membarrier now rather than when its first lease is
/// taken (a topic's first send): the registration takes milliseconds, which a scheduler spends
/// before its clock starts instead of inside a node's first tick. Once per process.
void prepare_publisher_leases() noexcept;

/// Held by at most one Topic handle of a topic at a time; released when the handle is
/// destroyed. Its holder claims slots with plain stores: no read-modify-write per message. The
/// handle of a process that died (kill -9) loses it to the next handle that asks, which
/// continues the topic's tickets where the dead one stopped. On a topic not created for a single
/// publisher, a second handle that sends shares the ring (ring_share): the lease is then let go
/// for good and every publisher claims tickets from write_index.
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
  /// Takes the lease of `ring` unless a handle in a live process holds it or the ring is shared;
  /// on success also marks `ring` fence-free when this process is covered by the sleepers'
  /// membarrier.
  bool acquire(RingView& ring) noexcept;

  /// Claims the holder's next ticket (only while held). The ticket is announced before the
  /// holder looks at the lease word, so whoever shares the ring learns which tickets the holder
  /// may still write (ring_share). When the ring was shared meanwhile, the lease is let go and
  /// the claim is a shared one (ring_claim), unless the ticket was announced in time and so is
  /// still this holder's to write. Always inlined: returned from a call, the claim was copied
  /// whole, and wide loads of the narrow stores just made stall until those stores retire (that
  /// doubled the cost of a send, bench/topic).
  [[gnu::always_inline]] Claim claim(RingView& ring) noexcept {
    const std::uint64_t ticket = next_ticket_;
    RingControl& control = *control_;
    bool still_held = false;
    if (ring.fence_free) {
      control.lease_announce.store(ticket + 1, std::memory_order_relaxed);
      std::atomic_signal_fence(std::memory_order_seq_cst);
      still_held = control.publisher_lease.load(std::memory_order_relaxed) == token_;
    } else {
      control.lease_announce.store(ticket + 1, std::memory_order_seq_cst);
      still_held = control.publisher_lease.load(std::memory_order_seq_cst) == token_;
    }
    if (still_held) {
      ++next_ticket_;
      return ring_claim_leased(ring, ticket);
    }
    return let_go(ring, ticket);
  }

 private:
  Claim let_go(RingView& ring, std::uint64_t ticket) noexcept;
  void release() noexcept;

  RingControl* control_ = nullptr;
  std::uint64_t token_ = 0;
  std::uint64_t next_ticket_ = 0;
};

/// Shares the ring among all publishers, for a handle that wants to send while another live
/// handle holds the lease (the first time only; later calls just learn the base). Marks the
/// lease word kLeaseShared, waits out the holder's announcement with a barrier on the holder's
/// CPU (membarrier, when the holder relies on it), and proposes the holder's announced ticket
/// as the first that write_index numbers. False when that barrier failed while the holder runs:
/// the holder, seeing the mark, then shares the ring at its next send or when its handle is
/// destroyed, and until then this handle's sends fail (counted in send_failures). A holder that
/// has exited needs no barrier.
bool ring_share(RingView& ring) noexcept;

}  // namespace horus::detail
