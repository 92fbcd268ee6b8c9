// horus::Scheduler: runs nodes in order, at their rates, with budgets, deadlines, a graduated
// watchdog, failure policies, a flight recorder and reverse-order shutdown on Ctrl+C / SIGTERM.
//
//   horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).watchdog(500_ms)};
//   sched.add(std::make_unique<MotorController>())
//       .order(1).rate(100_hz).budget(200_us).deadline(900_us).on_miss(horus::Miss::SafeMode)
//       .build();
//   return sched.run();
//
// See runtime/src/scheduler/README.md for the execution classes, the release grid and how
// misses and the watchdog are decided.
#pragma once

#include <chrono>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/error.hpp"
#include "horus/failure_policy.hpp"
#include "horus/live_view_options.hpp"
#include "horus/miss.hpp"
#include "horus/network.hpp"
#include "horus/node.hpp"
#include "horus/node_metrics.hpp"
#include "horus/node_state.hpp"
#include "horus/rate.hpp"
#include "horus/topic_metadata.hpp"

namespace horus {

namespace detail {
class SchedulerImpl;
struct NodeSlot;
/// The running program's name (its executable's file name; "horus" when unknown): a scheduler's
/// default name, so that two programs' log lines and announcements can be told apart.
std::string program_name();
}  // namespace detail

/// How a node is run; inferred from its settings (first match wins):
/// on(topic) -> Event, async_io() -> AsyncIo, compute() -> Compute, rate/budget/deadline -> Rt,
/// otherwise BestEffort.
enum class ExecutionClass : std::uint8_t {
  BestEffort,  // main thread, in order, every scheduler tick
  Rt,  // a dedicated thread per (rate, core, priority) group, in order; SCHED_FIFO when allowed
  Compute,  // the compute thread pool
  Event,    // a thread that sleeps until the topic receives a message
  AsyncIo,  // its own thread, where blocking I/O stalls nothing else
};

std::string_view to_string(ExecutionClass c) noexcept;

enum class SchedulerStatus : std::uint8_t { Idle, Running, Stopped };

std::string_view to_string(SchedulerStatus s) noexcept;

/// Scheduler-wide settings, chained:
/// SchedulerConfig{}.tick_rate(1000_hz).rt(true).watchdog(500_ms).
class SchedulerConfig {
 public:
  /// Rate of the main loop (BestEffort nodes) and the default rate of other nodes. Default 1 kHz.
  SchedulerConfig& tick_rate(Rate r) {
    tick_rate_ = r;
    return *this;
  }
  /// Ask for SCHED_FIFO on Rt threads, mlockall, and the kernel's isolated CPUs (isolcpus) for Rt
  /// threads not pinned by core()/cores(); what cannot be had is listed in degradations().
  SchedulerConfig& rt(bool on) {
    rt_ = on;
    return *this;
  }
  /// SimClock: time advances exactly one period per tick, rng_float() is seeded, everything runs on
  /// the calling thread in order, and wall-clock timing (budget, deadline, watchdog) is not
  /// enforced.
  SchedulerConfig& deterministic(bool on) {
    deterministic_ = on;
    return *this;
  }
  /// Seed of the deterministic random sequences.
  SchedulerConfig& seed(std::uint64_t s) {
    seed_ = s;
    return *this;
  }
  /// Frozen-node detection for every node (per-node watchdog() overrides). Zero disables.
  SchedulerConfig& watchdog(std::chrono::nanoseconds timeout) {
    watchdog_ = timeout;
    return *this;
  }
  /// Flight recorder size in MiB; zero disables it.
  SchedulerConfig& blackbox_mb(std::size_t mb) {
    blackbox_mb_ = mb;
    return *this;
  }
  /// Where the blackbox is written on a crash or a fatal stop. Default: "<name>.blackbox".
  SchedulerConfig& blackbox_path(std::filesystem::path p) {
    blackbox_path_ = std::move(p);
    return *this;
  }
  /// Stop the scheduler after this many deadline misses in total, all nodes together (default
  /// 100, as in Rust; nullopt: never). Every node with a rate has a deadline (95 % of its period
  /// unless NodeSettings::deadline() says otherwise), so a busy machine can reach it.
  SchedulerConfig& max_deadline_misses(std::optional<std::uint64_t> n) {
    max_deadline_misses_ = n;
    return *this;
  }
  /// What the scheduler's own log lines ("@<name>"), `horus node list`, telemetry and the
  /// blackbox call it. Default: the program's name (detail::program_name()).
  SchedulerConfig& name(std::string n) {
    name_ = std::move(n);
    return *this;
  }
  /// Pin every scheduler thread to these CPUs.
  SchedulerConfig& cores(std::vector<int> c) {
    cores_ = std::move(c);
    return *this;
  }
  SchedulerConfig& verbose(bool on) {
    verbose_ = on;
    return *this;
  }
  /// Threads of the Compute pool (default: one per CPU, at most one per compute node).
  SchedulerConfig& compute_threads(std::size_t n) {
    compute_threads_ = n;
    return *this;
  }
  /// How long each node's shutdown() may take before it is abandoned (default 3 s).
  SchedulerConfig& shutdown_timeout(std::chrono::nanoseconds t) {
    shutdown_timeout_ = t;
    return *this;
  }
  /// Export every node's metrics and health as JSON every telemetry_interval (default 1 s) while
  /// a loop runs, and once when run() ends: "udp://HOST:PORT" sends one datagram per snapshot,
  /// "file:///PATH" replaces the file each time. Empty (the default): off.
  SchedulerConfig& telemetry(std::string endpoint) {
    telemetry_ = std::move(endpoint);
    return *this;
  }
  SchedulerConfig& telemetry_interval(std::chrono::nanoseconds interval) {
    telemetry_interval_ = interval;
    return *this;
  }
  /// Keep the topics this process created in shared memory when the scheduler is destroyed, for
  /// late joiners. Default off: once its nodes are gone, the scheduler removes every topic
  /// segment this process created that no live process has open any more (seed 001, shutdown).
  SchedulerConfig& keep_topics(bool on) {
    keep_topics_ = on;
    return *this;
  }
  /// Record a session (docs/recording.md): every topic the nodes publish or subscribe (as their
  /// publishers()/subscribers() name them, and every topic this process has open once they are
  /// initialised) and every node's ticks go to one MCAP file in
  /// recordings_directory() ($HORUS_RECORDINGS), from the first run()/tick_once() until
  /// stop_recording() or the scheduler's end. Recording runs on a thread of its own.
  SchedulerConfig& recording(bool on) {
    recording_ = on;
    return *this;
  }
  /// Deterministic mode only: feeds the recording at `path` into its topics (all but those the
  /// nodes publish and "/horus/ticks"), each message before the cycle in which the recording
  /// received it, so the nodes' outputs are the same run after run. A topic whose type changed
  /// since the recording (another fingerprint) is refused with an error naming it.
  SchedulerConfig& replay(std::filesystem::path path) {
    replay_ = std::move(path);
    return *this;
  }
  /// Whether run()/run_for()/tick_for() turn SIGINT and SIGTERM into a clean stop (default on).
  SchedulerConfig& handle_signals(bool on) {
    handle_signals_ = on;
    return *this;
  }

