// horus::detail::ErasedTopic: horus::Topic<T> with the type known only at run time (a Python
// message class, a topic the DDS bridge or the remote link carries), moving bytes. Both run their
// slots through detail::TopicEndpoint, so an erased handle and a C++ Topic<T> handle share one
// segment as two C++ handles would.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "horus/detail/ring.hpp"
#include "horus/detail/topic_endpoint.hpp"
#include "horus/topic.hpp"

namespace horus::detail {

/// The identity of a message type as the Python class carries it (`T.__horus__`); owns its text.
struct ErasedType {
  std::string name;
  std::uint64_t fingerprint = 0;
  std::string schema;
  bool is_pod = false;
  std::size_t size = 0;  // POD only
  std::size_t alignment = 1;
};

class ErasedTopic {
 public:
  /// Opens (or creates) `name` for `type`; throws horus::Error as Topic<T> does (another type,
  /// a corrupt segment, no room).
  ErasedTopic(std::string name, ErasedType type, const TopicOptions& options);
  ErasedTopic(const ErasedTopic&) = delete;
  ErasedTopic& operator=(const ErasedTopic&) = delete;
  ~ErasedTopic() { release_loan(); }

  const std::string& name() const noexcept { return name_; }
  const ErasedType& type() const noexcept { return type_; }

  /// Publishes `bytes` (a POD message's exact size, or an encoded serialized one). False (and a
  /// counter) when nothing was published.
  bool send(std::span<const std::byte> bytes) noexcept;

  /// Claims a slot for writing a POD message in place; the payload (the slot, or a private spare
  /// when the ring refused one). Only one loan at a time per handle.
  std::byte* loan() noexcept;
  /// Commits the loan (true), or counts the failure of a loan that got no slot (false).
  bool publish() noexcept;
  /// Releases an unpublished loan without sending anything.
  void release_loan() noexcept;
  bool loaned() const noexcept { return loaned_; }

  /// The next message's bytes into the receive buffer; its size, or -1 when there is none.
  std::ptrdiff_t try_recv() noexcept;
  /// As try_recv(), waiting up to `timeout` asleep on the topic's futex.
  std::ptrdiff_t recv(std::chrono::nanoseconds timeout) noexcept;
  /// The newest message ever sent into the receive buffer; its size, or -1.
  std::ptrdiff_t read_latest() noexcept;
  /// What the last successful receive left (valid until the next receive).
  std::span<std::byte> received(std::size_t size) noexcept { return {buffer_.data(), size}; }
  /// The ticket of the message try_recv() or recv() took last: its sequence on the topic.
  std::uint64_t received_ticket() const noexcept { return endpoint_.next_ticket() - 1; }

  bool has_msg() const noexcept { return endpoint_.has_msg(); }
  TopicStats stats() const noexcept { return endpoint_.stats(); }
  std::size_t capacity() const noexcept {
    return static_cast<std::size_t>(endpoint_.ring().capacity());
  }
  std::size_t payload_capacity() const noexcept { return endpoint_.ring().payload_capacity; }

 private:
  std::ptrdiff_t receive(bool check_stall) noexcept;
  /// Copies a message of the right size out of its slot into the receive buffer.
  bool copy_received(const std::byte* payload, std::uint32_t size) noexcept;

  std::string name_;
  ErasedType type_;
  detail::TopicEndpoint endpoint_;
  std::vector<std::byte> buffer_;
  std::vector<std::byte> spare_;
  detail::Claim loan_{nullptr, 0, false, false};
  bool loaned_ = false;
};

}  // namespace horus::detail
