// detail::NodeSlot: one registered node with its settings, runtime state and counters.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/internal/param_owner.hpp"
#include "horus/internal/tick_log.hpp"
#include "horus/internal/topic_notifier.hpp"
#include "horus/scheduler.hpp"
#include "tick_context.hpp"

namespace horus::detail {

/// One registered node with its settings, its runtime state and its counters.
///
/// Ownership: fields without std::atomic are touched only by the thread that currently runs the
/// node (its executor during a loop, the caller of tick_once otherwise); hand-over between them is
/// a thread start or join. Atomics are what other threads (watchdog, introspection) read or poke.
struct NodeSlot : std::enable_shared_from_this<NodeSlot> {
  std::shared_ptr<Node> node;
  std::string name;
  std::size_t registration = 0;  // insertion index: breaks order() ties
  NodeConfig config;
  bool built = false;

  // Derived at start-up.
  ExecutionClass execution_class = ExecutionClass::BestEffort;
  bool budget_auto = false;
  bool deadline_auto = false;
  // Atomic: add_critical_node() may change them while the node's thread and the watchdog run.
  std::atomic<bool> critical{false};
  std::int64_t critical_timeout_ns = 0;
  std::atomic<std::int64_t> period_ns{0};
  std::atomic<std::int64_t> budget_ns{0};    // 0: none
  std::atomic<std::int64_t> deadline_ns{0};  // 0: none
  std::atomic<std::int64_t> watchdog_ns{0};  // 0: none
  std::unique_ptr<TopicNotifier> notifier;
  /// The node's ticks on their way to the session recording; null while nothing records. Set
  /// before the node first runs and never reset, so the running thread reads it unguarded.
  std::shared_ptr<TickLog> tick_log;
  /// The node's parameter store and write service, from its start until it is shut down; null
  /// for a node without parameters. Set before the node first runs, so its thread reads it
  /// unguarded.
  std::unique_ptr<ParamOwner> params;

  // Lifecycle.
  std::atomic<NodeState> state{NodeState::Uninitialized};
  std::atomic<NodeHealthState> health{NodeHealthState::Healthy};
  std::atomic<bool> pending_safe_state{false};
  std::atomic<bool> remove_requested{false};
  std::atomic<bool> removed{false};
  bool init_attempted = false;
  bool initialized = false;  // init() succeeded at least once (so shutdown() is owed)
  bool shut_down = false;
  bool restart_pending = false;

  // Release bookkeeping (executing thread only).
  std::int64_t next_release_ns = 0;
  bool warm_up = false;  // the node's first tick in this loop: timed, not judged
  std::int64_t last_tick_start_ns = -1;
  std::int64_t resume_at_ns = 0;        // Restart backoff / Skip cooldown
  std::int64_t unhealthy_until_ns = 0;  // Unhealthy rest period
  bool skip_next = false;
  std::uint32_t consecutive_failures = 0;
  std::uint32_t restart_attempts = 0;
  std::int64_t miss_logged_ns = 0;  // when a deadline miss of this node was last logged
  Rng rng;
  TickContext context;
  std::int64_t init_done_ns = 0;

  // Watchdog.
  std::atomic<std::int64_t> tick_started_ns{0};  // 0: not inside tick()
  std::atomic<std::uint8_t> watchdog_level{0};   // timeouts reached by the current/last tick

  // Counters (single writer: the executing thread; relaxed loads elsewhere).
  std::atomic<std::uint64_t> total_ticks{0};
  std::atomic<std::uint64_t> failed_ticks{0};
  std::atomic<std::uint64_t> skipped_ticks{0};
  std::atomic<std::int64_t> sum_tick_ns{0};
  std::atomic<std::int64_t> max_tick_ns{0};
  std::atomic<std::int64_t> min_tick_ns{0};
  std::atomic<std::int64_t> last_tick_ns{0};
  std::atomic<std::uint64_t> budget_overruns{0};
  std::atomic<std::uint64_t> deadline_misses{0};
  std::atomic<std::uint64_t> watchdog_expirations{0};
  std::atomic<std::uint64_t> errors{0};
  std::atomic<std::uint64_t> warnings{0};
  std::atomic<std::uint64_t> restarts{0};
  MessageCounts messages;                         // by the node's topics, inside its callbacks
  std::atomic<std::int64_t> running_since_ns{0};  // monotonic; 0 before init
  std::atomic<std::int64_t> stopped_at_ns{0};     // monotonic; 0 until shut down

  // Error path and introspection only (guarded by SchedulerImpl::mutex_).
  std::string last_error;
  std::vector<TopicMetadata> publishers;
  std::vector<TopicMetadata> subscribers;
};

using SlotPtr = std::shared_ptr<NodeSlot>;

/// Rt nodes without an explicit budget get 80 % of their period, and a deadline of 95 % (never
/// below the budget): room for the thread to wake and for earlier nodes in the same release.
inline std::int64_t automatic_budget_ns(std::int64_t period_ns) noexcept {
  return period_ns * 8 / 10;
}
inline std::int64_t automatic_deadline_ns(std::int64_t period_ns, std::int64_t budget_ns) noexcept {
  return std::max(period_ns * 95 / 100, budget_ns);
}

}  // namespace horus::detail
