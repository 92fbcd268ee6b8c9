// horus::detail::SchedulerImpl: the scheduler's state and algorithms (see README.md), and the
// executors its loops hand nodes to.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/internal/replayer.hpp"
#include "horus/log.hpp"
#include "horus/presence.hpp"
#include "horus/recording.hpp"
#include "horus/scheduler.hpp"
#include "node_slot.hpp"

namespace horus::detail {

/// A set of nodes run by one thread on their release grids, in order.
struct Executor {
  std::string label;
  std::vector<SlotPtr> slots;
  bool main = false;      // the main loop: passes on the scheduler's tick grid
  bool realtime = false;  // apply SCHED_FIFO when rt is on
  std::optional<int> priority;
  std::optional<int> core;
  std::atomic<bool> exited{false};
};

enum class Phase : std::uint8_t { Init, Tick, Shutdown };

/// The CPUs of a kernel CPU list ("2-3,5"); empty for an empty or malformed one.
std::vector<int> parse_cpu_list(std::string_view text);

/// what() of the exception, or "unknown exception".
std::string exception_text(std::exception_ptr error);

/// The first point of the grid `release + k * period` after `now`: a late thread skips the
/// releases it overran instead of drifting or bursting to catch up.
inline std::int64_t next_on_grid(std::int64_t release, std::int64_t period, std::int64_t now) {
  std::int64_t next = release + period;
  if (next <= now) next += ((now - next) / period + 1) * period;
  return next;
}

/// Who runs what during one real loop.
struct LoopPlan {
  std::shared_ptr<Executor> main;                    // BestEffort nodes, on the caller's thread
  std::vector<std::shared_ptr<Executor>> executors;  // Rt groups, AsyncIo nodes, the compute pool
  std::vector<SlotPtr> events;                       // one waiting thread each
  std::vector<SlotPtr> watched;                      // nodes with a watchdog timeout
};

/// When one real loop's clock starts: its threads wait for it before their first release.
struct LoopClock {
  /// Starts the clock (the loop ends at `end`) and wakes the waiting threads.
  void start(std::int64_t end) noexcept;
  /// Waits until the clock has started; returns when the loop ends.
  std::int64_t wait() const noexcept;

 private:
  std::atomic<bool> started{false};
  std::int64_t end_ns = 0;  // written before `started`
};

class ThreadGroup;
class TelemetrySink;

class SchedulerImpl : public std::enable_shared_from_this<SchedulerImpl> {
 public:
  explicit SchedulerImpl(SchedulerConfig config);
  ~SchedulerImpl();

  // Set-up.
  NodeConfig* add(std::shared_ptr<Node> node);
  void build(NodeConfig* config);
  void add_critical_node(std::string_view name, std::chrono::nanoseconds timeout);

  // Running.
  int run(std::optional<std::int64_t> duration_ns);
  void tick_once(const std::vector<std::string>* names);
  void tick_for(std::int64_t duration_ns, const std::vector<std::string>* names);
  void request_stop(std::string_view reason, bool failure) noexcept;
  /// Shuts down whatever is still initialised (the Scheduler's destructor).
  void finish() noexcept;

  // Runtime mutation.
  bool set_node_rate(std::string_view name, Rate rate);
  bool set_tick_budget(std::string_view name, std::chrono::nanoseconds budget);
  bool remove_node(std::string_view name);

  // Introspection.
  SchedulerStatus status() const noexcept;
  bool in_loop() const noexcept { return in_loop_.load(std::memory_order_acquire); }
  std::uint64_t current_tick() const noexcept { return cycle_.load(std::memory_order_relaxed); }
  const SchedulerConfig& config() const noexcept { return config_; }
  std::string stop_reason() const;
  std::vector<SlotPtr> ordered_slots() const;
  SlotPtr find(std::string_view name) const;
  NodeInfo info(const NodeSlot& slot) const;
  NodeMetrics metrics(const NodeSlot& slot) const;
  SafetyStats safety_stats() const;
  std::vector<std::string> degradations() const;
  RtCapabilities capabilities() const { return capabilities_; }
  const Blackbox* blackbox() const noexcept { return blackbox_.get(); }
  std::string timing_report() const;

  // Recording and replay (docs/recording.md).
  bool is_recording() const noexcept;
  std::vector<std::filesystem::path> stop_recording();

 private:
  class Activity;

  void derive(NodeSlot& slot) const;
  void validate(const NodeSlot& slot) const;
  void prepare();
  /// Built nodes not yet initialised: those of the first run, and those added while running.
  std::vector<SlotPtr> unstarted_slots() const;
  /// Readies, records and initialises `fresh` (in order) on the calling thread.
  void start_nodes(const std::vector<SlotPtr>& fresh);
  /// At a safe point of a real loop (between two main-loop cycles, on the thread of run()):
  /// starts the nodes added since, each on a thread of its own (BestEffort ones join `plan.main`),
  /// and watches the nodes made critical since.
  void adopt_changes(LoopPlan& plan, ThreadGroup& threads, std::int64_t end,
                     const std::vector<std::string>* names);
  void refresh_loop_slots();
  void probe_rt();
  void add_degradation(const std::string& message);

