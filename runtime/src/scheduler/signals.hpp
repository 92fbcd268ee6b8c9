// Process-wide signal plumbing of the scheduler's loops: SIGINT/SIGTERM become a stop, a crash
// signal dumps the blackbox. Everything a handler touches is async-signal-safe.
#pragma once

#include <csignal>

#include <atomic>
#include <cstdint>
#include <filesystem>

#include "horus/blackbox.hpp"

namespace horus::detail {

/// Sets `word` and wakes every thread asleep on it (a futex); async-signal-safe.
void wake(std::atomic<std::uint32_t>& word) noexcept;

/// The SIGINT or SIGTERM received since the last call, or 0.
int take_stop_signal() noexcept;

/// Turns SIGINT/SIGTERM into a stop of the loop for its lifetime, and dumps the blackbox on a
/// crash; restores the previous handlers afterwards.
class SignalScope {
 public:
  SignalScope(bool stop_signals, std::atomic<std::uint32_t>& word, const Blackbox* box,
              const std::filesystem::path& box_path);
  ~SignalScope();
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

 private:
  bool stop_signals_;
  bool crash_;
  struct sigaction previous_int_ {};
  struct sigaction previous_term_ {};
};

}  // namespace horus::detail
