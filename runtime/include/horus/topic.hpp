// horus::Topic<T>: a named, typed channel between threads and processes over shared memory.
// How the segment and the slots work: runtime/src/transport/README.md.
#pragma once

#include <array>
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
#include "horus/detail/message_count.hpp"
#include "horus/detail/ring.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/detail/slot_copy.hpp"
#include "horus/detail/topic_endpoint.hpp"
#include "horus/detail/topic_stream.hpp"
#include "horus/msgpack.hpp"
#include "horus/plain_value.hpp"
#include "horus/topic_log.hpp"
#include "horus/topic_stats.hpp"
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
  /// This handle logs every message it sends or receives (seed 002's verbose topics): one line
  /// with the message's summary in the runtime's log, at most 10 a second, then a count of the
  /// lines suppressed (horus/topic_log.hpp). Per handle, unlike the options above; see
  /// also Topic::set_verbose. Off, send and receive pay one predictable branch for it.
  bool verbose = false;
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
  /// Always inlined, as send() is: a call here costs a loan as much as its commit.
  [[gnu::always_inline]] bool finish(std::uint32_t size) noexcept {
    return detail::finish_claim(*ring_, claim_, size);
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
        endpoint_(detail::ShmSegment::open_topic(
            name,
            detail::TypeDescriptor{TypeInfo<T>::name, TypeInfo<T>::fingerprint, TypeInfo<T>::schema,
                                   TypeInfo<T>::is_pod, TypeInfo<T>::is_pod ? sizeof(T) : 0,
                                   alignof(T), std::string_view(TypeInfo<T>::description)},
            detail::SegmentOptions{options.capacity, options.max_message_size, options.mode,
                                   options.namespace_name, options.single_publisher})) {
    if constexpr (PodTopicValue<T>) {
      spare_ = std::make_unique<T>();
    } else {
      buffer_.resize(endpoint_.ring().payload_capacity);
    }
    set_verbose(options.verbose);
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

  /// Turns this handle's logging of its messages on or off (TopicOptions::verbose).
  void set_verbose(bool on) {
    if (!on) {
      log_.reset();
    } else if (!log_) {
      log_ = std::make_unique<TopicLog>(name_);
    }
  }
  bool verbose() const noexcept { return log_ != nullptr; }

  /// Publishes a copy of `msg`. Never blocks; false (and a counter) when nothing was published.
  bool send(const T& msg) noexcept {
    const bool sent = endpoint_.send([&](std::byte* payload) noexcept {
      if constexpr (PodTopicValue<T>) {
        detail::copy_to_slot<sizeof(T)>(payload, &msg);
        return static_cast<std::uint32_t>(sizeof(T));
      } else {
        detail::FixedBufferStream stream(payload, endpoint_.ring().payload_capacity);
        msgpack::packer<detail::FixedBufferStream> packer(stream);
        detail::pack_payload(packer, msg);
        return stream.overflowed() ? detail::kReleasedSlot
                                   : static_cast<std::uint32_t>(stream.size());
      }
    });
    if (sent) {
      detail::count_sent(this, name_);
      if (log_) [[unlikely]] {
        log_->message(TopicLogDirection::Send, msg);
      }
    }
    return sent;
  }

  /// Lends the next slot for writing the message in place. Publish it with publish().
  /// When the ring refuses the slot, the caller writes into a private spare and publish()
  /// reports it.
  Loan<T> loan() noexcept requires PodTopicValue<T> {
    endpoint_.mark(detail::kRolePublisher);
    return Loan<T>(
        endpoint_.ring(), [this] { return endpoint_.claim_slot(); }, spare_.get());
  }

  /// Makes a loaned message visible. False (and a counter) when the loan had no slot.
  bool publish(Loan<T>&& loan) noexcept requires PodTopicValue<T> {
    if (log_) [[unlikely]] {
      return publish_logged(std::move(loan));
    }
    if (loan.finish(sizeof(T))) {
      detail::count_sent(this, name_);
      return true;
    }
    endpoint_.count_send_failure();
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
    endpoint_.receive_within(timeout, [&](bool check_stall) noexcept(PodTopicValue<T>) {
      receive(msg, check_stall);
      return msg.has_value();
    });
    return msg;
  }

  /// Whether try_recv() would find something (a message, or news that some were lost).
  bool has_msg() const noexcept { return endpoint_.has_msg(); }

  /// The newest message ever sent on the topic (not only since this handle opened); does not
  /// move this handle's position.
  std::optional<T> read_latest() const noexcept(PodTopicValue<T>) {
    if constexpr (PodTopicValue<T>) {
      std::optional<T> msg;
      if (detail::ring_read_latest(
              endpoint_.ring(), [&](const std::byte* payload, std::uint32_t size) {
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
      std::vector<std::uint8_t> bytes(endpoint_.ring().payload_capacity);
      std::size_t length = 0;
      if (!detail::ring_read_latest(endpoint_.ring(),
                                    [&](const std::byte* payload, std::uint32_t size) {
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
  std::uint64_t lost() const noexcept { return endpoint_.lost(); }
  TopicStats stats() const noexcept { return endpoint_.stats(); }
  /// Slots in the ring (a power of two).
  std::size_t capacity() const noexcept {
    return static_cast<std::size_t>(endpoint_.ring().capacity());
  }

 private:
  /// Fills `msg` with the next message, or empties it. The caller owns the result object, so
  /// a (possibly large) message is copied once, from the slot straight into what it returns.
  void receive(std::optional<T>& msg, bool check_stall) noexcept(PodTopicValue<T>) {
    std::size_t length = 0;
    const bool got = endpoint_.receive(
        check_stall,
        [&](const std::byte* payload, std::uint32_t size) {
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
        },
        [&]() noexcept(PodTopicValue<T>) {
          if constexpr (!PodTopicValue<T>) {
            msg = try_decode<T>(std::span<const std::uint8_t>(buffer_.data(), length));
          }
          return msg.has_value();
        });
    if (got) {
      detail::count_received(this, name_, endpoint_.next_ticket());
      if (log_) [[unlikely]] {
        log_->message(TopicLogDirection::Recv, *msg);
      }
    } else {
      msg.reset();
    }
  }

  /// publish() of a verbose handle: the summary is read from the slot before it is committed
  /// (after, the ring may reuse it), and logged once the message is published.
  [[gnu::cold]] bool publish_logged(Loan<T>&& loan) noexcept requires PodTopicValue<T> {
    std::array<char, TopicLog::kMaxSummary> buffer;
    detail::SummaryWriter summary(buffer.data(), buffer.size());
    const bool admitted = log_->admit();
    if (admitted) TopicLog::summarize(summary, *loan);
    if (!loan.finish(sizeof(T))) {
      endpoint_.count_send_failure();
      return false;
    }
    detail::count_sent(this, name_);
    if (admitted) log_->write(TopicLogDirection::Send, summary.view());
    return true;
  }

  std::string name_;
  detail::TopicEndpoint endpoint_;
  std::unique_ptr<T> spare_;
  std::vector<std::uint8_t> buffer_;
  std::unique_ptr<TopicLog> log_;  // null unless verbose
};

}  // namespace horus
