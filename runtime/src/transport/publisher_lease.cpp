// The publisher lease, the hand-over to shared claims, and the asymmetric barrier that lets a
// lease holder skip its own.
#include "horus/detail/publisher_lease.hpp"

#include <linux/membarrier.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <utility>

namespace horus::detail {

namespace {

/// Registers this process for the sleepers' membarrier, once per process: a forked child
/// registers itself again rather than trust its parent's registration. ThreadSanitizer cannot
/// see a barrier run by the kernel on another CPU, so its builds keep the publisher's own
/// barrier, which it can check.
bool covered_by_sleeper_barrier() noexcept {
#if defined(__SANITIZE_THREAD__)
  return false;
#else
  static std::atomic<std::uint32_t> registered_pid{0};
  const std::uint32_t pid = this_pid();
  if (registered_pid.load(std::memory_order_acquire) == pid) {
    return true;
  }
  if (syscall(SYS_membarrier, MEMBARRIER_CMD_REGISTER_GLOBAL_EXPEDITED, 0, 0) != 0) {
    return false;
  }
  registered_pid.store(pid, std::memory_order_release);
  return true;
#endif
}

bool global_barrier() noexcept {
  return syscall(SYS_membarrier, MEMBARRIER_CMD_GLOBAL_EXPEDITED, 0, 0) == 0;
}

std::uint64_t make_token(bool fence_free) noexcept {
  static std::atomic<std::uint32_t> serial{0};
  return static_cast<std::uint64_t>(this_pid()) << 32 | (fence_free ? kLeaseFenceFree : 0) |
         (serial.fetch_add(1, std::memory_order_relaxed) & kLeaseSerialMask);
}

/// The first ticket write_index numbers: `proposed`, unless somebody settled it first.
std::uint64_t settle_shared_base(RingControl& control, std::uint64_t proposed) noexcept {
  std::uint64_t unset = 0;
  control.shared_base.compare_exchange_strong(unset, proposed + 1, std::memory_order_acq_rel,
                                              std::memory_order_acquire);
  return ring_shared_base(control);
}

}  // namespace

void prepare_publisher_leases() noexcept { covered_by_sleeper_barrier(); }

bool ring_sleeper_barrier(const RingControl& control) noexcept {
  return !ring_leased(control) || global_barrier();
}

bool ring_share(RingView& ring) noexcept {
  RingControl& control = *ring.control;
  std::uint64_t base = ring_shared_base(control);
  if (base == kUnshared) {
    std::uint64_t lease = control.publisher_lease.load(std::memory_order_acquire);
    while ((lease & kLeaseShared) == 0 &&
           !control.publisher_lease.compare_exchange_weak(
               lease, lease | kLeaseShared, std::memory_order_seq_cst, std::memory_order_acquire)) {
    }
    // Past the barrier, every claim the holder made without seeing kLeaseShared has its
    // announcement visible here; every later one sees kLeaseShared. A holder that does not rely
    // on membarrier orders the two itself, and one that has exited claims nothing more (its
    // stores were made visible when its threads exited), so neither needs the barrier.
    if ((lease & kLeaseFenceFree) != 0 && !global_barrier() &&
        identity_alive(static_cast<std::uint32_t>(lease >> 32))) {
      return false;
    }
    base = settle_shared_base(control, control.lease_announce.load(std::memory_order_seq_cst));
  }
  ring.shared_base = base;
  return true;
}

PublisherLease::PublisherLease(PublisherLease&& other) noexcept
    : control_(std::exchange(other.control_, nullptr)),
      token_(other.token_),
      next_ticket_(other.next_ticket_) {}

PublisherLease& PublisherLease::operator=(PublisherLease&& other) noexcept {
  if (this != &other) {
    release();
    control_ = std::exchange(other.control_, nullptr);
    token_ = other.token_;
    next_ticket_ = other.next_ticket_;
  }
  return *this;
}

PublisherLease::~PublisherLease() { release(); }

bool PublisherLease::acquire(RingView& ring) noexcept {
  // Registered before the lease is taken, so no commit under the lease is ever unfenced.
  const bool fence_free = covered_by_sleeper_barrier();
  const std::uint64_t token = make_token(fence_free);
  RingControl& control = *ring.control;
  std::uint64_t holder = control.publisher_lease.load(std::memory_order_acquire);
  do {
    if ((holder & kLeaseShared) != 0 ||
        (holder != 0 && process_alive(static_cast<std::uint32_t>(holder >> 32)))) {
      return false;
    }
  } while (!control.publisher_lease.compare_exchange_weak(holder, token, std::memory_order_acq_rel,
                                                          std::memory_order_acquire));
  control_ = &control;
  token_ = token;
  // A dead holder's half-written ticket is written again: it never became visible.
  next_ticket_ = control.commits.load(std::memory_order_acquire);
  ring.fence_free = fence_free;
  return true;
}

Claim PublisherLease::let_go(RingView& ring, std::uint64_t ticket) noexcept {
  // Proposing `ticket` says this holder has not written it. Whoever shared the ring proposes
  // the announcement it saw, which may already count it: the ticket is then still ours.
  const std::uint64_t base = settle_shared_base(*control_, ticket);
  ring.shared_base = base;
  // The lease word keeps kLeaseShared, so nobody takes the lease again: nothing to release.
  control_ = nullptr;
  if (ticket < base) {
    return ring_claim_leased(ring, ticket);
  }
  return ring_claim(ring, this_pid());
}

void PublisherLease::release() noexcept {
  // A forked child's copy of the handle does not give away its parent's lease.
  if (!held()) {
    return;
  }
  std::uint64_t expected = token_;
  if (!control_->publisher_lease.compare_exchange_strong(expected, 0, std::memory_order_acq_rel) &&
      expected == (token_ | kLeaseShared)) {
    // A second publisher shares the ring and may be waiting for the first ticket write_index
    // numbers (its barrier failed): this holder writes nothing more, so it is the next one.
    static_cast<void>(settle_shared_base(*control_, next_ticket_));
  }
  control_ = nullptr;
}

}  // namespace horus::detail