  /// Carry topics to and from other hosts over Cyclone DDS (docs/dds-bridge.md): the scheduler
  /// runs the DDS bridge with these options, in its namespace, on threads of its own process
  /// from its construction until run() ends (or it is destroyed); the program links horus::dds.
  /// A bridge that fails stops the scheduler, and run() returns 1. The Scheduler's constructor
  /// throws horus::Error for an invalid Network, options the bridge does not carry yet, and a
  /// program not linked with horus::dds.
  SchedulerConfig& network(Network n) {
    network_ = std::move(n);
    return *this;
  }
  /// Serve this scheduler's namespace to Foxglove, Lichtblick and the built-in page over the
  /// Foxglove WebSocket protocol (docs/live-view.md), from its construction until run() ends (or
  /// it is destroyed), on threads of its own process; the program links horus::view. The view
  /// tells viewers the scheduler's clock (simulated time in deterministic mode) unless the
  /// options give one. A view that fails stops the scheduler, and run() returns 1. The
  /// Scheduler's constructor throws horus::Error for invalid options, an address it cannot
  /// listen on, and a program not linked with horus::view.
  SchedulerConfig& view(LiveViewOptions options) {
    view_ = std::move(options);
    return *this;
  }
  /// A YAML parameter file (docs/parameters.md: `node: {name: value}`) whose values each node of
  /// this scheduler starts with, applied after its defaults and before init(). A malformed file,
  /// an unknown node or parameter, or a value outside its declaration stops the start with
  /// horus::ParamError saying `FILE:LINE: reason` (every error of the file). Without one, the
  /// file named by the environment variable HORUS_PARAMS_FILE is used (`horus launch` sets it
  /// for a process whose entry gives `params:`).
  SchedulerConfig& params(std::filesystem::path file) {
    params_ = std::move(file);
    return *this;
  }

