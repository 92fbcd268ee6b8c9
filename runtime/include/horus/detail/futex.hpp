// Cross-process futex wait/wake on a 32-bit word in shared memory.
//
// FUTEX_PRIVATE_FLAG is deliberately absent: the word lives in a MAP_SHARED mapping and the
// waker is usually another process, which the private variant would never wake.
#pragma once

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <climits>
#include <cstdint>
#include <ctime>

namespace horus::detail {

static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t) &&
                  std::atomic<std::uint32_t>::is_always_lock_free,
              "the futex word must be a plain lock-free 32-bit integer");

/// Sleeps while `*word == expected`, at most `timeout`. Returns on a wake, a timeout, a signal or
/// when the word already differs; the caller re-checks its condition in every case.
inline void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected,
                       std::chrono::nanoseconds timeout) noexcept {
  if (timeout <= std::chrono::nanoseconds::zero()) {
    return;
  }
  const auto secs = std::chrono::duration_cast<std::chrono::seconds>(timeout);
  timespec relative{};
  relative.tv_sec = static_cast<time_t>(secs.count());
  relative.tv_nsec = static_cast<long>((timeout - secs).count());
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAIT, expected, &relative,
          nullptr, 0);
}

/// Wakes every thread of every process sleeping on `word`; returns how many there were (-1 on
/// error).
inline long futex_wake_all(std::atomic<std::uint32_t>& word) noexcept {
  return syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE, INT_MAX, nullptr,
                 nullptr, 0);
}

}  // namespace horus::detail
