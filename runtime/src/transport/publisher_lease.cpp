// The single-publisher lease and the asymmetric barrier that lets its holder skip its own.
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

std::uint64_t make_token() noexcept {
  static std::atomic<std::uint32_t> serial{0};
  return static_cast<std::uint64_t>(this_pid()) << 32 |
         serial.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

bool ring_sleeper_barrier(const RingControl& control) noexcept {
  if (control.single_publisher.load(std::memory_order_relaxed) == 0) {
    return true;
  }
  return syscall(SYS_membarrier, MEMBARRIER_CMD_GLOBAL_EXPEDITED, 0, 0) == 0;
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
  const std::uint64_t token = make_token();
  RingControl& control = *ring.control;
  std::uint64_t holder = control.publisher_lease.load(std::memory_order_acquire);
  do {
    if (holder != 0 && process_alive(static_cast<std::uint32_t>(holder >> 32))) {
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

void PublisherLease::release() noexcept {
  // A forked child's copy of the handle does not give away its parent's lease.
  if (!held()) {
    return;
  }
  std::uint64_t expected = token_;
  control_->publisher_lease.compare_exchange_strong(expected, 0, std::memory_order_acq_rel);
  control_ = nullptr;
}

}  // namespace horus::detail
