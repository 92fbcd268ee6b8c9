// Running one node on the thread that owns it: init(), each release (restart backoff, skips,
// health, the tick and its timing checks) and what follows a failure or a missed deadline.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "scheduler_impl.hpp"

namespace horus::detail {
namespace {

const char* phase_name(Phase phase) {
  switch (phase) {
    case Phase::Init:
      return "init()";
    case Phase::Tick:
      return "tick()";
    case Phase::Shutdown:
      return "shutdown()";
  }
  return "?";
}

}  // namespace

std::string exception_text(std::exception_ptr error) {
  try {
    std::rethrow_exception(error);
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "unknown exception";
  }
}

bool SchedulerImpl::init_node(NodeSlot& slot) noexcept {
  slot.state.store(NodeState::Initializing);
  std::exception_ptr error;
  {
    slot.context.tick_index = 0;
    slot.context.dt_ns = 0;
    slot.context.budget_ns = 0;
    slot.context.sim_now_ns = sim_now_ns_;
    slot.context.tick_start_ns = monotonic_ns();
    slot.context.release_ns = slot.context.tick_start_ns;
    TickContextScope scope(&slot.context);
    try {
      slot.node->init();
    } catch (...) {
      error = std::current_exception();
    }
  }
  if (error) {
    handle_failure(slot, Phase::Init, exception_text(error), sched_now(monotonic_ns()));
    return false;
  }
  slot.initialized = true;
  slot.consecutive_failures = 0;
  slot.running_since_ns.store(monotonic_ns(), std::memory_order_relaxed);
  try {
    auto publishers = slot.node->publishers();
    auto subscribers = slot.node->subscribers();
    std::lock_guard lock(mutex_);
    slot.publishers = std::move(publishers);
    slot.subscribers = std::move(subscribers);
  } catch (...) {
    log(LogLevel::Warn, "node '%s': publishers()/subscribers() threw; topic metadata left empty",
        slot.name.c_str());
  }
  slot.state.store(NodeState::Running);
  record(BlackboxEventKind::NodeInit, slot);
  return true;
}

void SchedulerImpl::service(NodeSlot& slot, std::int64_t release, std::int64_t& mono) noexcept {
  if (slot.removed.load(std::memory_order_relaxed)) return;
  if (slot.remove_requested.load(std::memory_order_acquire)) {
    shutdown_node(slot.shared_from_this(), true);
    return;
  }
  deliver_params(slot);
  const bool deterministic = config_.deterministic();
  const std::int64_t now = sched_now(mono);
  if (slot.pending_safe_state.exchange(false, std::memory_order_acq_rel)) enter_safe(slot);
  if (slot.restart_pending) {
    if (now < slot.resume_at_ns) {
      slot.skipped_ticks.store(slot.skipped_ticks.load(std::memory_order_relaxed) + 1,
                               std::memory_order_relaxed);
      return;
    }
    slot.restart_pending = false;
    slot.restarts.fetch_add(1, std::memory_order_relaxed);
    record(BlackboxEventKind::NodeRestart, slot, slot.restart_attempts);
    if (!init_node(slot)) return;
    mono = monotonic_ns();
  }
  if (slot.state.load(std::memory_order_relaxed) != NodeState::Running) return;

  const auto skip = [&slot] {
    slot.skipped_ticks.store(slot.skipped_ticks.load(std::memory_order_relaxed) + 1,
                             std::memory_order_relaxed);
  };
  if (now < slot.resume_at_ns) return skip();
  if (slot.skip_next) {
    slot.skip_next = false;
    return skip();
  }
  const NodeHealthState health = slot.health.load(std::memory_order_acquire);
  if (health == NodeHealthState::Isolated) {
    bool safe = false;
    try {
      safe = slot.node->is_safe_state();
    } catch (...) {
      safe = false;
    }
    if (!safe) return skip();
    set_health(slot, NodeHealthState::Healthy);
  } else if (health == NodeHealthState::Unhealthy && now < slot.unhealthy_until_ns) {
    return skip();
  }

  // The tick itself.
  TickContext& ctx = slot.context;
  const std::int64_t period = slot.period_ns.load(std::memory_order_relaxed);
  const std::uint64_t index = slot.total_ticks.load(std::memory_order_relaxed);
  ctx.tick_index = index;
  ctx.sim_now_ns = sim_now_ns_;
  ctx.budget_ns = slot.budget_ns.load(std::memory_order_relaxed);
  if (deterministic) {
    ctx.dt_ns = slot.execution_class == ExecutionClass::Event && slot.last_tick_start_ns >= 0
                    ? now - slot.last_tick_start_ns
                    : period;
  } else {
    ctx.dt_ns = slot.last_tick_start_ns >= 0 ? mono - slot.last_tick_start_ns : period;
  }
  slot.last_tick_start_ns = now;
  const std::int64_t watchdog = slot.watchdog_ns.load(std::memory_order_relaxed);
  const bool watched = watchdog > 0 && !deterministic;
  const std::int64_t start = deterministic ? monotonic_ns() : mono;
  ctx.tick_start_ns = start;
  ctx.release_ns = deterministic ? start : release;
  if (watched) {
    slot.watchdog_level.store(0, std::memory_order_relaxed);
    slot.tick_started_ns.store(start, std::memory_order_release);
  }
  // A replay feeds what this tick got live just where the live run counted what it had, and
  // sets the parameters this tick had.
  if (replayer_) {
    if (slot.params) replay_params(slot);
    replayer_->deliver_before_tick(slot.name);
  }
  if (slot.tick_log) slot.tick_log->note_start();
  slot.messages.topics.clear();
  std::exception_ptr error;
  {
    TickContextScope scope(&ctx);
    try {
      slot.node->tick();
    } catch (...) {
      error = std::current_exception();
    }
  }
  const std::int64_t end = monotonic_ns();
  if (watched) slot.tick_started_ns.store(0, std::memory_order_release);
  mono = end;

  const std::int64_t duration = end - start;
  if (blackbox_) blackbox_->record_tick(slot.name, index, duration, slot.messages.topics);
  slot.total_ticks.store(index + 1, std::memory_order_relaxed);
  slot.sum_tick_ns.store(slot.sum_tick_ns.load(std::memory_order_relaxed) + duration,
                         std::memory_order_relaxed);
  slot.last_tick_ns.store(duration, std::memory_order_relaxed);
  if (duration > slot.max_tick_ns.load(std::memory_order_relaxed)) {
    slot.max_tick_ns.store(duration, std::memory_order_relaxed);
  }
  if (index == 0 || duration < slot.min_tick_ns.load(std::memory_order_relaxed)) {
    slot.min_tick_ns.store(duration, std::memory_order_relaxed);
  }

  if (error) {
    slot.failed_ticks.store(slot.failed_ticks.load(std::memory_order_relaxed) + 1,
                            std::memory_order_relaxed);
    handle_failure(slot, Phase::Tick, exception_text(error), sched_now(end));
  } else {
    slot.consecutive_failures = 0;
    slot.restart_attempts = 0;
  }
  const std::uint64_t cycle = cycle_.load(std::memory_order_relaxed);
  const TickOutcome outcome = error ? TickOutcome::Error : TickOutcome::Ok;
  // Wall-clock enforcement would make a deterministic run depend on the machine's load.
  if (deterministic) return log_tick(slot, cycle, start, duration, outcome);
  // A loop's first tick of each node pays one-time costs (a thread's first page faults, lazily
  // made state, an interpreter's first calls) that say nothing about the ones to come.
  const bool judged = !std::exchange(slot.warm_up, false);

  if (judged && ctx.budget_ns > 0 && duration > ctx.budget_ns) {
    slot.budget_overruns.fetch_add(1, std::memory_order_relaxed);
    total_overruns_.fetch_add(1, std::memory_order_relaxed);
    record(BlackboxEventKind::BudgetOverrun, slot, duration);
  }
  if (watched) {
    const std::int64_t level = std::min<std::int64_t>(duration / watchdog, 3);
    if (level > 0) escalate(slot, static_cast<std::uint8_t>(level));
    if (slot.health.load(std::memory_order_acquire) != NodeHealthState::Isolated) {
      const std::uint8_t reached = slot.watchdog_level.load(std::memory_order_acquire);
      const NodeHealthState after = reached == 0   ? NodeHealthState::Healthy
                                    : reached == 1 ? NodeHealthState::Warning
                                                   : NodeHealthState::Unhealthy;
      set_health(slot, after);
      if (after == NodeHealthState::Unhealthy) slot.unhealthy_until_ns = end + watchdog;
    }
    if (slot.pending_safe_state.exchange(false, std::memory_order_acq_rel)) enter_safe(slot);
  }
  const std::int64_t deadline = slot.deadline_ns.load(std::memory_order_relaxed);
  if (judged && deadline > 0 && end - release > deadline) {
    deadline_missed(slot, end - release - deadline, end);
    return log_tick(slot, cycle, start, duration, TickOutcome::DeadlineMiss);
  }
  log_tick(slot, cycle, start, duration, outcome);
}

void SchedulerImpl::handle_failure(NodeSlot& slot, Phase phase, const std::string& what,
                                   std::int64_t now) noexcept {
  slot.errors.fetch_add(1, std::memory_order_relaxed);
  try {
    std::lock_guard lock(mutex_);
    slot.last_error = std::string(phase_name(phase)) + ": " + what;
  } catch (...) {
    // Out of memory while recording the message: the counters above still tell the story.
  }
  record(phase == Phase::Init       ? BlackboxEventKind::NodeInitFailed
         : phase == Phase::Shutdown ? BlackboxEventKind::NodeShutdownFailed
                                    : BlackboxEventKind::NodeError,
         slot, 0, what);
  try {
    TickContextScope scope(&slot.context);
    slot.node->on_error(what);
  } catch (...) {
    log(LogLevel::Error, "node '%s': on_error() threw while handling: %s", slot.name.c_str(),
        what.c_str());
  }
  if (phase == Phase::Shutdown) return;

  char reason[160];
  const FailurePolicy& policy = slot.config.failure_policy;
  switch (policy.kind()) {
    case FailurePolicy::Kind::Fatal:
      if (phase == Phase::Init && !policy.fatal()->stop_on_failed_init) {
        slot.state.store(NodeState::Error);
        break;
      }
      slot.state.store(phase == Phase::Tick ? NodeState::Crashed : NodeState::Error);
      std::snprintf(reason, sizeof(reason), "node '%s' failed in %s: %s (FailurePolicy::Fatal)",
                    slot.name.c_str(), phase_name(phase), what.c_str());
      request_stop(reason, true);
      break;
    case FailurePolicy::Kind::Restart: {
      const FailurePolicy::Restart& r = *policy.restart();
      if (slot.restart_attempts >= r.max_restarts) {
        slot.state.store(NodeState::Error);
        std::snprintf(reason, sizeof(reason), "node '%s' still failing after %u restarts: %s",
                      slot.name.c_str(), r.max_restarts, what.c_str());
        request_stop(reason, true);
        break;
      }
      const std::int64_t backoff = r.initial_backoff.count()
                                   << std::min<std::uint32_t>(slot.restart_attempts, 30);
      ++slot.restart_attempts;
      slot.resume_at_ns = now + backoff;
      slot.restart_pending = true;
      slot.state.store(NodeState::Uninitialized);
      break;
    }
    case FailurePolicy::Kind::Skip: {
      if (phase == Phase::Init) {
        slot.state.store(NodeState::Error);
        break;
      }
      const FailurePolicy::Skip& s = *policy.skip();
      if (++slot.consecutive_failures >= s.max_failures) {
        slot.consecutive_failures = 0;
        slot.resume_at_ns = now + s.cooldown.count();
        if (config_.verbose()) {
          log(LogLevel::Warn, "node '%s': %u consecutive failures, cooling down", slot.name.c_str(),
              s.max_failures);
        }
      }
      break;
    }
    case FailurePolicy::Kind::Ignore:
      if (phase == Phase::Init) slot.state.store(NodeState::Error);
      break;
  }
  if (phase == Phase::Init && slot.state.load() == NodeState::Error) {
    log(LogLevel::Error, "node '%s' excluded: init() failed: %s", slot.name.c_str(), what.c_str());
  }
}

void SchedulerImpl::deadline_missed(NodeSlot& slot, std::int64_t late_ns,
                                    std::int64_t now_ns) noexcept {
  const std::uint64_t mine = slot.deadline_misses.fetch_add(1, std::memory_order_relaxed) + 1;
  const std::uint64_t total = total_misses_.fetch_add(1, std::memory_order_relaxed) + 1;
  record(BlackboxEventKind::DeadlineMiss, slot, late_ns, to_string(slot.config.on_miss));
  const auto limit = config_.max_deadline_misses();
  // The first miss and then one line per interval, whatever the policy: a node that keeps
  // missing shows up in the log long before the limit stops everything, without a line per miss.
  if (mine == 1 || config_.verbose() || now_ns - slot.miss_logged_ns >= kMissLogIntervalNs) {
    slot.miss_logged_ns = now_ns;
    char of_limit[64] = "";
    if (limit) {
      std::snprintf(of_limit, sizeof(of_limit), " of max_deadline_misses %llu",
                    static_cast<unsigned long long>(*limit));
    }
    const std::string_view policy = to_string(slot.config.on_miss);
    log(LogLevel::Warn,
        "node '%s' missed its deadline (%lld us) by %lld us (Miss::%.*s); misses: %llu by this "
        "node, %llu%s in total",
        slot.name.c_str(),
        static_cast<long long>(slot.deadline_ns.load(std::memory_order_relaxed) / 1000),
        static_cast<long long>(late_ns / 1000), static_cast<int>(policy.size()), policy.data(),
        static_cast<unsigned long long>(mine), static_cast<unsigned long long>(total), of_limit);
  }
  switch (slot.config.on_miss) {
    case Miss::Warn:
      slot.warnings.fetch_add(1, std::memory_order_relaxed);
      break;
    case Miss::Skip:
      slot.skip_next = true;
      break;
    case Miss::SafeMode:
      enter_safe(slot);
      break;
    case Miss::Stop: {
      char reason[160];
      std::snprintf(reason, sizeof(reason), "node '%s' missed its deadline (Miss::Stop)",
                    slot.name.c_str());
      request_stop(reason, true);
      break;
    }
  }
  // Only the miss that reaches the limit says so: the counter hands out each total once.
  if (limit && total == *limit) {
    try {
      request_stop(miss_limit_reason(*limit), true);
    } catch (...) {
      request_stop("max_deadline_misses reached", true);  // out of memory for the details
    }
  }
}

std::string SchedulerImpl::miss_limit_reason(std::uint64_t limit) const {
  std::vector<std::pair<std::uint64_t, std::string>> missed;
  for (const SlotPtr& s : ordered_slots()) {
    if (const auto n = s->deadline_misses.load(std::memory_order_relaxed); n > 0) {
      missed.emplace_back(n, s->name);
    }
  }
  std::stable_sort(missed.begin(), missed.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string nodes;
  for (const auto& [count, name] : missed) {
    nodes += (nodes.empty() ? "'" : ", '") + name + "' " + std::to_string(count);
  }
  return "max_deadline_misses (" + std::to_string(limit) + ") reached: deadline misses by node " +
         nodes +
         "; a node with a rate has a deadline of 95 % of its period unless deadline() sets it; "
         "raise the limit with max_deadline_misses(n), or never stop with "
         "max_deadline_misses(std::nullopt) (None in Python)";
}

}  // namespace horus::detail
