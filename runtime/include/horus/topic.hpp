// horus::Topic<T>: a named, typed channel between threads and processes over shared memory.
// How the segment and the slots work: runtime/src/transport/README.md.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/codec.hpp"
#include "horus/detail/process.hpp"
#include "horus/detail/publisher_lease.hpp"
#include "horus/detail/ring.hpp"
#include "horus/detail/send_clock.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/detail/slot_copy.hpp"
#include "horus/detail/topic_stream.hpp"
#include "horus/msgpack.hpp"
#include "horus/plain_value.hpp"
#include "horus/type_info.hpp"

namespace horus {

/// How a topic is created. Only the creator's options apply: a later opener adopts the segment.
struct TopicOptions {
  /// Messages kept for subscribers (rounded up to a power of two). A subscriber that falls
  /// further behind loses the oldest and counts them in lost().
  std::size_t capacity = 64;
  /// Serialized types only: the largest encoded message a slot holds; send() of a larger one
  /// returns false and counts it in TopicStats::oversized.
  std::size_t max_message_size = std::size_t{16} * 1024;
  /// Permissions of the segment (and of the namespace folder, when this creates it). Group bits
  /// (e.g. 0660) share the topic with a group: then segments and folders other members created
  /// are accepted too (runtime/src/transport/README.md). Write access for every user is refused.
  unsigned mode = 0600;
  /// Empty: HORUS_NAMESPACE, or "default".
  std::string namespace_name{};
  /// Only one handle at a time may publish (the first to send; another may take over once it is
  /// destroyed or its process died); sends from other handles fail and count in
  /// TopicStats::not_the_publisher. Without it, any number of handles publish: the first one
  /// alone sends as fast as this (its sends take no atomic read-modify-write, which waits for a
  /// cross-core round trip while a subscriber keeps up, bench/topic/RESULTS.md), until a second
  /// handle sends; from then on every send claims its slot with two. Either way, while one
  /// handle publishes alone, a blocking receiver pays a membarrier(2) each time it goes to sleep.
  bool single_publisher = false;
};

/// Per-handle counters: nothing fails silently.
struct TopicStats {
  /// Messages this handle never received because it fell more than `capacity` behind
  /// (or their publisher died while writing them).
  std::uint64_t lost = 0;
  /// send()/publish() calls that published nothing (oversized, or the slot was held by a
  /// publisher stalled for a whole lap of the ring).
  std::uint64_t send_failures = 0;
  /// The part of send_failures due to messages over max_message_size.
  std::uint64_t oversized = 0;
  /// The part of send_failures on a single-publisher topic whose lease another live handle
  /// holds.
  std::uint64_t not_the_publisher = 0;
  /// Received slots whose content did not decode as T (a corrupted segment).
  std::uint64_t invalid = 0;
};

template <TopicValue T>
class Topic;

/// A slot of a POD topic lent for writing in place (zero copy); give it back with
/// Topic::publish(). Its content is unspecified (an old message): write every field.
/// Dropping it unpublished releases the slot without sending anything. It must not outlive
/// its Topic nor be held while its Topic is moved, and while it is held the ring cannot reuse
/// its slot.
template <TopicValue T>
class Loan {
  static_assert(PodTopicValue<T>, "only POD messages can be written in place");

 public:
  Loan(Loan&& other) noexcept : claim_(other.claim_), ring_(other.ring_), data_(other.data_) {
    other.claim_.slot = nullptr;
    other.claim_.wake = false;
  }
  Loan& operator=(Loan&&) = delete;
  Loan(const Loan&) = delete;
  Loan& operator=(const Loan&) = delete;
  ~Loan() { finish(detail::kReleasedSlot); }

  T& operator*() const noexcept { return *data_; }
  T* operator->() const noexcept { return data_; }

 private:
  friend class Topic<T>;
  // The claim is built in place and finish() reads it field by field: copying it whole (16-byte
  // loads of 8-byte stores just made) stalled every loan until the slot's cache line arrived.
  // The ring is the Topic's own, not a copy: while the subscriber holds the lines of the last
  // message, every store of a send waits in a full store buffer, and a copy is ten more.
  template <class MakeClaim>
  Loan(const detail::RingView& ring, MakeClaim&& make_claim, T* spare) noexcept
      : claim_(make_claim()),
        ring_(&ring),
        data_(claim_.slot != nullptr ? reinterpret_cast<T*>(ring.payload(*claim_.slot)) : spare) {}

  /// Commits the slot with `size` bytes (or releases it); whether a message was published.
  bool finish(std::uint32_t size) noexcept {
    if (claim_.slot != nullptr) {
      detail::ring_commit(*ring_, claim_, size, detail::send_stamp_s());
      claim_.slot = nullptr;
      claim_.wake = false;
      return size != detail::kReleasedSlot;
    }
    detail::ring_refused(*ring_, claim_);
    claim_.wake = false;
    return false;
  }

