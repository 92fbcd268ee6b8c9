// What the scheduler tells about itself: node lookup, info, metrics, safety stats, the timing
// report, and its own log lines and blackbox events.
#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <sstream>

#include "logger.hpp"
#include "scheduler_impl.hpp"

namespace horus::detail {

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
  if (const auto w = slot.watchdog_ns.load(); w > 0) info.watchdog = std::chrono::nanoseconds(w);
  info.on_miss = slot.config.on_miss;
  info.failure_policy = slot.config.failure_policy.kind();
  info.critical = slot.critical.load();
  info.on_topic = slot.config.on_topic;
  info.priority = slot.config.priority;
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
  m.messages_sent = slot.messages.sent.load(std::memory_order_relaxed);
  m.messages_received = slot.messages.received.load(std::memory_order_relaxed);
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

}  // namespace horus::detail
