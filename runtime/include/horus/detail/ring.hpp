// The lock-free slot ring of a topic: claim/commit by a lease holder or by publishers sharing the
// ring, and a seqlock-style read.
//
// Ticket t (ever increasing: numbered by the holder of the publisher lease while one publisher
// sends, then by write_index once a second one shares the ring) lives in slot t % capacity. The
// slot's `seq` is 2t+1 while ticket t is being written and 2t+2 once it is committed. A reader
// expecting ticket t accepts the slot only if it reads 2t+2 before and after copying the payload,
// so a half-written slot (a writer killed mid-memcpy, or one overwriting it a lap later) is never
// accepted.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "horus/detail/futex.hpp"
#include "horus/detail/process.hpp"
#include "horus/detail/send_clock.hpp"

namespace horus::detail {

/// One open handle in the segment's users table (shm_segment.hpp).
struct UserEntry;

/// The shared counters of a ring, in the type-independent control page.
struct RingControl {
  /// Low 56 bits: tickets handed out by fetch_add once the ring is shared (counted from
  /// `shared_base`; 0 before). High 8 bits: threads about to sleep or sleeping on `notify`.
  /// Sharing the word lets a shared claim's fetch_add tell a publisher whether to wake anybody,
  /// so a send needs no extra barrier.
  alignas(64) std::atomic<std::uint64_t> write_index;
  /// 1 when the topic was created for a single publisher (TopicOptions::single_publisher): the
  /// lease is never shared, and other handles cannot send.
  std::atomic<std::uint32_t> single_publisher;
  /// Bumped (and futex-woken) after a commit whose publisher saw sleepers.
  alignas(64) std::atomic<std::uint32_t> notify;
  /// Ticket + 1 of the latest commit (a plain store, so not strictly monotonic once several
  /// publishers share the ring): how TopicNotifier learns of messages sent while it was not
  /// asleep. While a lease holder numbers the tickets it is exact: the count handed out.
  alignas(64) std::atomic<std::uint64_t> commits;
  /// pid << 32 | flags | handle serial of the handle that numbers tickets itself, or 0.
  /// kLeaseShared once a second publisher arrived: the lease is then never taken again.
  std::atomic<std::uint64_t> publisher_lease;
  /// Stored by the lease holder before each claim: its ticket + 1. No ticket at or past the
  /// value read after the holder's barrier (ring_share) is written under the lease.
  std::atomic<std::uint64_t> lease_announce;
  /// 0 while the lease numbers the tickets; then 1 + the first ticket that write_index numbers.
  /// Set once, by the first compare-and-swap (ring_share, or the holder letting its lease go).
  std::atomic<std::uint64_t> shared_base;
  /// The first ticket since the ring was last started afresh: the slots of earlier tickets may
  /// hold anything (a re-typed segment's slots are zeroed, its ticket count is kept).
  std::atomic<std::uint64_t> first_ticket;
};
static_assert(sizeof(RingControl) == 192, "the control page layout is part of the format");

/// RingControl::publisher_lease: the lease was given up for a second publisher.
inline constexpr std::uint64_t kLeaseShared = std::uint64_t{1} << 31;
/// RingControl::publisher_lease: the holder skips its own barrier, relying on membarrier(2).
inline constexpr std::uint64_t kLeaseFenceFree = std::uint64_t{1} << 30;
inline constexpr std::uint64_t kLeaseSerialMask = kLeaseFenceFree - 1;
/// RingView::shared_base of a ring whose tickets a lease holder still numbers.
inline constexpr std::uint64_t kUnshared = UINT64_MAX;

inline constexpr std::uint64_t kIndexMask = (std::uint64_t{1} << 56) - 1;
inline constexpr std::uint64_t kSleeper = std::uint64_t{1} << 56;
inline constexpr std::uint64_t kMaxSleepers = 255;

/// What subscribers read of a slot; the payload follows (on the next cache line when it does
/// not fit beside this header, so a publisher filling it does not fight a subscriber polling
/// `seq`).
struct SlotHeader {
  /// The seqlock: 2t+1 while ticket t is written, 2t+2 once it is committed.
  std::atomic<std::uint64_t> seq;
  /// Payload bytes, or kReleasedSlot for a ticket that carries no message.
  std::atomic<std::uint32_t> size;
  /// When the ticket was committed (send_stamp_s()), for introspection. Here rather than with
  /// the publishers' claims because the commit writes this line anyway: a lease holder
  /// then touches no claim line at all.
  std::atomic<std::uint32_t> send_time_s;
};
static_assert(sizeof(SlotHeader) == 16 && offsetof(SlotHeader, seq) == 0);

/// Publishers' side of a slot: exclusion among them. These live in an array of their own, away
/// from the slots, so that a subscriber never holds their cache lines: not by reading them, and
/// not by the hardware prefetcher pulling in the neighbour of a line it reads. A publisher's
/// compare-and-swap on a line that a subscriber holds waits for a cross-core round trip: with
/// the claim word on its own line inside each slot, topic throughput was 1.5x lower.
struct SlotClaim {
  /// 2t+1 while the writer of ticket t holds the slot, 2t+2 once it let go.
  std::atomic<std::uint64_t> claim;
  /// Pid of that writer, so a successor can tell a dead writer from a slow one.
  std::atomic<std::uint32_t> owner;
  std::uint32_t reserved[5];
};
static_assert(sizeof(SlotClaim) == 32);
static_assert(std::atomic<std::uint64_t>::is_always_lock_free);

/// Size of a slot whose writer gave it up (an unpublished loan, an oversized message).
inline constexpr std::uint32_t kReleasedSlot = 0xffffffffU;
/// How long a reader waits for a ticket whose writer vanished before even marking its slot.
inline constexpr std::int64_t kStallLimitNs = 1'000'000'000;
/// How long a reader waits for a ticket whose writer holds its slot before asking whether
/// that writer is still alive.
inline constexpr std::int64_t kDeadCheckNs = 1'000'000;
/// Empty polls between the checks for a dead writer.
inline constexpr std::uint32_t kStallCheckInterval = 1024;

/// Pointers and geometry of a mapped ring, copied out of the validated header.
struct RingView {
  RingControl* control = nullptr;
  SlotClaim* claims = nullptr;
  std::byte* slots = nullptr;
  std::uint64_t mask = 0;
  std::uint64_t stride = 0;
  std::uint64_t payload_offset = 0;
  std::uint64_t payload_capacity = 0;
  /// Copied from RingControl::single_publisher when the segment is opened.
  bool single_publisher = false;
  /// The sleepers' membarrier covers this process, so a lease holder needs no barrier of its
  /// own before looking for sleepers (set by PublisherLease).
  bool fence_free = false;
  /// The first ticket write_index numbers, once this handle saw the ring shared (it never
  /// changes after); kUnshared before.
  std::uint64_t shared_base = kUnshared;
  /// The segment's users table, where a wake that found nobody looks for sleepers that died.
  UserEntry* users = nullptr;

