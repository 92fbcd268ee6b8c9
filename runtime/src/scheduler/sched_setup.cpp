// Scheduler set-up, validation, runtime mutation and introspection.
#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

#include "horus/detail/errno_text.hpp"
#include "horus/error.hpp"
#include "logger.hpp"
#include "sched_impl_class.hpp"

namespace horus {
namespace detail {
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

SchedulerImpl::SchedulerImpl(SchedulerConfig config)
    : config_(std::move(config)), tick_period_ns_(0), log_source_("@" + config_.name()) {
  prepare_logging();
  const std::string where = "horus::Scheduler '" + config_.name() + "': ";
  if (!config_.tick_rate().valid()) {
    throw Error(where + "tick_rate must be a positive, finite rate");
  }
  tick_period_ns_ = config_.tick_rate().period().count();
  if (config_.watchdog().count() < 0) throw Error(where + "watchdog timeout must not be negative");
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
    blackbox_ = std::make_unique<Blackbox>(Blackbox::capacity_for_mb(config_.blackbox_mb()));
    blackbox_path_ = config_.blackbox_path().empty()
                         ? std::filesystem::path(config_.name() + ".blackbox")
                         : config_.blackbox_path();
  }
  if (config_.rt()) probe_rt();
}

SchedulerImpl::~SchedulerImpl() {
  if (locked_memory_) munlockall();
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
  std::ifstream isolated("/sys/devices/system/cpu/isolated");
  std::string line;
  std::getline(isolated, line);
  capabilities_.cpu_isolation = !line.empty();
  if (!capabilities_.cpu_isolation) {
    add_degradation("no isolated CPUs (isolcpus) - RT threads share cores with other work");
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
  if (active_.load()) {
    throw Error("horus::Scheduler::add: cannot add node '" + std::string(node->name()) +
                "' while the scheduler is running");
  }
  auto slot = std::make_shared<NodeSlot>();
  slot->name = std::string(node->name());
  node->scheduler_ = weak_from_this();
  slot->node = std::move(node);
  std::lock_guard lock(mutex_);
  slot->registration = registrations_++;
  slots_.push_back(slot);
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
  const std::int64_t budget = c.budget ? c.budget->count() : timed ? period * 8 / 10 : 0;
  const std::int64_t deadline = c.deadline ? c.deadline->count()
                                : timed    ? std::max(period * 95 / 100, budget)
                                           : 0;
  slot.budget_ns.store(budget);
  slot.deadline_ns.store(deadline);
  slot.watchdog_ns = slot.critical ? slot.critical_timeout_ns
                     : c.watchdog  ? c.watchdog->count()
                                   : config_.watchdog().count();
}

void SchedulerImpl::build(NodeConfig* config) {
  std::lock_guard lock(mutex_);
  const auto it = std::find_if(slots_.begin(), slots_.end(),
                               [&](const SlotPtr& s) { return &s->config == config; });
  if (it == slots_.end())
    throw Error("horus::NodeBuilder::build: the node is no longer registered");
  NodeSlot& slot = **it;
  if (slot.built) throw Error("node '" + slot.name + "': build() called twice");
  for (const SlotPtr& other : slots_) {
    if (other.get() != &slot && other->name == slot.name) {
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
  std::stable_sort(slots_.begin(), slots_.end(), [](const SlotPtr& a, const SlotPtr& b) {
    return a->config.order != b->config.order ? a->config.order < b->config.order
                                              : a->registration < b->registration;
  });
}

void SchedulerImpl::add_critical_node(std::string_view name, std::chrono::nanoseconds timeout) {
  if (timeout.count() <= 0) {
    throw Error("add_critical_node('" + std::string(name) + "'): timeout must be positive");
  }
  if (active_.load()) {
    throw Error("add_critical_node('" + std::string(name) + "'): not while the scheduler runs");
  }
  SlotPtr slot = find(name);
  if (!slot || !slot->built) {
    throw Error("add_critical_node: no built node named '" + std::string(name) + "'");
  }
  std::lock_guard lock(mutex_);
  slot->critical = true;
  slot->critical_timeout_ns = timeout.count();
  slot->watchdog_ns = timeout.count();
}

void SchedulerImpl::prepare() {
  std::vector<SlotPtr> fresh;
  {
    std::lock_guard lock(mutex_);
    for (const SlotPtr& s : slots_) {
      if (!s->built) {
        throw Error("node '" + s->name + "' was added but .build() was never called");
      }
      if (!s->init_attempted) fresh.push_back(s);
    }
  }
  if (!prepared_) {
    start_mono_ns_ = monotonic_ns();
    sim_now_ns_ = 0;
    prepared_ = true;
    record_scheduler(BlackboxEventKind::SchedulerStart,
                     config_.deterministic() ? "deterministic" : "");
  }
  // Nodes built since the last run are initialised (lazily, in order) like the first ones.
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
    s->next_release_ns = sim_now_ns_;
  }
  for (const SlotPtr& s : fresh) {
    if (stop_requested_.load()) break;
    s->init_attempted = true;
    init_node(*s);
  }
}

void SchedulerImpl::refresh_loop_slots() {
  const std::uint64_t version = structure_version_.load(std::memory_order_acquire);
  if (version == loop_slots_version_) return;
  loop_slots_ = ordered_slots();
  loop_slots_version_ = version;
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
  if (slot->budget_auto) slot->budget_ns.store(period * 8 / 10);
  if (slot->deadline_auto) {
    slot->deadline_ns.store(std::max(period * 95 / 100, slot->budget_ns.load()));
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

SlotPtr SchedulerImpl::find(std::string_view name) const {
  std::lock_guard lock(mutex_);
  for (const SlotPtr& s : slots_) {
    if (s->name == name && !s->removed.load() && !s->remove_requested.load()) return s;
  }
  return nullptr;
}

std::vector<SlotPtr> SchedulerImpl::ordered_slots() const {
  std::lock_guard lock(mutex_);
  std::vector<SlotPtr> out;
  for (const SlotPtr& s : slots_) {
    if (!s->removed.load() && !s->remove_requested.load()) out.push_back(s);
  }
  return out;
}

SchedulerStatus SchedulerImpl::status() const noexcept {
  if (in_loop_.load()) return SchedulerStatus::Running;
  std::lock_guard lock(mutex_);
  return finished_ ? SchedulerStatus::Stopped : SchedulerStatus::Idle;
}

std::string SchedulerImpl::stop_reason() const {
  if (!stop_reason_set_.load(std::memory_order_acquire)) return {};
  return stop_reason_;
}

NodeInfo SchedulerImpl::info(const NodeSlot& slot) const {
  std::lock_guard lock(mutex_);
  NodeInfo info;
  info.name = slot.name;
  info.order = slot.config.order;
  info.execution_class = slot.execution_class;
  info.state = slot.state.load();
  info.health = slot.health.load();
  info.rate = slot.config.rate;
  if (const auto b = slot.budget_ns.load(); b > 0) info.budget = std::chrono::nanoseconds(b);
  if (const auto d = slot.deadline_ns.load(); d > 0) info.deadline = std::chrono::nanoseconds(d);
  if (slot.watchdog_ns > 0) info.watchdog = std::chrono::nanoseconds(slot.watchdog_ns);
  info.on_miss = slot.config.on_miss;
  info.failure_policy = slot.config.failure_policy.kind();
  info.critical = slot.critical;
  info.on_topic = slot.config.on_topic;
  info.last_error = slot.last_error;
  info.publishers = slot.publishers;
  info.subscribers = slot.subscribers;
  return info;
}

NodeMetrics SchedulerImpl::metrics(const NodeSlot& slot) const {
  using std::chrono::nanoseconds;
  NodeMetrics m;
  m.name = slot.name;
  m.order = slot.config.order;
  m.total_ticks = slot.total_ticks.load(std::memory_order_relaxed);
  m.failed_ticks = slot.failed_ticks.load(std::memory_order_relaxed);
  m.successful_ticks = m.total_ticks - std::min(m.total_ticks, m.failed_ticks);
  m.skipped_ticks = slot.skipped_ticks.load(std::memory_order_relaxed);
  const auto sum = slot.sum_tick_ns.load(std::memory_order_relaxed);
  m.avg_tick_duration =
      nanoseconds(m.total_ticks > 0 ? sum / static_cast<std::int64_t>(m.total_ticks) : 0);
  m.max_tick_duration = nanoseconds(slot.max_tick_ns.load(std::memory_order_relaxed));
  m.min_tick_duration = nanoseconds(slot.min_tick_ns.load(std::memory_order_relaxed));
  m.last_tick_duration = nanoseconds(slot.last_tick_ns.load(std::memory_order_relaxed));
  m.budget_overruns = slot.budget_overruns.load(std::memory_order_relaxed);
  m.deadline_misses = slot.deadline_misses.load(std::memory_order_relaxed);
  m.watchdog_expirations = slot.watchdog_expirations.load(std::memory_order_relaxed);
  m.errors_count = slot.errors.load(std::memory_order_relaxed);
  m.warnings_count = slot.warnings.load(std::memory_order_relaxed);
  m.restarts = slot.restarts.load(std::memory_order_relaxed);
  const auto since = slot.running_since_ns.load(std::memory_order_relaxed);
  if (since > 0) {
    const auto stopped = slot.stopped_at_ns.load(std::memory_order_relaxed);
    m.uptime = nanoseconds((stopped > 0 ? stopped : monotonic_ns()) - since);
    if (m.uptime.count() > 0) {
      m.achieved_rate_hz =
          static_cast<double>(m.total_ticks) * 1e9 / static_cast<double>(m.uptime.count());
    }
  }
  return m;
}

SafetyStats SchedulerImpl::safety_stats() const {
  SafetyStats stats;
  stats.budget_overruns = total_overruns_.load();
  stats.deadline_misses = total_misses_.load();
  stats.watchdog_expirations = total_watchdog_.load();
  for (const SlotPtr& s : ordered_slots())
    stats.health_states.emplace_back(s->name, s->health.load());
  return stats;
}

std::vector<std::string> SchedulerImpl::degradations() const {
  std::lock_guard lock(mutex_);
  return degradations_;
}

void SchedulerImpl::log(LogLevel level, const char* format, ...) const noexcept {
  va_list args;
  va_start(args, format);
  vlog_as(level, log_source_, format, args);
  va_end(args);
}

void SchedulerImpl::record(BlackboxEventKind kind, const NodeSlot& slot, std::int64_t value,
                           std::string_view detail) noexcept {
  if (blackbox_) {
    blackbox_->record(kind, slot.name, slot.total_ticks.load(std::memory_order_relaxed), value,
                      detail);
  }
}

void SchedulerImpl::record_scheduler(BlackboxEventKind kind, std::string_view detail) noexcept {
  if (blackbox_) blackbox_->record(kind, config_.name(), cycle_.load(), 0, detail);
}

std::string SchedulerImpl::timing_report() const {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-16s %-10s %9s %9s %10s %10s %8s %8s %6s  %-9s %s\n", "node",
                "class", "target Hz", "actual Hz", "avg tick", "max tick", "overrun", "missed",
                "errors", "health", "state");
  out << line;
  for (const auto& s : ordered_slots()) {
    const NodeInfo node = info(*s);
    const NodeMetrics m = metrics(*s);
    char target[16] = "-";
    if (node.execution_class != ExecutionClass::Event) {
      const double hz = node.rate ? node.rate->hz() : config_.tick_rate().hz();
      std::snprintf(target, sizeof(target), "%.1f", hz);
    }
    std::snprintf(
        line, sizeof(line), "%-16s %-10s %9s %9.1f %8.1fus %8.1fus %8llu %8llu %6llu  %-9s %s\n",
        node.name.c_str(), std::string(to_string(node.execution_class)).c_str(), target,
        m.achieved_rate_hz, static_cast<double>(m.avg_tick_duration.count()) / 1e3,
        static_cast<double>(m.max_tick_duration.count()) / 1e3,
        static_cast<unsigned long long>(m.budget_overruns),
        static_cast<unsigned long long>(m.deadline_misses),
        static_cast<unsigned long long>(m.errors_count),
        std::string(to_string(node.health)).c_str(), std::string(to_string(node.state)).c_str());
    out << line;
  }
  return out.str();
}

}  // namespace detail

// ---- public wrappers -------------------------------------------------------------------------

std::string_view to_string(ExecutionClass c) noexcept {
  switch (c) {
    case ExecutionClass::BestEffort:
      return "BestEffort";
    case ExecutionClass::Rt:
      return "Rt";
    case ExecutionClass::Compute:
      return "Compute";
    case ExecutionClass::Event:
      return "Event";
    case ExecutionClass::AsyncIo:
      return "AsyncIo";
  }
  return "?";
}

std::string_view to_string(SchedulerStatus s) noexcept {
  switch (s) {
    case SchedulerStatus::Idle:
      return "idle";
    case SchedulerStatus::Running:
      return "running";
    case SchedulerStatus::Stopped:
      return "stopped";
  }
  return "?";
}

Scheduler& NodeBuilder::build() {
  scheduler_->impl_->build(config_);
  return *scheduler_;
}

Scheduler::Scheduler(SchedulerConfig config)
    : impl_(std::make_shared<detail::SchedulerImpl>(std::move(config))) {}

Scheduler::~Scheduler() { impl_->finish(); }

NodeBuilder Scheduler::add(std::shared_ptr<Node> node) {
  return NodeBuilder(*this, impl_->add(std::move(node)));
}

void Scheduler::add_critical_node(std::string_view name, std::chrono::nanoseconds timeout) {
  impl_->add_critical_node(name, timeout);
}

int Scheduler::run() { return impl_->run(std::nullopt); }
int Scheduler::run_for(std::chrono::nanoseconds duration) { return impl_->run(duration.count()); }
void Scheduler::tick_once() { impl_->tick_once(nullptr); }
void Scheduler::tick_once(const std::vector<std::string>& names) { impl_->tick_once(&names); }
void Scheduler::tick_for(std::chrono::nanoseconds duration, const std::vector<std::string>& names) {
  impl_->tick_for(duration.count(), names.empty() ? nullptr : &names);
}
void Scheduler::stop() noexcept { impl_->request_stop("stop() called", false); }

bool Scheduler::set_node_rate(std::string_view name, Rate rate) {
  return impl_->set_node_rate(name, rate);
}
bool Scheduler::set_tick_budget(std::string_view name, std::chrono::nanoseconds budget) {
  return impl_->set_tick_budget(name, budget);
}
bool Scheduler::remove_node(std::string_view name) { return impl_->remove_node(name); }

SchedulerStatus Scheduler::status() const noexcept { return impl_->status(); }
bool Scheduler::is_running() const noexcept { return impl_->in_loop(); }
std::uint64_t Scheduler::current_tick() const noexcept { return impl_->current_tick(); }
const std::string& Scheduler::name() const noexcept { return impl_->config().name(); }
const SchedulerConfig& Scheduler::config() const noexcept { return impl_->config(); }
std::string Scheduler::stop_reason() const { return impl_->stop_reason(); }

std::size_t Scheduler::node_count() const { return impl_->ordered_slots().size(); }

std::vector<std::string> Scheduler::node_names() const {
  std::vector<std::string> names;
  for (const auto& s : impl_->ordered_slots()) names.push_back(s->name);
  return names;
}

bool Scheduler::has_node(std::string_view name) const { return impl_->find(name) != nullptr; }

std::optional<NodeInfo> Scheduler::node_info(std::string_view name) const {
  const auto slot = impl_->find(name);
  if (!slot) return std::nullopt;
  return impl_->info(*slot);
}

std::vector<NodeInfo> Scheduler::nodes() const {
  std::vector<NodeInfo> out;
  for (const auto& s : impl_->ordered_slots()) out.push_back(impl_->info(*s));
  return out;
}

std::optional<NodeMetrics> Scheduler::node_metrics(std::string_view name) const {
  const auto slot = impl_->find(name);
  if (!slot) return std::nullopt;
  return impl_->metrics(*slot);
}

SafetyStats Scheduler::safety_stats() const { return impl_->safety_stats(); }

std::string Scheduler::timing_report() const { return impl_->timing_report(); }

bool Scheduler::has_full_rt() const {
  return impl_->config().rt() && impl_->degradations().empty();
}
std::vector<std::string> Scheduler::degradations() const { return impl_->degradations(); }
RtCapabilities Scheduler::capabilities() const { return impl_->capabilities(); }
const Blackbox* Scheduler::blackbox() const noexcept { return impl_->blackbox(); }

void Scheduler::dump_blackbox(const std::filesystem::path& path) const {
  const Blackbox* box = impl_->blackbox();
  if (box == nullptr) {
    throw Error("horus::Scheduler '" + name() + "': dump_blackbox needs blackbox_mb > 0");
  }
  box->write_to(path);
}

}  // namespace horus
