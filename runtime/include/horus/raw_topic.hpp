// horus::RawTopic: a topic opened by name with its message type known only at run time, moving
// bytes. The seam for everything that carries messages without compiling their types: the Python
// binding (a Python message class), bridges and the remote link (a type learnt from a peer),
// recorders and tools. A RawTopic and a C++ Topic<T> of the same type share one segment as two
// Topic<T> handles would: both run their slots through the same endpoint code, and the segment
// checks the type identity (name and fingerprint) of every opener.
//
// Frames of pool-backed types (Image, ...) are descriptors naming pool blocks; horus::PoolFrames
// (pool_frames.hpp) turns them into bytes that stand alone and back.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "horus/detail/ring.hpp"
#include "horus/detail/topic_endpoint.hpp"
#include "horus/topic.hpp"
#include "horus/topic_stats.hpp"
#include "horus/type_info.hpp"

namespace horus {

/// The identity of a message type, owning its text: what a segment records about the type it
/// carries, what the generated Python class carries (`T.__horus__`), what a peer sends.
struct TypeIdentity {
  /// "pkg.Name".
  std::string name;
  /// Hash of the canonical schema; two types are the same when name and fingerprint are.
  std::uint64_t fingerprint = 0;
  /// Canonical schema text of the type and every type it uses (human-readable).
  std::string schema;
  /// Raw struct bytes on the wire (true) or MessagePack (false).
  bool is_pod = false;
  /// sizeof(T), the wire size of every message of a POD type; 0 for a serialized one.
  std::size_t size = 0;
  std::size_t alignment = 1;
  /// The type description (MessagePack, format "horus.typedesc": the type and every type it uses,
  /// fields with offsets, defaults and units). Every type HORUS generates or defines has one;
  /// empty only when a raw opener gives none, and readers then refuse to walk the messages.
  std::string description{};
};

/// The TypeIdentity of a generated message type (or a plain value a Topic<T> carries).
template <class T>
TypeIdentity type_identity() {
  TypeIdentity identity;
  identity.name = TypeInfo<T>::name;
  identity.fingerprint = TypeInfo<T>::fingerprint;
  identity.schema = TypeInfo<T>::schema;
  identity.is_pod = TypeInfo<T>::is_pod;
  identity.size = TypeInfo<T>::is_pod ? sizeof(T) : 0;
  identity.alignment = alignof(T);
  identity.description = std::string(std::string_view(TypeInfo<T>::description));
  return identity;
}

struct TopicInfo;

/// The type a topic's segment records (a TopicInfo of list_topics()), as a TypeIdentity: what a
/// tool or bridge opens the topic with when it knows the topic only by its segment.
TypeIdentity type_identity_of(const TopicInfo& info);

/// What a waiter outside the handle sleeps on until the topic has a message for it
/// (RawTopic::begin_wait): an event loop's io_uring futex wait, futex_waitv beside other words.
struct TopicWaitWord {
  /// The topic's futex word, 32 bits in memory shared between processes: wait on it as a shared
  /// futex (without FUTEX_PRIVATE_FLAG or FUTEX2_PRIVATE), which a publisher's FUTEX_WAKE reaches.
  const std::atomic<std::uint32_t>* word;
  /// The value to sleep on: the futex wait compares it, so a send since begin_wait (which
  /// changed the word) ends the wait at once rather than being missed.
  std::uint32_t expected;
  /// Zero: a send wakes the sleeper. Otherwise a message already on its way may arrive without
  /// a wake-up (a publisher that took its ticket before the announcement): sleep at most this
  /// long, then end the wait and look again, as recv() does.
  std::chrono::nanoseconds recheck_after;
};

class RawTopic {
 public:
  /// Opens (or creates) `name` for `type`; throws horus::Error as Topic<T> does (another type,
  /// a corrupt segment, no room).
  RawTopic(std::string name, TypeIdentity type, const TopicOptions& options);
  /// Opens the topic `info` describes (a TopicInfo of list_topics(namespace_name)) with the type,
  /// capacity and slot size its segment records; throws horus::Error as the constructor does
  /// (the topic was recreated with another type meanwhile, ...).
  static std::unique_ptr<RawTopic> open_recorded(const TopicInfo& info,
                                                 const std::string& namespace_name);
  RawTopic(const RawTopic&) = delete;
  RawTopic& operator=(const RawTopic&) = delete;
  ~RawTopic() {
    end_wait();
    release_loan();
  }

  const std::string& name() const noexcept { return name_; }
  const TypeIdentity& type() const noexcept { return type_; }

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
  /// The first half of recv()'s slow path, for a waiter that sleeps by its own means (an event
  /// loop): announces this handle as a sleeper, so that publishers wake the topic's futex, with
  /// recv()'s barrier, then looks at the ring once more. Empty when there is something to read
  /// now (try_recv() until it returns -1, then begin again); nothing stays announced then.
  /// Otherwise sleep on the word, then call end_wait() and read: whatever a publisher commits
  /// after this call either changes the word before the sleep (the wait returns at once) or
  /// wakes it. Non-blocking, no allocation. A begin_wait() while one is begun ends that one
  /// first; a handle waits once at a time, and not beside a recv() of its own.
  std::optional<TopicWaitWord> begin_wait() noexcept;
  /// Withdraws begin_wait()'s announcement once the sleep ended (woken, timed out, cancelled):
  /// left in place, it would make every send pay a futex wake. Does nothing when none is held;
  /// the destructor calls it.
  void end_wait() noexcept;

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
  TypeIdentity type_;
  detail::TopicEndpoint endpoint_;
  std::vector<std::byte> buffer_;
  std::vector<std::byte> spare_;
  detail::Claim loan_{nullptr, 0, false, false};
  bool loaned_ = false;
  /// A counted sleeper announcement of begin_wait() is held.
  bool waiting_ = false;
};

}  // namespace horus