  detail::Claim claim_;
  const detail::RingView* ring_;
  T* data_;
};

/// One handle on a topic: it can send and receive. Every handle sees every message sent after
/// it opened, in order. A handle is used by one thread at a time; open one per thread.
template <TopicValue T>
class Topic {
 public:
  /// Opens (or creates) the topic `name` in the namespace. Throws horus::Error when the topic
  /// carries another type, its segment is corrupt, /dev/shm has no room, or its folder or
  /// segment belongs to another user (outside a shared group) or is writable by every user.
  explicit Topic(std::string_view name, const TopicOptions& options = {})
      : name_(name),
        segment_(detail::ShmSegment::open_topic(
            name,
            detail::TypeDescriptor{TypeInfo<T>::name, TypeInfo<T>::fingerprint, TypeInfo<T>::schema,
                                   TypeInfo<T>::is_pod, TypeInfo<T>::is_pod ? sizeof(T) : 0,
                                   alignof(T)},
            detail::SegmentOptions{options.capacity, options.max_message_size, options.mode,
                                   options.namespace_name, options.single_publisher})),
        ring_(segment_.ring()) {
    cursor_.next = detail::ring_written(ring_);
    if constexpr (PodTopicValue<T>) {
      spare_ = std::make_unique<T>();
    } else {
      buffer_.resize(ring_.payload_capacity);
    }
  }

  Topic(Topic&&) noexcept = default;
  /// Not member-wise: the old segment would be unmapped before the old lease is given back.
  Topic& operator=(Topic&& other) noexcept {
    if (this != &other) {
      std::destroy_at(this);
      std::construct_at(this, std::move(other));
    }
    return *this;
  }

  const std::string& name() const noexcept { return name_; }

  /// Publishes a copy of `msg`. Never blocks; false (and a counter) when nothing was published.
  bool send(const T& msg) noexcept {
    mark(detail::kRolePublisher);
    const std::uint32_t sent = detail::send_stamp_s();
    const detail::Claim claim = claim_slot();
    if (claim.slot == nullptr) {
      detail::ring_refused(ring_, claim);
      ++stats_.send_failures;
      return false;
    }
    std::byte* payload = ring_.payload(*claim.slot);
    if constexpr (PodTopicValue<T>) {
      detail::copy_to_slot<sizeof(T)>(payload, &msg);
      detail::ring_commit(ring_, claim, sizeof(T), sent);
      return true;
    } else {
      detail::FixedBufferStream stream(payload, ring_.payload_capacity);
      msgpack::packer<detail::FixedBufferStream> packer(stream);
      packer.pack(msg);
      if (stream.overflowed()) {
        detail::ring_commit(ring_, claim, detail::kReleasedSlot, sent);
        ++stats_.send_failures;
        ++stats_.oversized;
        return false;
      }
      detail::ring_commit(ring_, claim, static_cast<std::uint32_t>(stream.size()), sent);
      return true;
    }
  }

  /// Lends the next slot for writing the message in place. Publish it with publish().
  /// When the ring refuses the slot, the caller writes into a private spare and publish()
  /// reports it.
  Loan<T> loan() noexcept requires PodTopicValue<T> {
    mark(detail::kRolePublisher);
    return Loan<T>(
        ring_, [this] { return claim_slot(); }, spare_.get());
  }

  /// Makes a loaned message visible. False (and a counter) when the loan had no slot.
  bool publish(Loan<T>&& loan) noexcept requires PodTopicValue<T> {
    if (loan.finish(sizeof(T))) {
      return true;
    }
    ++stats_.send_failures;
    return false;
  }

  /// The next message for this handle, if one is there. Never blocks.
  std::optional<T> try_recv() noexcept(PodTopicValue<T>) {
    std::optional<T> msg;
    receive(msg, false);
    return msg;
  }

  /// The next message, waiting up to `timeout` for one (asleep on a futex, no polling).
  std::optional<T> recv(std::chrono::nanoseconds timeout) noexcept(PodTopicValue<T>) {
    // One result object on every path: returning two different ones would copy a large message.
    std::optional<T> msg;
    receive(msg, false);
    if (msg) {
      return msg;
    }
    detail::RingControl& control = *ring_.control;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const std::uint32_t seen = control.notify.load(std::memory_order_seq_cst);
      const std::uint64_t claimed_before = segment_.announce_sleeper();
      const bool announced = detail::ring_sleeper_barrier(control);
      receive(msg, true);
      const auto remaining = deadline - std::chrono::steady_clock::now();
      if (!msg && remaining > std::chrono::nanoseconds::zero()) {
        // A ticket claimed before this thread announced itself may still be in flight, and its
        // publisher will not wake us: only then sleep in short slices.
        const bool unannounced =
            claimed_before == UINT64_MAX || !announced || cursor_.next < claimed_before;
        detail::futex_wait(
            control.notify, seen,
            unannounced ? std::min<std::chrono::nanoseconds>(remaining, kSlice) : remaining);
      }
      if (claimed_before != UINT64_MAX) {
        segment_.withdraw_sleeper();
      }
      if (msg || remaining <= std::chrono::nanoseconds::zero()) {
        return msg;
      }
    }
  }