  Rate tick_rate() const { return tick_rate_; }
  bool rt() const { return rt_; }
  bool deterministic() const { return deterministic_; }
  std::uint64_t seed() const { return seed_; }
  std::chrono::nanoseconds watchdog() const { return watchdog_; }
  std::size_t blackbox_mb() const { return blackbox_mb_; }
  const std::filesystem::path& blackbox_path() const { return blackbox_path_; }
  std::optional<std::uint64_t> max_deadline_misses() const { return max_deadline_misses_; }
  const std::string& name() const { return name_; }
  const std::vector<int>& cores() const { return cores_; }
  bool verbose() const { return verbose_; }
  std::size_t compute_threads() const { return compute_threads_; }
  std::chrono::nanoseconds shutdown_timeout() const { return shutdown_timeout_; }
  const std::string& telemetry() const { return telemetry_; }
  std::chrono::nanoseconds telemetry_interval() const { return telemetry_interval_; }
  bool keep_topics() const { return keep_topics_; }
  bool handle_signals() const { return handle_signals_; }
  bool recording() const { return recording_; }
  const std::filesystem::path& replay() const { return replay_; }
  const std::optional<Network>& network() const { return network_; }
  const std::optional<LiveViewOptions>& view() const { return view_; }
  const std::filesystem::path& params() const { return params_; }

 private:
  Rate tick_rate_ = Rate::hz(1000.0);
  bool rt_ = false;
  bool deterministic_ = false;
  std::uint64_t seed_ = 0x5EED'0F'4085ULL;
  std::chrono::nanoseconds watchdog_{0};
  std::size_t blackbox_mb_ = 0;
  std::filesystem::path blackbox_path_;
  std::optional<std::uint64_t> max_deadline_misses_ = 100;
  std::string name_ = detail::program_name();
  std::vector<int> cores_;
  bool verbose_ = false;
  std::size_t compute_threads_ = 0;
  std::chrono::nanoseconds shutdown_timeout_ = std::chrono::seconds(3);
  std::string telemetry_;
  std::chrono::nanoseconds telemetry_interval_ = std::chrono::seconds(1);
  bool keep_topics_ = false;
  bool handle_signals_ = true;
  bool recording_ = false;
  std::filesystem::path replay_;
  std::optional<Network> network_;
  std::optional<LiveViewOptions> view_;
  std::filesystem::path params_;
};

/// A node's scheduling settings as given to the builder (unset optionals are derived at start-up).
struct NodeConfig {
  std::int32_t order = 100;  // lower runs first: 0-9 critical, 10-49 high, 50-99 normal, 100+ low
  std::optional<Rate> rate;
  std::optional<std::chrono::nanoseconds> budget;    // default 80 % of the period (Rt)
  std::optional<std::chrono::nanoseconds> deadline;  // default 95 % of the period (Rt)
  Miss on_miss = Miss::Warn;
  FailurePolicy failure_policy;
  bool compute = false;
  std::optional<std::string> on_topic;
  bool async_io = false;
  std::optional<int> priority;  // SCHED_FIFO 1..99, needs rt
  std::optional<int> core;
  std::optional<std::chrono::nanoseconds> watchdog;
};

/// The chained node settings shared by Scheduler::add()'s NodeBuilder and horus::RunNode.
template <class Self>
class NodeSettings {
 public:
  Self& order(std::int32_t o) {
    settings().order = o;
    return self();
  }
  Self& rate(Rate r) {
    settings().rate = r;
    return self();
  }
  Self& budget(std::chrono::nanoseconds b) {
    settings().budget = b;
    return self();
  }
  Self& deadline(std::chrono::nanoseconds d) {
    settings().deadline = d;
    return self();
  }
  Self& on_miss(Miss m) {
    settings().on_miss = m;
    return self();
  }
  Self& failure_policy(FailurePolicy p) {
    settings().failure_policy = p;
    return self();
  }
  Self& compute(bool on = true) {
    settings().compute = on;
    return self();
  }
  /// Event node: tick only when `topic` receives a message (the thread sleeps meanwhile).
  Self& on(std::string topic) {
    settings().on_topic = std::move(topic);
    return self();
  }
  Self& async_io(bool on = true) {
    settings().async_io = on;
    return self();
  }
  Self& priority(int p) {
    settings().priority = p;
    return self();
  }
  Self& core(int c) {
    settings().core = c;
    return self();
  }
  Self& watchdog(std::chrono::nanoseconds t) {
    settings().watchdog = t;
    return self();
  }
  /// Replaces every setting at once (language bindings).
  Self& configure(const NodeConfig& config) {
    settings() = config;
    return self();
  }

