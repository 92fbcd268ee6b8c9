// horus::NodeMetrics: a snapshot of one node's counters, from Scheduler::node_metrics().
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace horus {

/// Counters the scheduler keeps for every node. Durations are measured around tick() only.
struct NodeMetrics {
  std::string name;
  std::int32_t order = 0;
  std::uint64_t total_ticks = 0;       // tick() calls
  std::uint64_t successful_ticks = 0;  // ... that returned normally
  std::uint64_t failed_ticks = 0;      // ... that threw
  std::uint64_t skipped_ticks =
      0;  // releases not ticked (Miss::Skip, Unhealthy, Isolated, cooldown)
  std::chrono::nanoseconds avg_tick_duration{0};
  std::chrono::nanoseconds max_tick_duration{0};
  std::chrono::nanoseconds min_tick_duration{0};
  std::chrono::nanoseconds last_tick_duration{0};
  std::uint64_t budget_overruns = 0;       // tick took longer than its budget
  std::uint64_t deadline_misses = 0;       // tick ended later than release + deadline
  std::uint64_t watchdog_expirations = 0;  // a tick passed the watchdog timeout
  std::uint64_t errors_count = 0;          // exceptions from init/tick/shutdown
  std::uint64_t warnings_count = 0;        // Miss::Warn misses and watchdog warnings
  std::uint64_t restarts = 0;              // re-inits under FailurePolicy::Restart
  std::uint64_t messages_sent = 0;         // by its topics inside its callbacks
  std::uint64_t messages_received = 0;     // ... messages its topics returned there
  double achieved_rate_hz = 0.0;           // ticks per second of uptime
  std::chrono::nanoseconds uptime{0};      // since init() succeeded
};

}  // namespace horus