  // Lifecycle of one node (on the thread that runs it).
  bool init_node(NodeSlot& slot) noexcept;
  void service(NodeSlot& slot, std::int64_t release, std::int64_t& mono) noexcept;
  void handle_failure(NodeSlot& slot, Phase phase, const std::string& what,
                      std::int64_t sched_now) noexcept;
  void deadline_missed(NodeSlot& slot, std::int64_t late_ns, std::int64_t now_ns) noexcept;
  /// Why max_deadline_misses stopped the scheduler: the limit, each node's misses, the settings.
  std::string miss_limit_reason(std::uint64_t limit) const;
  /// A node that keeps missing is logged at most this often (its first miss at once).
  static constexpr std::int64_t kMissLogIntervalNs = 10'000'000'000;
  void escalate(NodeSlot& slot, std::uint8_t level) noexcept;
  void set_health(NodeSlot& slot, NodeHealthState health) noexcept;
  void enter_safe(NodeSlot& slot) noexcept;
  void shutdown_node(const SlotPtr& slot, bool removing) noexcept;
  void shutdown_all() noexcept;
  void purge_removed() noexcept;

  // Loops.
  /// Services the node when its release is due (on the simulated grid in deterministic mode)
  /// and moves its release to the next grid point after now.
  void release_if_due(NodeSlot& slot, std::int64_t& mono) noexcept;
  void pass_once(const std::vector<std::string>* names);
  void real_loop(std::optional<std::int64_t> duration_ns, const std::vector<std::string>* names);
  void simulated_loop(std::optional<std::int64_t> duration_ns,
                      const std::vector<std::string>* names);
  LoopPlan plan_loop(const std::vector<SlotPtr>& slots);
  void start_threads(const LoopPlan& plan, const std::shared_ptr<LoopClock>& clock,
                     ThreadGroup& threads);
  void run_main_loop(LoopPlan& plan, ThreadGroup& threads, std::int64_t loop_start,
                     std::int64_t end_ns, const std::vector<std::string>* names);
  void spawn_event(const SlotPtr& slot, const std::shared_ptr<LoopClock>& clock,
                   ThreadGroup& threads);
  void run_executor(Executor& ex, std::int64_t end_ns) noexcept;
  void run_event(NodeSlot& slot, std::int64_t end_ns) noexcept;
  void run_watchdog(const std::vector<SlotPtr>& watched, std::int64_t end_ns) noexcept;
  /// Calls `action` every `interval_ns` on the loop's grid until `end_ns` or the loop ends.
  void run_every(std::int64_t interval_ns, std::int64_t end_ns,
                 void (SchedulerImpl::*action)() noexcept) noexcept;
  void run_telemetry(std::int64_t end_ns) noexcept;
  void export_telemetry() noexcept;
  std::string telemetry_snapshot() const;
  /// Rewrites this scheduler's presence announcement (horus/presence.hpp) with the telemetry
  /// snapshot: off the tick path, on its own thread while running and once at the end.
  void run_presence(std::int64_t end_ns) noexcept;
  void announce_presence() noexcept;
  /// Often enough for `horus node list` and `horus monitor`, rare enough to cost nothing.
  static constexpr std::int64_t kPresenceIntervalNs = 500'000'000;
  void apply_thread_settings(const Executor& ex) noexcept;
  /// Sleeps until `mono_ns` or the loop's end, lending `slots` (the nodes this thread ticks) to
  /// their parameter services meanwhile (ParamOwner::idle/hold), and delivers what was queued.
  bool sleep_until(std::int64_t mono_ns, const std::vector<SlotPtr>* slots = nullptr) noexcept;
  /// Opens the stores of the fresh nodes that declared parameters (the parameter file read and
  /// checked first) and starts answering their writes. Throws ParamError.
  void open_param_stores(const std::vector<SlotPtr>& fresh);
  /// Wakes the thread that ticks `slot` for a parameter change (any thread).
  void wake_for_params(NodeSlot& slot) noexcept;
  /// Hands waiting parameter changes to the node, between two ticks on its own thread.
  static void deliver_params(NodeSlot& slot) noexcept {
    if (slot.params && slot.params->pending()) slot.params->deliver();
  }
  bool loop_ending() const noexcept { return wake_word_.load(std::memory_order_acquire) != 0; }
  void check_signal() noexcept;
  std::int64_t sched_now(std::int64_t mono) const noexcept {
    return config_.deterministic() ? sim_now_ns_ : mono;
  }