 private:
  NodeConfig& settings() { return static_cast<Self&>(*this).node_config(); }
  Self& self() { return static_cast<Self&>(*this); }
};

class Scheduler;

/// A node and its settings, chained as on Scheduler::add()'s NodeBuilder (a bare node gets the
/// defaults): what seed 001's Python Node carries in its keywords. Scheduler::add(RunNode) adds
/// and builds it at once and returns the scheduler, so that additions chain as the seed writes
/// them (`sched.add(safety).add(lidar)`); horus::run takes a list of them.
class RunNode : public NodeSettings<RunNode> {
 public:
  template <std::derived_from<Node> N>
  RunNode(std::shared_ptr<N> node)  // NOLINT(google-explicit-constructor): run({a, b})
      : node_(std::move(node)) {}
  const std::shared_ptr<Node>& node() const noexcept { return node_; }
  const NodeConfig& config() const noexcept { return config_; }

 private:
  friend class NodeSettings<RunNode>;
  NodeConfig& node_config() { return config_; }
  std::shared_ptr<Node> node_;
  NodeConfig config_;
};

/// Returned by Scheduler::add(); set what you need, then build() (which validates and throws
/// horus::Error). A node added without build() makes the next run()/tick_once() throw.
class [[nodiscard]] NodeBuilder : public NodeSettings<NodeBuilder> {
 public:
  /// Validates the settings and the name's uniqueness; throws horus::Error saying what is wrong.
  Scheduler& build();

 private:
  friend class Scheduler;
  friend class NodeSettings<NodeBuilder>;
  NodeBuilder(Scheduler& s, NodeConfig* c) : scheduler_(&s), config_(c) {}
  NodeConfig& node_config() { return *config_; }
  Scheduler* scheduler_;
  NodeConfig* config_;
};

/// What the scheduler knows about one node.
struct NodeInfo {
  std::string name;
  std::int32_t order = 0;
  ExecutionClass execution_class = ExecutionClass::BestEffort;
  NodeState state = NodeState::Uninitialized;
  NodeHealthState health = NodeHealthState::Healthy;
  std::optional<Rate> rate;
  std::optional<std::chrono::nanoseconds> budget;
  std::optional<std::chrono::nanoseconds> deadline;
  std::optional<std::chrono::nanoseconds> watchdog;
  Miss on_miss = Miss::Warn;
  FailurePolicy::Kind failure_policy = FailurePolicy::Kind::Fatal;
  bool critical = false;
  std::optional<std::string> on_topic;
  std::optional<int> priority;  // as given to NodeSettings::priority()
  std::string last_error;
  std::vector<TopicMetadata> publishers;  // as reported after init()
  std::vector<TopicMetadata> subscribers;
};

struct SafetyStats {
  std::uint64_t budget_overruns = 0;
  std::uint64_t deadline_misses = 0;
  std::uint64_t watchdog_expirations = 0;
  std::vector<std::pair<std::string, NodeHealthState>> health_states;
};

/// What rt() actually obtained.
struct RtCapabilities {
  bool rt_scheduling = false;      // SCHED_FIFO could be set
  bool memory_locking = false;     // mlockall succeeded
  bool cpu_isolation = false;      // the kernel has isolated CPUs (isolcpus)
  std::vector<int> isolated_cpus;  // where Rt threads go unless pinned by core()/cores()
};

class Scheduler {
 public:
  /// Throws horus::Error for an invalid configuration (non-positive rate, unknown cores, ...).
  explicit Scheduler(SchedulerConfig config = {});
  /// Shuts down nodes that were initialised and not yet shut down (reverse order).
  ~Scheduler();
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  /// Registers a node; finish with .build(). Throws horus::Error for a null node.
  /// Takes std::make_unique<MyNode>() as well; the scheduler shares ownership so that a language
  /// binding can keep its own reference to the object it handed over.
  ///
  /// Also while the scheduler runs, from any thread or from a node's callback: the node is
  /// initialised at the loop's next cycle (on the thread of run()), then ticks at its rate on a
  /// thread of its own (BestEffort nodes join the main loop), shows in introspection and presence
  /// at once, and is shut down in reverse order with the others.
  NodeBuilder add(std::shared_ptr<Node> node);
  template <std::derived_from<Node> N>
  NodeBuilder add(std::shared_ptr<N> node) {
    return add(std::shared_ptr<Node>(std::move(node)));
  }
  /// Adds and builds a node with its settings (throws horus::Error as build() does); returns the
  /// scheduler so that additions chain: sched.add(imu).add(attitude).add(esc).
  Scheduler& add(const RunNode& node);

