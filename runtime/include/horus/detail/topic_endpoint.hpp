// The byte-level side of one topic handle, whatever its message type: the slot claim (lease,
// single publisher, shared ring), the commit, the receive loop and the blocking wait. Written
// once for horus::Topic<T> (type known at compile time) and horus::RawTopic (type known at run
// time: the Python binding's, the bridges'), so both follow one slot protocol and share a segment.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>

#include "horus/detail/futex.hpp"
#include "horus/detail/process.hpp"
#include "horus/detail/publisher_lease.hpp"
#include "horus/detail/ring.hpp"
#include "horus/detail/send_clock.hpp"
#include "horus/detail/shm_segment.hpp"
#include "horus/topic_stats.hpp"

namespace horus::detail {

/// Ends a claim: commits `size` payload bytes to its slot (kReleasedSlot gives the slot back
/// unsent) or, when the ring refused a slot, settles the refusal. Whether a message was
/// published. Reads and resets the claim in place: copying it whole stalls (see Loan).
[[gnu::always_inline]] inline bool finish_claim(const RingView& ring, Claim& claim,
                                                std::uint32_t size) noexcept {
  if (claim.slot != nullptr) {
    ring_commit(ring, claim, size, send_stamp_s());
    claim.slot = nullptr;
    claim.wake = false;
    return size != kReleasedSlot;
  }
  ring_refused(ring, claim);
  claim.wake = false;
  return false;
}

/// A mapped topic segment with one handle's publisher lease, read position, roles and counters.
/// Movable (the mapping does not move); not assignable member-wise, as the old segment would be
/// unmapped before the old lease is given back.
class TopicEndpoint {
 public:
  explicit TopicEndpoint(ShmSegment segment) noexcept
      : segment_(std::move(segment)), ring_(segment_.ring()) {
    cursor_.next = ring_written(ring_);
  }
  TopicEndpoint(TopicEndpoint&&) noexcept = default;
  TopicEndpoint& operator=(TopicEndpoint&&) = delete;
  TopicEndpoint(const TopicEndpoint&) = delete;
  TopicEndpoint& operator=(const TopicEndpoint&) = delete;
  ~TopicEndpoint() = default;

  /// The handle's own view of the ring: a Loan points at it rather than holding a copy.
  const RingView& ring() const noexcept { return ring_; }
  bool has_msg() const noexcept { return ring_ready(ring_, cursor_); }
  std::uint64_t lost() const noexcept { return cursor_.lost; }
  /// The ticket this handle reads next: the one just received is next_ticket() - 1 (recorders
  /// store it as the message's sequence number).
  std::uint64_t next_ticket() const noexcept { return cursor_.next; }
  TopicStats stats() const noexcept {
    TopicStats stats = stats_;
    stats.lost = cursor_.lost;
    return stats;
  }

  /// Registers the role in the segment the first time this handle takes it.
  void mark(std::uint32_t role) noexcept {
    if ((roles_ & role) == 0) {
      roles_ |= role;
      segment_.add_role(role);
    }
  }

  /// A slot for the next message; no slot when the ring refused one (or, on a single-publisher
  /// topic, when another handle holds the lease). Every path returns its callee's claim as is,
  /// so the claim is never copied (see PublisherLease::claim).
  [[gnu::always_inline]] Claim claim_slot() noexcept {
    if (ring_.shared_base == kUnshared) {
      if (lease_.held() || lease_.acquire(ring_)) {
        return lease_.claim(ring_);
      }
      if (ring_.single_publisher) {
        ++stats_.not_the_publisher;
        return Claim{nullptr, 0, false, false};
      }
      if (!ring_share(ring_)) {
        return Claim{nullptr, 0, false, false};
      }
    }
    return ring_claim(ring_, this_pid());
  }

  /// Publishes one message: `write(payload)` fills the claimed slot and returns the bytes it
  /// wrote, or kReleasedSlot when the message did not fit (counted as oversized). Whether a
  /// message was published; each failure is counted.
  template <class Write>
  [[gnu::always_inline]] bool send(Write&& write) noexcept {
    mark(kRolePublisher);
    const std::uint32_t sent = send_stamp_s();
    const Claim claim = claim_slot();
    if (claim.slot == nullptr) {
      ring_refused(ring_, claim);
      ++stats_.send_failures;
      return false;
    }
    const std::uint32_t size = write(ring_.payload(*claim.slot));
    ring_commit(ring_, claim, size, sent);
    if (size == kReleasedSlot) {
      count_oversized();
      return false;
    }
    return true;
  }

  /// A send refused for its size: no slot was claimed.
  void count_oversized() noexcept {
    ++stats_.send_failures;
    ++stats_.oversized;
  }
  /// A loan that got no slot was published.
  void count_send_failure() noexcept { ++stats_.send_failures; }