  /// Starts the session recording (first call) and subscribes it to the nodes' topics and ticks.
  void start_recording(const std::vector<SlotPtr>& fresh);
  /// Opens the replayed recording once the nodes' topics exist (deterministic mode).
  void start_replay();
  /// Tells the session recording the parameter values of the fresh nodes as they start, and
  /// then every change of them the nodes accept (with the cycle it took effect before).
  void record_params(const std::shared_ptr<Recorder>& recorder, const std::vector<SlotPtr>& fresh);
  /// Applies the replayed recording's parameter changes due before this tick of `slot`, on
  /// its thread, as a write would be (source "replay").
  void replay_params(NodeSlot& slot) noexcept;
  /// Hands a finished tick to the recording, if one runs (the tick path: no lock, no allocation).
  static void log_tick(NodeSlot& slot, std::uint64_t cycle, std::int64_t start,
                       std::int64_t duration, TickOutcome outcome) noexcept {
    if (slot.tick_log) {
      slot.tick_log->push(TickEntry{cycle, start, duration, outcome}, slot.messages.topics);
    }
  }

  void record(BlackboxEventKind kind, const NodeSlot& slot, std::int64_t value = 0,
              std::string_view detail = {}) noexcept;
  void record_scheduler(BlackboxEventKind kind, std::string_view detail = {}) noexcept;
  /// The scheduler's own lines, from the source "@<name>".
  void log(LogLevel level, const char* format, ...) const noexcept
      __attribute__((format(printf, 3, 4)));

  SchedulerConfig config_;
  std::int64_t tick_period_ns_;
  std::string log_source_;
  std::filesystem::path blackbox_path_;
  std::unique_ptr<Blackbox> blackbox_;
  std::unique_ptr<TelemetrySink> telemetry_;
  std::atomic<bool> telemetry_failure_logged_{false};
  std::unique_ptr<PresenceAnnouncement> presence_;  // null when the registry could not be opened
  std::atomic<bool> presence_failure_logged_{false};
  RtCapabilities capabilities_;
  bool locked_memory_ = false;

  mutable std::mutex mutex_;    // structure, strings and degradations; never held around a callback
  std::vector<SlotPtr> slots_;  // execution order: (order, registration)
  std::size_t registrations_ = 0;
  std::vector<std::string> degradations_;
  std::vector<SlotPtr> loop_slots_;  // every node, in order; refreshed between loops/passes only
  std::uint64_t loop_slots_version_ = 0;
  std::atomic<std::uint64_t> structure_version_{1};  // bumped when nodes are built or removed
  std::atomic<bool> removals_pending_{false};
  /// Nodes added with add() while running, kept out of slots_ (where the loop's threads would
  /// read their settings) until build() has them complete.
  std::vector<SlotPtr> unbuilt_;
  /// Nodes made critical while a real loop runs, for its watchdog (guarded by mutex_).
  std::vector<SlotPtr> newly_critical_;
  /// Set by build() and add_critical_node() while running: the one load a main-loop cycle pays
  /// for runtime additions.
  std::atomic<bool> changes_pending_{false};

  /// SchedulerConfig::params(), read and checked when the first nodes start.
  std::optional<ParamFileValues> param_file_;
  /// The parameter values the replayed recording's nodes started with (replay mode), read
  /// when the first nodes start: their stores start from them.
  std::optional<ParamFileValues> replay_start_params_;

  bool topic_cycle_reported_ = false;
  bool prepared_ = false;
  bool finished_ = false;
  std::atomic<bool> active_{false};   // run/tick_once/tick_for in progress
  std::atomic<bool> in_loop_{false};  // run/tick_for in progress
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> failed_{false};
  std::atomic<std::uint32_t> wake_word_{0};  // non-zero: the current loop must end
  char stop_reason_[512] = {};
  std::atomic<bool> stop_reason_set_{false};

  std::atomic<std::uint64_t> cycle_{0};
  std::atomic<std::uint64_t> total_misses_{0};
  std::atomic<std::uint64_t> total_overruns_{0};
  std::atomic<std::uint64_t> total_watchdog_{0};
  std::int64_t start_mono_ns_ = 0;
  /// Guarded by mutex_; the recorder's own thread does the work.
  std::shared_ptr<Recorder> recorder_;
  std::unique_ptr<Replayer> replayer_;
  bool recording_done_ = false;
  std::int64_t sim_now_ns_ = 0;
  /// sim_now_ns_ for other threads (a live view's clock), stored once a pass.
  std::atomic<std::int64_t> sim_clock_ns_{0};
  /// SchedulerConfig::network()'s DDS bridge and view()'s live view, from construction until
  /// run() ends. Last, so that they end (and their threads, which may request_stop(), are
  /// joined) first.
  std::unique_ptr<SchedulerCompanion> network_;
  std::unique_ptr<SchedulerCompanion> view_;
};

}  // namespace horus::detail