  /// Whether try_recv() would find something (a message, or news that some were lost).
  bool has_msg() const noexcept { return detail::ring_ready(ring_, cursor_); }

  /// The newest message ever sent on the topic (not only since this handle opened); does not
  /// move this handle's position.
  std::optional<T> read_latest() const noexcept(PodTopicValue<T>) {
    if constexpr (PodTopicValue<T>) {
      std::optional<T> msg;
      if (detail::ring_read_latest(ring_, [&](const std::byte* payload, std::uint32_t size) {
            if (size != sizeof(T)) {
              return false;
            }
            msg.emplace(*std::launder(reinterpret_cast<const T*>(payload)));
            return true;
          })) {
        return msg;
      }
      return std::nullopt;
    } else {
      std::vector<std::uint8_t> bytes(ring_.payload_capacity);
      std::size_t length = 0;
      if (!detail::ring_read_latest(ring_, [&](const std::byte* payload, std::uint32_t size) {
            if (size > bytes.size()) {
              return false;
            }
            std::memcpy(bytes.data(), payload, size);
            length = size;
            return true;
          })) {
        return std::nullopt;
      }
      return try_decode<T>(std::span<const std::uint8_t>(bytes.data(), length));
    }
  }

  /// Messages this handle lost by falling more than the capacity behind.
  std::uint64_t lost() const noexcept { return cursor_.lost; }
  TopicStats stats() const noexcept {
    TopicStats stats = stats_;
    stats.lost = cursor_.lost;
    return stats;
  }
  /// Slots in the ring (a power of two).
  std::size_t capacity() const noexcept { return static_cast<std::size_t>(ring_.capacity()); }

 private:
  static constexpr std::chrono::nanoseconds kSlice = std::chrono::microseconds(50);

  /// A slot for the next message; no slot when the ring refused one (or, on a single-publisher
  /// topic, when another handle holds the lease). Every path returns its callee's claim as is,
  /// so the claim is never copied (see PublisherLease::claim).
  [[gnu::always_inline]] detail::Claim claim_slot() noexcept {
    if (ring_.shared_base == detail::kUnshared) {
      if (lease_.held() || lease_.acquire(ring_)) {
        return lease_.claim(ring_);
      }
      if (ring_.single_publisher) {
        ++stats_.not_the_publisher;
        return detail::Claim{nullptr, 0, false, false};
      }
      if (!detail::ring_share(ring_)) {
        return detail::Claim{nullptr, 0, false, false};
      }
    }
    return detail::ring_claim(ring_, detail::this_pid());
  }

  void mark(std::uint32_t role) noexcept {
    if ((roles_ & role) == 0) {
      roles_ |= role;
      segment_.add_role(role);
    }
  }

  /// Fills `msg` with the next message, or empties it. The caller owns the result object, so
  /// a (possibly large) message is copied once, from the slot straight into what it returns.
  void receive(std::optional<T>& msg, bool check_stall) noexcept(PodTopicValue<T>) {
    mark(detail::kRoleSubscriber);
    for (;;) {
      std::size_t length = 0;
      const int got = detail::ring_read(
          ring_, cursor_, check_stall, [&](const std::byte* payload, std::uint32_t size) {
            if constexpr (PodTopicValue<T>) {
              if (size != sizeof(T)) {
                return false;
              }
              // Copy-constructs straight from the slot: no zeroing of a large T first.
              msg.emplace(*std::launder(reinterpret_cast<const T*>(payload)));
            } else {
              if (size > buffer_.size()) {
                return false;
              }
              std::memcpy(buffer_.data(), payload, size);
              length = size;
            }
            return true;
          });
      if (got == 0) {
        msg.reset();
        return;
      }
      if (got > 0) {
        if constexpr (!PodTopicValue<T>) {
          msg = try_decode<T>(std::span<const std::uint8_t>(buffer_.data(), length));
        }
        if (msg) {
          return;
        }
      }
      ++stats_.invalid;
    }
  }

  std::string name_;
  detail::ShmSegment segment_;
  detail::RingView ring_;
  /// Declared after segment_: released before the segment is unmapped.
  detail::PublisherLease lease_;
  detail::ReadCursor cursor_;
  std::uint32_t roles_ = 0;
  TopicStats stats_;
  std::unique_ptr<T> spare_;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace horus