  /// Marks a built node safety-critical with its own watchdog timeout: past 3x it is Isolated and
  /// every other node is asked to enter its safe state. Also while running (the watchdog picks the
  /// node up at the loop's next cycle). Throws horus::Error for an unknown node.
  void add_critical_node(std::string_view name, std::chrono::nanoseconds timeout);

  /// Initialises nodes (first time), runs until stop(), Ctrl+C, SIGTERM or a fatal failure, then
  /// shuts every node down in reverse order. Returns 0, or 1 when a failure stopped it.
  int run();
  /// As run(), but stops on its own after `duration` (simulated time in deterministic mode).
  int run_for(std::chrono::nanoseconds duration);
  /// One cycle on the calling thread, no sleeping: every node ticks once (in deterministic mode,
  /// the nodes due at this simulated time; event nodes only when their topic has a message).
  void tick_once();
  /// As tick_once(), only for the named nodes (the others stay frozen).
  void tick_once(const std::vector<std::string>& names);
  /// Runs the real loop (threads and all) for `duration`, optionally only for `names`, then returns
  /// without shutting nodes down.
  void tick_for(std::chrono::nanoseconds duration, const std::vector<std::string>& names = {});
  /// Asks the loop to end; safe from any thread, a node's tick, or a signal handler's caller.
  void stop() noexcept;

  /// Runtime changes; false when no such node. set_node_rate re-derives automatic budget/deadline.
  bool set_node_rate(std::string_view name, Rate rate);
  bool set_tick_budget(std::string_view name, std::chrono::nanoseconds budget);
  /// Shuts the node down (on its own thread when running) and removes it.
  bool remove_node(std::string_view name);

  SchedulerStatus status() const noexcept;
  bool is_running() const noexcept;
  /// Main-loop cycles so far (tick_once() calls included).
  std::uint64_t current_tick() const noexcept;
  const std::string& name() const noexcept;
  const SchedulerConfig& config() const noexcept;
  /// Why the scheduler stopped ("" while it has not been asked to).
  std::string stop_reason() const;

  std::size_t node_count() const;
  std::vector<std::string> node_names() const;  // in execution order
  bool has_node(std::string_view name) const;
  std::optional<NodeInfo> node_info(std::string_view name) const;
  std::vector<NodeInfo> nodes() const;
  std::optional<NodeMetrics> node_metrics(std::string_view name) const;
  SafetyStats safety_stats() const;
  /// A table of every node's rate, tick times, misses and health.
  std::string timing_report() const;

  bool has_full_rt() const;
  std::vector<std::string> degradations() const;
  RtCapabilities capabilities() const;

  /// The flight recorder, or nullptr when blackbox_mb is 0.
  const Blackbox* blackbox() const noexcept;
  /// Writes the flight recorder to `path`; throws horus::Error when it is disabled or unwritable.
  void dump_blackbox(const std::filesystem::path& path) const;

  /// Whether a session is being recorded (SchedulerConfig::recording): from the first
  /// run()/tick_once() until stop_recording().
  bool is_recording() const noexcept;
  /// Finishes the session file(s) and returns their paths (empty when nothing was recording).
  std::vector<std::filesystem::path> stop_recording();
  /// The sessions in recordings_directory() (horus::list_recordings()).
  std::vector<std::string> list_recordings() const;
  /// Removes a session file by name (horus::delete_recording()); whether it existed.
  bool delete_recording(std::string_view name);

 private:
  friend class NodeBuilder;
  std::shared_ptr<detail::SchedulerImpl> impl_;
};

}  // namespace horus