  std::uint64_t capacity() const noexcept { return mask + 1; }
  SlotHeader& slot(std::uint64_t ticket) const noexcept {
    return *reinterpret_cast<SlotHeader*>(slots + (ticket & mask) * stride);
  }
  SlotClaim& slot_claim(std::uint64_t ticket) const noexcept { return claims[ticket & mask]; }
  std::byte* payload(SlotHeader& slot) const noexcept {
    return reinterpret_cast<std::byte*>(&slot) + payload_offset;
  }
};

/// Per-handle reading position.
struct ReadCursor {
  std::uint64_t next = 0;
  std::uint64_t lost = 0;
  std::uint32_t empty_polls = 0;
  std::int64_t stall_since_ns = 0;
};

/// The seqlock's fences. ThreadSanitizer does not model fences (GCC rejects them under -Wtsan);
/// its builds use compiler-only barriers, which is what these fences compile to on x86-64.
inline void seqlock_fence(std::memory_order order) noexcept {
#if defined(__SANITIZE_THREAD__)
  std::atomic_signal_fence(order);
#else
  std::atomic_thread_fence(order);
#endif
}

/// A claimed slot: where to write, under which lease, and whether a sleeper must be woken after
/// the commit.
struct Claim {
  SlotHeader* slot;
  std::uint64_t ticket;
  /// Numbered by the lease holder (no claim word), rather than by write_index.
  bool leased;
  bool wake;
};

/// The first ticket write_index numbers, or kUnshared while a lease holder numbers them.
inline std::uint64_t ring_shared_base(const RingControl& control) noexcept {
  const std::uint64_t stored = control.shared_base.load(std::memory_order_acquire);
  return stored == 0 ? kUnshared : stored - 1;
}

/// Whether the ring was just shared and the slot of `ticket` (whose sequence reads `seq`) still
/// holds, a lap before, a ticket numbered under the lease that its holder has not committed: the
/// holder writes it without a claim word, so only its liveness says whether the slot is still
/// being written.
inline bool ring_lease_ticket_pending(const RingView& ring, std::uint64_t ticket,
                                      std::uint64_t seq) noexcept {
  if (ticket - ring.shared_base >= ring.capacity() || ticket < ring.capacity()) {
    return false;
  }
  const std::uint64_t previous = ticket - ring.capacity();
  if (previous < ring.control->first_ticket.load(std::memory_order_relaxed) ||
      seq >= 2 * previous + 2) {
    return false;
  }
  const std::uint64_t lease = ring.control->publisher_lease.load(std::memory_order_acquire);
  return process_alive(static_cast<std::uint32_t>(lease >> 32));
}

/// Whether a shared claim may take a slot whose claim word is not what the previous lap's
/// commit left there (`current`, below the ticket being claimed). Odd: a writer holds it, but if
/// the slot shows that writer's ticket committed, it is only late letting go (preempted between
/// its two commit stores) and the slot is free. Even: either the previous lap's writer has not
/// claimed it yet (it will find itself overtaken), or that writer's claim was overwritten by
/// the late release of the lap before it; then the slot's odd sequence shows it writing. A
/// writer still writing keeps the slot while its process lives. In the first lap after the ring
/// was shared, no claim word is the previous lap's release, and the lease holder's tickets there
/// have none at all: those slots are checked against the holder.
inline bool ring_stale_claim_free(const RingView& ring, std::uint64_t ticket,
                                  std::uint64_t current) noexcept {
  const std::uint64_t seq = ring.slot(ticket).seq.load(std::memory_order_acquire);
  if (ring_lease_ticket_pending(ring, ticket, seq)) {
    return false;
  }
  const bool writing = (seq & 1) != 0 || ((current & 1) != 0 && seq < current + 1);
  return !writing || !process_alive(ring.slot_claim(ticket).owner.load(std::memory_order_relaxed));
}

/// Claims the slot of a fresh ticket of a shared ring for writing; slot is nullptr when it cannot
/// be taken without racing a live writer (one stalled for a whole lap) or this ticket was
/// already overtaken.
inline Claim ring_claim(const RingView& ring, std::uint32_t pid) noexcept {
  const std::uint64_t word = ring.control->write_index.fetch_add(1, std::memory_order_seq_cst);
  Claim claim{nullptr, ring.shared_base + (word & kIndexMask), false, (word & ~kIndexMask) != 0};
  SlotClaim& entry = ring.slot_claim(claim.ticket);
  const std::uint64_t writing = 2 * claim.ticket + 1;
  // The claim word once the previous lap's ticket was committed and let go: the common case.
  const std::uint64_t released =
      claim.ticket >= ring.capacity() ? writing + 1 - 2 * ring.capacity() : 0;
  std::uint64_t current = entry.claim.load(std::memory_order_relaxed);
  for (;;) {
    if (current >= writing) {
      return claim;
    }
    if (current != released && !ring_stale_claim_free(ring, claim.ticket, current)) {
      return claim;
    }
    entry.owner.store(pid, std::memory_order_relaxed);
    if (entry.claim.compare_exchange_weak(current, writing, std::memory_order_acquire,
                                          std::memory_order_relaxed)) {
      SlotHeader& slot = ring.slot(claim.ticket);
      slot.seq.store(writing, std::memory_order_relaxed);
      // Orders the odd sequence before the payload stores (the seqlock writer's fence).
      seqlock_fence(std::memory_order_release);
      claim.slot = &slot;
      return claim;
    }
  }
}

/// The lease holder's claim of its next ticket: no read-modify-write, as nobody else writes
/// the ring while the lease is held.
[[gnu::always_inline]] inline Claim ring_claim_leased(const RingView& ring,
                                                      std::uint64_t ticket) noexcept {
  SlotHeader& slot = ring.slot(ticket);
  slot.seq.store(2 * ticket + 1, std::memory_order_relaxed);
  seqlock_fence(std::memory_order_release);
  return Claim{&slot, ticket, true, false};
}

/// Whether a thread sleeps on the ring, asked by a lease holder once its commit is stored. The
/// commit must be visible before the question is asked, or a sleeper re-checking the ring just
/// before it and this load just before the sleeper's announcement would both miss. Sleepers
/// make it so with a barrier on every CPU (membarrier) between announcing and re-checking, so
/// the publisher's load costs nothing; a publisher that membarrier does not cover pays for a
/// barrier itself, and so does one whose lease was shared meanwhile: once the ring is shared,
/// sleepers stop paying for that barrier. (A lease word without kLeaseShared is still the
/// caller's: only a dead holder's lease is ever taken.)
[[gnu::always_inline]] inline bool ring_sleepers_after_commit(const RingView& ring) noexcept {
  RingControl& control = *ring.control;
  if (ring.fence_free) {
    std::atomic_signal_fence(std::memory_order_seq_cst);
    if ((control.publisher_lease.load(std::memory_order_relaxed) & kLeaseShared) == 0) {
      return (control.write_index.load(std::memory_order_relaxed) & ~kIndexMask) != 0;
    }
  }
  return (control.write_index.fetch_add(0, std::memory_order_seq_cst) & ~kIndexMask) != 0;
}

/// Gives back the sleeper announcements of handles whose process died asleep. Left alone, they
/// would make every later send wake nobody, with a syscall, until the topic is recreated.
void ring_reclaim_dead_sleepers(const RingView& ring) noexcept;

/// Whether this thread may search for dead sleepers now: at most once in 50 ms. A
/// wake that finds nobody is also what a live sleeper about to sleep causes, often on a busy
/// ring, and each search asks the kernel whether each sleeper's process lives (kill, /proc).
bool ring_reclaim_due() noexcept;

/// Wakes the sleepers a claim saw (also for a claim that got no slot: they wait for its ticket).
/// A wake that finds nobody asleep is the sign of a sleeper that died (or of one about to sleep,
/// which notices the bumped word): only then is the users table searched, on a path that has
/// made a syscall anyway.
inline void ring_wake(const RingView& ring) noexcept {
  ring.control->notify.fetch_add(1, std::memory_order_seq_cst);
  if (futex_wake_all(ring.control->notify) == 0 && ring_reclaim_due()) {
    ring_reclaim_dead_sleepers(ring);
  }
}

/// Lets go of a claim that got no slot. Its ticket is used up all the same, and the sleepers the
/// claim saw wait for that ticket: they are woken to move past it.
inline void ring_refused(const RingView& ring, const Claim& claim) noexcept {
  if (claim.wake) {
    ring_wake(ring);
  }
}

/// Makes the claimed ticket visible with `size` payload bytes (or kReleasedSlot), stamped `sent`
/// (send_stamp_s(), read by a sender before its claim: a subscriber polling the slot's header
/// line takes it away while the slot is marked written, and a clock call there would give it
/// time to). No barrier and no syscall unless there is a sleeper.
[[gnu::always_inline]] inline void ring_commit(const RingView& ring, const Claim& claim,
                                               std::uint32_t size, std::uint32_t sent) noexcept {
  SlotHeader& slot = *claim.slot;
  slot.size.store(size, std::memory_order_relaxed);
  slot.send_time_s.store(sent, std::memory_order_relaxed);
  slot.seq.store(2 * claim.ticket + 2, std::memory_order_release);
  if (!claim.leased) {
    ring.slot_claim(claim.ticket).claim.store(2 * claim.ticket + 2, std::memory_order_release);
  }
  ring.control->commits.store(claim.ticket + 1, std::memory_order_release);
  if (claim.leased ? ring_sleepers_after_commit(ring) : claim.wake) {
    ring_wake(ring);
  }
}

/// Tickets handed out so far (not all committed yet).
inline std::uint64_t ring_written(const RingControl& control) noexcept {
  const std::uint64_t base = ring_shared_base(control);
  if (base == kUnshared) {
    return control.commits.load(std::memory_order_acquire);
  }
  return base + (control.write_index.load(std::memory_order_acquire) & kIndexMask);
}
inline std::uint64_t ring_written(const RingView& ring) noexcept {
  return ring_written(*ring.control);
}

/// Announces a thread about to sleep on `notify`. Returns the shared tickets handed out before
/// the announcement (their publishers will not wake it; later ones will), 0 while a lease holder
/// numbers the tickets (ring_sleeper_barrier covers it), or UINT64_MAX when the sleeper count is
/// full and the caller must sleep in short slices instead.
inline std::uint64_t ring_add_sleeper(RingControl& control) noexcept {
  const std::uint64_t word = control.write_index.fetch_add(kSleeper, std::memory_order_seq_cst);
  if ((word >> 56) >= kMaxSleepers) {
    control.write_index.fetch_sub(kSleeper, std::memory_order_seq_cst);
    return UINT64_MAX;
  }
  // Read after the announcement: a shared claim that came before it was made after the base
  // was set, so the base is seen here whenever `word` counts such a claim.
  const std::uint64_t base = ring_shared_base(control);
  return base == kUnshared ? 0 : base + (word & kIndexMask);
}

/// Whether a lease holder may be numbering the ring's tickets, so that a sleeper needs
/// ring_sleeper_barrier before its last look at the ring.
inline bool ring_leased(const RingControl& control) noexcept {
  return control.single_publisher.load(std::memory_order_relaxed) != 0 ||
         ring_shared_base(control) == kUnshared;
}

/// Called between ring_add_sleeper and the sleeper's last look at the ring. While a lease holder
/// numbers the tickets it runs a memory barrier on every CPU that runs a fence-free publisher
/// (membarrier), after which the holder has either made its commit visible or will see this
/// sleeper. False when that failed: the caller then sleeps in short slices.
bool ring_sleeper_barrier(const RingControl& control) noexcept;

inline void ring_remove_sleeper(RingControl& control) noexcept {
  control.write_index.fetch_sub(kSleeper, std::memory_order_seq_cst);
}

/// Moves a reader that was lapped to the oldest ticket still in the ring.
inline void ring_resync(const RingView& ring, ReadCursor& cursor) noexcept {
  const std::uint64_t written = ring_written(ring);
  const std::uint64_t oldest = written > ring.capacity() ? written - ring.capacity() : 0;
  const std::uint64_t next = oldest > cursor.next + 1 ? oldest : cursor.next + 1;
  cursor.lost += next - cursor.next;
  cursor.next = next;
  cursor.stall_since_ns = 0;
}

/// True when the writer of the reader's next ticket is gone, so the ticket must be skipped.
/// Only a stall that outlasts kDeadCheckNs costs a syscall (the liveness check).
inline bool ring_writer_gone(const RingView& ring, ReadCursor& cursor) noexcept {
  if (cursor.next >= ring_written(ring)) {
    cursor.stall_since_ns = 0;
    return false;
  }
  const std::int64_t now = clock_ns(CLOCK_MONOTONIC);
  if (cursor.stall_since_ns == 0) {
    cursor.stall_since_ns = now;
    return false;
  }
  const std::int64_t stalled = now - cursor.stall_since_ns;
  const SlotClaim& entry = ring.slot_claim(cursor.next);
  if (stalled > kDeadCheckNs &&
      entry.claim.load(std::memory_order_relaxed) == 2 * cursor.next + 1 &&
      !process_alive(entry.owner.load(std::memory_order_relaxed))) {
    return true;
  }
  // Ticket taken but slot never claimed: the writer may have died between the two.
  return stalled > kStallLimitNs;
}

/// Reads the reader's next message. `copy(payload, size)` copies it out (checking `size` first)
/// and returns whether the size was acceptable; it may run on a slot being overwritten, whose
/// copy is then discarded. Returns 1 for a message, 0 for none, -1 for an invalid size.
template <class Copy>
int ring_read(const RingView& ring, ReadCursor& cursor, bool check_stall, Copy&& copy) noexcept {
  // Bounded: every pass either returns or moves the cursor forward.
  for (int pass = 0; pass < 64; ++pass) {
    SlotHeader& slot = ring.slot(cursor.next);
    const std::uint64_t committed = 2 * cursor.next + 2;
    const std::uint64_t before = slot.seq.load(std::memory_order_acquire);
    if (before == committed) {
      const std::uint32_t size = slot.size.load(std::memory_order_relaxed);
      const bool valid = size != kReleasedSlot && copy(ring.payload(slot), size);
      seqlock_fence(std::memory_order_acquire);
      if (slot.seq.load(std::memory_order_relaxed) != before) {
        ring_resync(ring, cursor);
        continue;
      }
      ++cursor.next;
      cursor.stall_since_ns = 0;
      cursor.empty_polls = 0;
      if (size == kReleasedSlot) {
        continue;
      }
      return valid ? 1 : -1;
    }
    if (before > committed) {
      ring_resync(ring, cursor);
      continue;
    }
    if (!check_stall && ++cursor.empty_polls % kStallCheckInterval != 0) {
      return 0;
    }
    if (!ring_writer_gone(ring, cursor)) {
      return 0;
    }
    ++cursor.lost;
    ++cursor.next;
    cursor.stall_since_ns = 0;
  }
  return 0;
}

/// Whether the reader's next ticket is readable (or was overwritten, which try_recv resolves).
inline bool ring_ready(const RingView& ring, const ReadCursor& cursor) noexcept {
  return ring.slot(cursor.next).seq.load(std::memory_order_acquire) >= 2 * cursor.next + 2;
}

/// Copies the newest committed message with `copy`, without moving any cursor.
template <class Copy>
bool ring_read_latest(const RingView& ring, Copy&& copy) noexcept {
  const std::uint64_t written = ring_written(ring);
  const std::uint64_t depth = written < ring.capacity() ? written : ring.capacity();
  for (std::uint64_t back = 1; back <= depth; ++back) {
    const std::uint64_t ticket = written - back;
    SlotHeader& slot = ring.slot(ticket);
    const std::uint64_t before = slot.seq.load(std::memory_order_acquire);
    if (before != 2 * ticket + 2) {
      continue;
    }
    const std::uint32_t size = slot.size.load(std::memory_order_relaxed);
    if (size == kReleasedSlot) {
      continue;
    }
    const bool valid = copy(ring.payload(slot), size);
    seqlock_fence(std::memory_order_acquire);
    if (valid && slot.seq.load(std::memory_order_relaxed) == before) {
      return true;
    }
  }
  return false;
}

}  // namespace horus::detail
