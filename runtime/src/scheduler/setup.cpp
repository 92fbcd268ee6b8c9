// Scheduler set-up: configuration checks, RT probing, registering, validating and deriving
// nodes, lazy initialisation, and changes to nodes at runtime.
#include <sched.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <thread>

#include "horus/detail/publisher_lease.hpp"
#include "horus/error.hpp"
#include "horus/internal/created_segments.hpp"
#include "horus/internal/errno_text.hpp"
#include "horus/topic_registry.hpp"
#include "logger.hpp"
#include "scheduler_impl.hpp"
#include "telemetry.hpp"
#include "topic_order.hpp"

namespace horus::detail {
namespace {

std::string ns_text(std::int64_t ns) {
  char buf[48];
  if (ns % 1'000'000'000 == 0) {
    std::snprintf(buf, sizeof(buf), "%llds", static_cast<long long>(ns / 1'000'000'000));
  } else if (ns % 1'000'000 == 0) {
    std::snprintf(buf, sizeof(buf), "%lldms", static_cast<long long>(ns / 1'000'000));
  } else if (ns % 1'000 == 0) {
    std::snprintf(buf, sizeof(buf), "%lldus", static_cast<long long>(ns / 1'000));
  } else {
    std::snprintf(buf, sizeof(buf), "%lldns", static_cast<long long>(ns));
  }
  return buf;
}

std::uint64_t fnv1a(std::string_view text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : text) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace

std::vector<int> parse_cpu_list(std::string_view text) {
  std::vector<int> cpus;
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    text = comma == std::string_view::npos ? std::string_view{} : text.substr(comma + 1);
    int first = 0;
    int last = 0;
    const char* end = item.data() + item.size();
    auto [after_first, error] = std::from_chars(item.data(), end, first);
    if (error != std::errc{}) return {};  // not a list the kernel writes: trust none of it
    if (after_first != end) {
      if (*after_first != '-') return {};
      auto [after_last, error_last] = std::from_chars(after_first + 1, end, last);
      if (error_last != std::errc{} || after_last != end || last < first) return {};
    } else {
      last = first;
    }
    for (int cpu = first; cpu <= last && cpu < CPU_SETSIZE; ++cpu) cpus.push_back(cpu);
  }
  return cpus;
}

SchedulerImpl::SchedulerImpl(SchedulerConfig config)
    : config_(std::move(config)), tick_period_ns_(0), log_source_("@" + config_.name()) {
  prepare_logging();
  const std::string where = "horus::Scheduler '" + config_.name() + "': ";
  if (config_.params().empty()) {
    // How `horus launch` hands a process its parameter file without the program taking a
    // command-line option for it; a file the program names itself wins.
    const char* file = std::getenv("HORUS_PARAMS_FILE");  // NOLINT(concurrency-mt-unsafe): once
    if (file != nullptr && *file != '\0') config_.params(file);
  }
  if (!config_.tick_rate().valid()) {
    throw Error(where + "tick_rate must be a positive, finite rate");
  }
  tick_period_ns_ = config_.tick_rate().period().count();
  if (config_.watchdog().count() < 0) throw Error(where + "watchdog timeout must not be negative");
  if (!config_.replay().empty() && !config_.deterministic()) {
    throw Error(where + "replay(" + config_.replay().string() +
                ") needs deterministic(true): only simulated time lines messages up with ticks");
  }
  if (config_.shutdown_timeout().count() <= 0)
    throw Error(where + "shutdown_timeout must be positive");
  if (config_.max_deadline_misses() && *config_.max_deadline_misses() == 0) {
    throw Error(where + "max_deadline_misses must be at least 1 (nullopt disables it)");
  }
  const int cpus = static_cast<int>(std::max(1U, std::thread::hardware_concurrency()));
  for (const int core : config_.cores()) {
    if (core < 0 || core >= cpus) {
      throw Error(where + "core " + std::to_string(core) + " does not exist (this machine has " +
                  std::to_string(cpus) + " CPUs)");
    }
  }
  if (config_.name().empty()) throw Error("horus::Scheduler: name must not be empty");
  if (config_.blackbox_mb() > 0) {
    const Blackbox::Capacity capacity = Blackbox::capacity_for_mb(config_.blackbox_mb());
    blackbox_ = std::make_unique<Blackbox>(capacity.events, capacity.ticks);
    blackbox_path_ = config_.blackbox_path().empty()
                         ? std::filesystem::path(config_.name() + ".blackbox")
                         : config_.blackbox_path();
  }
  if (!config_.telemetry().empty()) {
    if (config_.telemetry_interval().count() <= 0) {
      throw Error(where + "telemetry_interval must be positive");
    }
    telemetry_ = std::make_unique<TelemetrySink>(config_.telemetry());
  }
  // A node's first send must not spend the milliseconds of the process's one-time set-up for
  // publishing inside its tick (and, in Python, under the one lock every node's tick needs).
  prepare_publisher_leases();
  if (config_.rt()) probe_rt();
  try {
    presence_ = std::make_unique<PresenceAnnouncement>(current_namespace());
  } catch (const Error& e) {
    log(LogLevel::Warn, "not announced to `horus node list`: %s", e.what());
  }
  if (config_.network()) {
    try {
      network_ = start_network(*config_.network(), current_namespace(),
                               [this](const std::string& failure) { request_stop(failure, true); });
    } catch (const Error& e) {
      throw Error(where + "network: " + e.what());
    }
  }
  if (config_.view()) {
    LiveViewOptions options = *config_.view();
    if (!options.clock && config_.deterministic()) {
      options.clock = [this] { return sim_clock_ns_.load(std::memory_order_relaxed); };
    }
    try {
      view_ = start_live_view(options, current_namespace(), [this](const std::string& failure) {
        request_stop("view: " + failure, true);
      });
    } catch (const Error& e) {
      throw Error(where + "view: " + e.what());
    }
  }
}

SchedulerImpl::~SchedulerImpl() {
  if (locked_memory_) munlockall();
  // The session file is finished, and its subscriptions closed, before topics are cleaned.
  try {
    stop_recording();
  } catch (const std::exception& e) {
    log(LogLevel::Error, "could not finish the session recording: %s", e.what());
  }
  replayer_.reset();
  if (config_.keep_topics()) return;
  // The nodes go first: their topics close, so a segment only they used has no live user left.
  loop_slots_.clear();
  slots_.clear();
  unbuilt_.clear();
  try {
    remove_created_segments_nobody_uses();
  } catch (const std::exception& e) {
    log(LogLevel::Warn, "could not remove this process's unused topics: %s", e.what());
  }
}

void SchedulerImpl::probe_rt() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    locked_memory_ = true;
    capabilities_.memory_locking = true;
  } else {
    add_degradation(std::string("mlockall failed (") +
                    (errno == EPERM ? "EPERM" : detail::errno_text(errno)) +
                    ") - memory pages may be swapped");
  }
  bool fifo = false;
  std::thread probe([&fifo] {
    sched_param param{};
    param.sched_priority = sched_get_priority_min(SCHED_FIFO);
    fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  });
  probe.join();
  capabilities_.rt_scheduling = fifo;
  if (!fifo) add_degradation("SCHED_FIFO unavailable (no CAP_SYS_NICE) - using SCHED_OTHER");
  // HORUS_ISOLATED_CPUS names CPUs set aside by other means than isolcpus (a cpuset, a
  // container's reserved cores); only those this process may run on count.
  std::string line;
  const char* reserved = std::getenv("HORUS_ISOLATED_CPUS");  // NOLINT(concurrency-mt-unsafe)
  if (reserved != nullptr) {
    line = reserved;
  } else {
    std::ifstream isolated("/sys/devices/system/cpu/isolated");
    std::getline(isolated, line);
  }
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  sched_getaffinity(0, sizeof(allowed), &allowed);
  for (const int cpu : parse_cpu_list(line)) {
    if (CPU_ISSET(static_cast<unsigned>(cpu), &allowed)) capabilities_.isolated_cpus.push_back(cpu);
  }
  capabilities_.cpu_isolation = !capabilities_.isolated_cpus.empty();
  if (!capabilities_.cpu_isolation) {
    add_degradation(
        "no isolated CPUs (isolcpus, HORUS_ISOLATED_CPUS) - RT threads share cores with other "
        "work");
  }
}

void SchedulerImpl::add_degradation(const std::string& message) {
  {
    std::lock_guard lock(mutex_);
    if (std::find(degradations_.begin(), degradations_.end(), message) != degradations_.end()) {
      return;
    }
    degradations_.push_back(message);
  }
  record_scheduler(BlackboxEventKind::Degradation, message);
  if (config_.verbose()) log(LogLevel::Warn, "RT degraded: %s", message.c_str());
}

NodeConfig* SchedulerImpl::add(std::shared_ptr<Node> node) {
  if (!node) throw Error("horus::Scheduler::add: node is null");
  auto slot = std::make_shared<NodeSlot>();
  slot->name = std::string(node->name());
  node->scheduler_ = weak_from_this();
  slot->node = std::move(node);
  std::lock_guard lock(mutex_);
  slot->registration = registrations_++;
  (active_.load() ? unbuilt_ : slots_).push_back(slot);
  return &slot->config;
}

void SchedulerImpl::validate(const NodeSlot& slot) const {
  const NodeConfig& c = slot.config;
  const std::string where = "node '" + slot.name + "': ";
  if (slot.name.empty()) throw Error("node of type with empty name(): every node needs a name");
  if (c.rate && !c.rate->valid()) throw Error(where + "rate must be a positive, finite rate");
  if (c.budget && c.budget->count() <= 0) throw Error(where + "budget must be positive");
  if (c.deadline && c.deadline->count() <= 0) throw Error(where + "deadline must be positive");
  if (c.budget && c.deadline && *c.budget > *c.deadline) {
    throw Error(where + "budget " + ns_text(c.budget->count()) + " exceeds deadline " +
                ns_text(c.deadline->count()));
  }
  if (c.watchdog && c.watchdog->count() <= 0) throw Error(where + "watchdog must be positive");
  if (c.on_topic) {
    if (c.on_topic->empty()) throw Error(where + "on(): topic name must not be empty");
    if (c.compute || c.async_io) {
      throw Error(where + "on(topic) cannot be combined with compute() or async_io()");
    }
    if (c.rate) throw Error(where + "on(topic) ticks on messages; it cannot also have a rate()");
  }
  if (c.compute && c.async_io) throw Error(where + "choose compute() or async_io(), not both");
  if (c.priority && (*c.priority < 1 || *c.priority > 99)) {
    throw Error(where + "priority must be 1..99 (SCHED_FIFO), got " + std::to_string(*c.priority));
  }
  const int cpus = static_cast<int>(std::max(1U, std::thread::hardware_concurrency()));
  if (c.core && (*c.core < 0 || *c.core >= cpus)) {
    throw Error(where + "core " + std::to_string(*c.core) + " does not exist (this machine has " +
                std::to_string(cpus) + " CPUs)");
  }
  if (const auto* r = c.failure_policy.restart(); r != nullptr && r->initial_backoff.count() < 0) {
    throw Error(where + "FailurePolicy::Restart initial_backoff must not be negative");
  }
  if (const auto* s = c.failure_policy.skip(); s != nullptr) {
    if (s->max_failures == 0) throw Error(where + "FailurePolicy::Skip max_failures must be >= 1");
    if (s->cooldown.count() < 0)
      throw Error(where + "FailurePolicy::Skip cooldown must not be negative");
  }
}

void SchedulerImpl::derive(NodeSlot& slot) const {
  const NodeConfig& c = slot.config;
  if (c.on_topic) {
    slot.execution_class = ExecutionClass::Event;
  } else if (c.async_io) {
    slot.execution_class = ExecutionClass::AsyncIo;
  } else if (c.compute) {
    slot.execution_class = ExecutionClass::Compute;
  } else if (c.rate || c.budget || c.deadline) {
    slot.execution_class = ExecutionClass::Rt;
  } else {
    slot.execution_class = ExecutionClass::BestEffort;
  }
  const std::int64_t period = c.rate ? c.rate->period().count() : tick_period_ns_;
  slot.period_ns.store(period);
  const bool timed = slot.execution_class == ExecutionClass::Rt;
  slot.budget_auto = !c.budget && timed;
  slot.deadline_auto = !c.deadline && timed;
  const std::int64_t budget = c.budget ? c.budget->count()
                              : timed  ? automatic_budget_ns(period)
                                       : 0;
  const std::int64_t deadline = c.deadline ? c.deadline->count()
                                : timed    ? automatic_deadline_ns(period, budget)
                                           : 0;
  slot.budget_ns.store(budget);
  slot.deadline_ns.store(deadline);
  slot.watchdog_ns.store(slot.critical.load() ? slot.critical_timeout_ns
                         : c.watchdog         ? c.watchdog->count()
                                              : config_.watchdog().count());
}

void SchedulerImpl::build(NodeConfig* config) {
  std::lock_guard lock(mutex_);
  const auto is_it = [&](const SlotPtr& s) { return &s->config == config; };
  auto it = std::find_if(slots_.begin(), slots_.end(), is_it);
  if (const auto added = std::find_if(unbuilt_.begin(), unbuilt_.end(), is_it);
      added != unbuilt_.end()) {
    // Added while running: it joins slots_ complete, or not at all.
    SlotPtr slot = *added;
    unbuilt_.erase(added);
    slots_.push_back(std::move(slot));
    it = std::prev(slots_.end());
  }
  if (it == slots_.end())
    throw Error("horus::NodeBuilder::build: the node is no longer registered");
  NodeSlot& slot = **it;
  if (slot.built) throw Error("node '" + slot.name + "': build() called twice");
  for (const SlotPtr& other : slots_) {
    if (other.get() != &slot && other->name == slot.name && !other->removed.load() &&
        !other->remove_requested.load()) {
      const std::string name = slot.name;  // the slot dies with the erase
      slots_.erase(it);
      throw Error("duplicate node name '" + name +
                  "': names must be unique within a scheduler (override name() when adding "
                  "several nodes of one type)");
    }
  }
  try {
    validate(slot);
  } catch (...) {
    slots_.erase(it);
    throw;
  }
  derive(slot);
  slot.built = true;
  structure_version_.fetch_add(1, std::memory_order_release);
  if (active_.load()) changes_pending_.store(true, std::memory_order_release);
  std::stable_sort(slots_.begin(), slots_.end(), [](const SlotPtr& a, const SlotPtr& b) {
    return a->config.order != b->config.order ? a->config.order < b->config.order
                                              : a->registration < b->registration;
  });
}

void SchedulerImpl::add_critical_node(std::string_view name, std::chrono::nanoseconds timeout) {
  if (timeout.count() <= 0) {
    throw Error("add_critical_node('" + std::string(name) + "'): timeout must be positive");
  }
  SlotPtr slot = find(name);
  if (!slot || !slot->built) {
    throw Error("add_critical_node: no built node named '" + std::string(name) + "'");
  }
  std::lock_guard lock(mutex_);
  slot->critical.store(true);
  slot->critical_timeout_ns = timeout.count();
  slot->watchdog_ns.store(timeout.count());
  // The running loop's watchdog thread knows only the nodes watched when it started.
  if (in_loop_.load() && !config_.deterministic()) {
    newly_critical_.push_back(slot);
    changes_pending_.store(true, std::memory_order_release);
  }
}

void SchedulerImpl::prepare() {
  {
    std::lock_guard lock(mutex_);
    for (const SlotPtr& s : slots_) {
      if (!s->built) {
        throw Error("node '" + s->name + "' was added but .build() was never called");
      }
    }
  }
  if (!prepared_) {
    start_mono_ns_ = monotonic_ns();
    sim_now_ns_ = 0;
    sim_clock_ns_.store(0, std::memory_order_relaxed);
    prepared_ = true;
    record_scheduler(BlackboxEventKind::SchedulerStart,
                     config_.deterministic() ? "deterministic" : "");
  }
  // Nodes built since the last run are initialised (lazily, in order) like the first ones.
  start_nodes(unstarted_slots());
  if (!config_.replay().empty() && !replayer_) start_replay();
}

std::vector<SlotPtr> SchedulerImpl::unstarted_slots() const {
  std::vector<SlotPtr> fresh;
  std::lock_guard lock(mutex_);
  for (const SlotPtr& s : slots_) {
    if (s->built && !s->init_attempted && !s->removed.load() && !s->remove_requested.load()) {
      fresh.push_back(s);
    }
  }
  return fresh;
}

void SchedulerImpl::start_nodes(const std::vector<SlotPtr>& fresh) {
  for (const SlotPtr& s : fresh) {
    if (s->execution_class == ExecutionClass::Event && !s->notifier) {
      s->notifier = std::make_unique<TopicNotifier>(*s->config.on_topic);
    }
    const std::uint64_t salt =
        config_.deterministic()
            ? config_.seed()
            : static_cast<std::uint64_t>(monotonic_ns()) * 0x9E3779B97F4A7C15ULL;
    s->rng = Rng(salt ^ fnv1a(s->name));
    s->context.deterministic = config_.deterministic();
    s->context.rng = &s->rng;
    s->context.start_ns = start_mono_ns_;
    s->context.node_name = s->name;
    s->context.messages = &s->messages;
    s->messages.track_topics = blackbox_ != nullptr;  // for the blackbox's tick records
    s->next_release_ns = sim_now_ns_;
  }
  open_param_stores(fresh);
  if (config_.recording()) start_recording(fresh);
  for (const SlotPtr& s : fresh) {
    if (stop_requested_.load()) break;
    s->init_attempted = true;
    init_node(*s);
  }
  std::shared_ptr<Recorder> recorder;
  {
    std::lock_guard lock(mutex_);
    recorder = recorder_;
  }
  if (recorder && !fresh.empty()) {
    // Topics a node names once initialised (publishers()/subscribers() are asked after init()).
    std::vector<std::string> topics;
    {
      std::lock_guard lock(mutex_);
      for (const SlotPtr& s : fresh) {
        std::vector<std::string> subscribed;
        for (const TopicMetadata& t : s->publishers) topics.push_back(t.topic_name);
        for (const TopicMetadata& t : s->subscribers) {
          topics.push_back(t.topic_name);
          subscribed.push_back(t.topic_name);
        }
        // Its ticks, with the positions of the topics it reads (replay lines them up by those).
        if (s->tick_log) recorder->add_tick_log(s->name, s->tick_log, std::move(subscribed));
      }
    }
    record_params(recorder, fresh);
    // And the topics this process has open, for nodes that open topics without naming them.
    for (const TopicInfo& info : list_topics()) {
      if (info.open_here && !info.type_name.empty()) topics.push_back(info.name);
    }
    for (const std::string& topic : topics) recorder->add_topic(topic);
  }
}

void SchedulerImpl::open_param_stores(const std::vector<SlotPtr>& fresh) {
  if (!config_.params().empty() && !param_file_) {
    // Checked against every node at the first start: a wrong value stops it before any store
    // or node is touched.
    std::vector<SlotPtr> slots;
    {
      std::lock_guard lock(mutex_);
      slots = slots_;
    }
    std::map<std::string, const std::vector<ParamDeclaration>*> declarations;
    for (const SlotPtr& s : slots) {
      if (!s->node->param_declarations().empty()) {
        declarations[s->name] = &s->node->param_declarations();
      }
    }
    param_file_ = read_scheduler_param_file(config_.params(), declarations);
  }
  if (!config_.replay().empty() && !replay_start_params_) {
    replay_start_params_ = recorded_starting_params(config_.replay());
  }
  for (const SlotPtr& s : fresh) {
    if (s->params || s->node->param_declarations().empty()) continue;
    const std::map<std::string, std::string>* values = nullptr;
    if (param_file_) {
      if (const auto found = param_file_->find(s->name); found != param_file_->end()) {
        values = &found->second;
      }
    }
    const std::map<std::string, std::string>* replayed = nullptr;
    if (replay_start_params_) {
      if (const auto found = replay_start_params_->find(s->name);
          found != replay_start_params_->end()) {
        replayed = &found->second;
      }
    }
    s->params = std::make_unique<ParamOwner>(*s->node, s->name, values, replayed);
    NodeSlot* slot = s.get();
    s->params->serve([this, slot] { wake_for_params(*slot); });
  }
}

void SchedulerImpl::start_recording(const std::vector<SlotPtr>& fresh) {
  std::lock_guard lock(mutex_);
  if (recording_done_) return;  // stop_recording() ended this scheduler's session
  if (!recorder_) {
    RecorderOptions options;
    options.frames = true;  // the nodes' lookups depend on the frame tree (docs/recording.md)
    recorder_ = std::make_shared<Recorder>(std::move(options));
    log(LogLevel::Info, "recording the session to %s", recorder_->path().c_str());
  }
  for (const SlotPtr& s : fresh) {
    if (s->tick_log) continue;
    s->tick_log = std::make_shared<TickLog>();  // handed to the recorder once initialised
    s->messages.track_topics = true;  // how far each tick read its topics goes into its entry
  }
}

void SchedulerImpl::start_replay() {
  std::set<std::string> produced;
  {
    std::lock_guard lock(mutex_);
    for (const SlotPtr& s : slots_) {
      for (const TopicMetadata& t : s->publishers) produced.insert(t.topic_name);
    }
  }
  replayer_ = std::make_unique<Replayer>(config_.replay(), std::string{}, produced);
  log(LogLevel::Info, "replaying %s into %zu topics", config_.replay().c_str(),
      replayer_->topic_count());
}

void SchedulerImpl::record_params(const std::shared_ptr<Recorder>& recorder,
                                  const std::vector<SlotPtr>& fresh) {
  for (const SlotPtr& s : fresh) {
    if (!s->params) continue;
    try {
      for (const ParamInfo& info : ParamStoreReader(s->name).list()) {
        recorder->add_param_change(RecordedParamChange{s->name, info.declaration.name, info.value,
                                                       info.version, "start", true, std::nullopt});
      }
    } catch (const Error& e) {
      // The node runs without them: a replay of this session starts it from its defaults.
      log(LogLevel::Warn, "recording: the starting parameters of node '%s' are not recorded: %s",
          s->name.c_str(), e.what());
    }
    // As each change is stored, between two of the node's ticks: the cycle is the one its ticks
    // from now on belong to (a change between two passes takes effect before the next).
    s->params->on_accepted([this, recorder, node = s->name](
                               const ParamDeclaration& declaration, const std::string& value,
                               std::uint64_t version, const std::string& source) {
      recorder->add_param_change(RecordedParamChange{node, declaration.name, value, version, source,
                                                     false,
                                                     cycle_.load(std::memory_order_relaxed)});
    });
  }
}

void SchedulerImpl::replay_params(NodeSlot& slot) noexcept {
  try {
    replayer_->apply_params_before_tick(slot.name, [&](const RecordedParamChange& change) {
      const ParamSetResult result = slot.params->apply(change.name, change.value, "replay");
      if (!result.accepted) {
        log(LogLevel::Warn, "replay: node '%s' keeps parameter '%s' at version %llu: %s",
            slot.name.c_str(), change.name.c_str(), static_cast<unsigned long long>(result.version),
            result.reason.c_str());
      }
    });
  } catch (const std::exception& e) {
    log(LogLevel::Error, "replay: parameters of node '%s': %s", slot.name.c_str(), e.what());
  }
}

bool SchedulerImpl::is_recording() const noexcept {
  std::lock_guard lock(mutex_);
  return recorder_ != nullptr && recorder_->recording();
}

std::vector<std::filesystem::path> SchedulerImpl::stop_recording() {
  std::shared_ptr<Recorder> recorder;
  {
    std::lock_guard lock(mutex_);
    recording_done_ = true;
    recorder = std::move(recorder_);
  }
  if (!recorder) return {};
  const RecordingSummary summary = recorder->stop();
  return {summary.path};
}

void SchedulerImpl::refresh_loop_slots() {
  const std::uint64_t version = structure_version_.load(std::memory_order_acquire);
  if (version == loop_slots_version_) return;
  loop_slots_ = ordered_slots();
  loop_slots_version_ = version;
  if (!config_.deterministic()) return;
  std::vector<std::string> cycle_breaks;
  {
    std::lock_guard lock(mutex_);  // publishers/subscribers are written under it
    loop_slots_ = order_by_topics(loop_slots_, cycle_breaks);
  }
  if (!cycle_breaks.empty() && !topic_cycle_reported_) {
    topic_cycle_reported_ = true;
    std::string names;
    for (const std::string& n : cycle_breaks) names += (names.empty() ? "'" : ", '") + n + "'";
    log(LogLevel::Warn, "topic cycle: %s run before their publishers (by order())", names.c_str());
  }
}

bool SchedulerImpl::set_node_rate(std::string_view name, Rate rate) {
  if (!rate.valid()) {
    throw Error("set_node_rate('" + std::string(name) + "'): rate must be positive and finite");
  }
  SlotPtr slot = find(name);
  if (!slot) return false;
  std::lock_guard lock(mutex_);
  slot->config.rate = rate;
  const std::int64_t period = rate.period().count();
  slot->period_ns.store(period);
  if (slot->budget_auto) slot->budget_ns.store(automatic_budget_ns(period));
  if (slot->deadline_auto) {
    slot->deadline_ns.store(automatic_deadline_ns(period, slot->budget_ns.load()));
  }
  return true;
}

bool SchedulerImpl::set_tick_budget(std::string_view name, std::chrono::nanoseconds budget) {
  if (budget.count() <= 0) {
    throw Error("set_tick_budget('" + std::string(name) + "'): budget must be positive");
  }
  SlotPtr slot = find(name);
  if (!slot) return false;
  std::lock_guard lock(mutex_);
  slot->config.budget = budget;
  slot->budget_auto = false;
  slot->budget_ns.store(budget.count());
  return true;
}

bool SchedulerImpl::remove_node(std::string_view name) {
  SlotPtr slot = find(name);
  if (!slot) return false;
  if (active_.load()) {
    // Its own thread shuts it down at its next release (never concurrently with its tick).
    slot->remove_requested.store(true, std::memory_order_release);
    removals_pending_.store(true, std::memory_order_release);
    structure_version_.fetch_add(1, std::memory_order_release);
    return true;
  }
  shutdown_node(slot, true);
  std::lock_guard lock(mutex_);
  std::erase(slots_, slot);
  structure_version_.fetch_add(1, std::memory_order_release);
  return true;
}

}  // namespace horus::detail