  /// Takes the next message: `copy(payload, size)` copies it out of its slot (false: its size
  /// is wrong), then `accept()` says whether the copy is a valid message. Skips, counting them
  /// as invalid, the messages either refuses. Whether one was taken.
  /// Always inlined: the caller's receive is then this loop around one call of ring_read, as
  /// when each handle type wrote it out.
  template <class Copy, class Accept>
  [[gnu::always_inline]] bool receive(bool check_stall, Copy&& copy,
                                      Accept&& accept) noexcept(noexcept(accept())) {
    mark(kRoleSubscriber);
    for (;;) {
      const int got = ring_read(ring_, cursor_, check_stall, copy);
      if (got == 0) {
        return false;
      }
      if (got > 0 && accept()) {
        return true;
      }
      ++stats_.invalid;
    }
  }

  /// What a waiter that sleeps on the topic's futex by its own means (RawTopic::begin_wait)
  /// learns from announcing itself.
  struct WaitAnnouncement {
    /// `notify` as read before the announcement: a wake-up since then changed it.
    std::uint32_t seen;
    /// Counted in the sleeper bits, so withdraw_wait() must follow the sleep (a full sleeper
    /// count is not, and then the sleep is in slices).
    bool counted;
    /// Zero, or how long to sleep at a time when a publisher may not wake this waiter.
    std::chrono::nanoseconds recheck_after;
  };

  /// receive_within's announcement for a waiter that sleeps by its own means: the same steps in
  /// the same order (the futex word read, the sleeper announced, the barrier, a last look at the
  /// ring), except that the last look takes nothing. Empty, with nothing left announced, when
  /// the next receive has something to take.
  std::optional<WaitAnnouncement> announce_wait() noexcept {
    mark(kRoleSubscriber);
    RingControl& control = *ring_.control;
    const std::uint32_t seen = control.notify.load(std::memory_order_seq_cst);
    const std::uint64_t claimed_before = segment_.announce_sleeper();
    const bool counted = claimed_before != UINT64_MAX;
    const bool announced = ring_sleeper_barrier(control);
    if (readable()) {
      if (counted) {
        segment_.withdraw_sleeper();
      }
      return std::nullopt;
    }
    const bool unannounced = !counted || !announced || cursor_.next < claimed_before;
    return WaitAnnouncement{seen, counted, unannounced ? kSlice : std::chrono::nanoseconds::zero()};
  }
  /// Withdraws a counted announcement of announce_wait(), once its sleep ended.
  void withdraw_wait() noexcept { segment_.withdraw_sleeper(); }

  /// Waits up to `timeout` for `receive(check_stall)` to take a message, asleep on the topic's
  /// futex (no polling); whether it took one.
  template <class Receive>
  bool receive_within(std::chrono::nanoseconds timeout,
                      Receive&& receive) noexcept(noexcept(receive(false))) {
    if (receive(false)) {
      return true;
    }
    RingControl& control = *ring_.control;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const std::uint32_t seen = control.notify.load(std::memory_order_seq_cst);
      const std::uint64_t claimed_before = segment_.announce_sleeper();
      const bool announced = ring_sleeper_barrier(control);
      const bool got = receive(true);
      const auto remaining = deadline - std::chrono::steady_clock::now();
      if (!got && remaining > std::chrono::nanoseconds::zero()) {
        // A ticket claimed before this thread announced itself may still be in flight, and its
        // publisher will not wake us: only then sleep in short slices.
        const bool unannounced =
            claimed_before == UINT64_MAX || !announced || cursor_.next < claimed_before;
        futex_wait(control.notify, seen,
                   unannounced ? std::min<std::chrono::nanoseconds>(remaining, kSlice) : remaining);
      }
      if (claimed_before != UINT64_MAX) {
        segment_.withdraw_sleeper();
      }
      if (got || remaining <= std::chrono::nanoseconds::zero()) {
        return got;
      }
    }
  }

 private:
  /// How long a sleeper that may have missed its wake-up sleeps at a time.
  static constexpr std::chrono::nanoseconds kSlice = std::chrono::microseconds(50);

  /// Whether the next receive has something to take (a message, or a lap to catch up on), once
  /// a ticket whose writer is gone has been skipped as a stall-checking receive skips it.
  bool readable() noexcept {
    for (;;) {
      if (ring_ready(ring_, cursor_)) {
        return true;
      }
      if (!ring_writer_gone(ring_, cursor_)) {
        return false;
      }
      ++cursor_.lost;
      ++cursor_.next;
      cursor_.stall_since_ns = 0;
    }
  }

  ShmSegment segment_;
  RingView ring_;
  /// Declared after segment_: released before the segment is unmapped.
  PublisherLease lease_;
  ReadCursor cursor_;
  std::uint32_t roles_ = 0;
  TopicStats stats_;
};

}  // namespace horus::detail
