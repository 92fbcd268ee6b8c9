// The clocks of the transport's paths: a monotonic nanosecond count for stall timing, and the
// per-send stamp that tools read as "when did this topic last see traffic".
#pragma once

#include <cstdint>
#include <ctime>

namespace horus::detail {

/// Nanoseconds on `clock`, read through the vDSO (no syscall).
inline std::int64_t clock_ns(clockid_t clock) noexcept {
  timespec now{};
  clock_gettime(clock, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

/// The last-send stamp: CLOCK_REALTIME in whole seconds (unsigned 32 bits last until 2106).
/// Tools want "when did this topic last see traffic" (message timing belongs in the messages'
/// own timestamps), and time() is one load of a word the kernel keeps in the vDSO, nearly free.
/// A finer clock is not: clock_gettime(CLOCK_REALTIME_COARSE) on every send cut a raw ring's
/// throughput to about 0.6x on the benchmark machine (bench/topic/RESULTS.md).
inline std::uint32_t send_stamp_s() noexcept {
  return static_cast<std::uint32_t>(std::time(nullptr));
}

}  // namespace horus::detail
