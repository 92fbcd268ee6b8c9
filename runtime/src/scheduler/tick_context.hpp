// The per-thread state behind the framework clock (horus::now(), dt(), ...): the scheduler points
// the calling thread at a TickContext around every node callback.
#pragma once

#include <cstdint>
#include <ctime>
#include <string_view>

#include "horus/detail/message_count.hpp"

namespace horus::detail {

/// splitmix64: tiny, fast and good enough for simulation noise; fully determined by its state.
class Rng {
 public:
  explicit Rng(std::uint64_t seed = 0) noexcept : state_(seed) {}
  std::uint64_t next() noexcept {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1) with 53 bits of precision.
  double next_double() noexcept { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

struct TickContext {
  bool deterministic = false;
  std::int64_t start_ns = 0;       // scheduler start on the monotonic clock (real mode)
  std::int64_t sim_now_ns = 0;     // simulated time of this tick (deterministic mode)
  std::int64_t tick_start_ns = 0;  // monotonic (real mode)
  std::int64_t release_ns = 0;     // monotonic release of this tick (real mode)
  std::int64_t dt_ns = 0;
  std::int64_t budget_ns = 0;  // 0: no budget
  std::uint64_t tick_index = 0;
  Rng* rng = nullptr;
  std::string_view node_name;         // what log lines from this node's callbacks carry
  MessageCounts* messages = nullptr;  // what its topics count into
};

/// The calling thread's context while inside a node callback, else nullptr.
TickContext*& current_tick_context() noexcept;

/// Sets the thread's context for the lifetime of the guard (callbacks may nest through tick_once).
class TickContextScope {
 public:
  explicit TickContextScope(TickContext* ctx) noexcept
      : previous_(current_tick_context()), previous_messages_(current_message_counts) {
    current_tick_context() = ctx;
    current_message_counts = ctx != nullptr ? ctx->messages : nullptr;
  }
  ~TickContextScope() {
    current_tick_context() = previous_;
    current_message_counts = previous_messages_;
  }
  TickContextScope(const TickContextScope&) = delete;
  TickContextScope& operator=(const TickContextScope&) = delete;

 private:
  TickContext* previous_;
  MessageCounts* previous_messages_;
};

inline std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace horus::detail
