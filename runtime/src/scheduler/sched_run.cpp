// The scheduler's loops: releasing nodes on their grids, timing checks, failure policies,
// the watchdog, signals and shutdown.
#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <fcntl.h>
#include <algorithm>
#include <cerrno>
#include <climits>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <thread>
#include <tuple>

#include "horus/detail/errno_text.hpp"
#include "horus/error.hpp"
#include "sched_impl_class.hpp"

namespace horus::detail {
namespace {

constexpr std::int64_t kMaxSleepNs = 3'600'000'000'000;  // an hour: avoids timespec overflow
constexpr std::int64_t kEventWaitSliceNs = 200'000'000;

// ---- process-wide signal plumbing (async-signal-safe parts only) ----------------------------

std::atomic<int> g_signal{0};
std::atomic<std::atomic<std::uint32_t>*> g_wake_word{nullptr};
std::atomic<const Blackbox*> g_crash_box{nullptr};
char g_crash_path[4096];

void wake(std::atomic<std::uint32_t>& word) noexcept {
  word.store(1, std::memory_order_release);
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr,
          nullptr, 0);
}

void on_stop_signal(int signo) {
  g_signal.store(signo);
  if (auto* word = g_wake_word.load()) wake(*word);
}

constexpr int kCrashSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
struct sigaction g_previous_crash[std::size(kCrashSignals)];

void on_crash_signal(int signo) {
  if (const Blackbox* box = g_crash_box.exchange(nullptr)) {
    const int fd = ::open(g_crash_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd >= 0) {
      box->write_to_fd(fd);
      ::close(fd);
      static const char note[] = "[horus] crash: blackbox written\n";
      [[maybe_unused]] const auto n = ::write(STDERR_FILENO, note, sizeof(note) - 1);
    }
  }
  for (std::size_t i = 0; i < std::size(kCrashSignals); ++i) {
    if (kCrashSignals[i] == signo) sigaction(signo, &g_previous_crash[i], nullptr);
  }
  raise(signo);
}

/// Turns SIGINT/SIGTERM into a stop of the loop for its lifetime, and dumps the blackbox on a
/// crash; restores the previous handlers afterwards.
class SignalScope {
 public:
  SignalScope(bool stop_signals, std::atomic<std::uint32_t>& word, const Blackbox* box,
              const std::filesystem::path& box_path)
      : stop_signals_(stop_signals), crash_(box != nullptr) {
    if (stop_signals_) {
      g_signal.store(0);
      g_wake_word.store(&word);
      struct sigaction action {};
      action.sa_handler = on_stop_signal;
      sigemptyset(&action.sa_mask);
      sigaction(SIGINT, &action, &previous_int_);
      sigaction(SIGTERM, &action, &previous_term_);
    }
    if (crash_) {
      const std::string path = std::filesystem::absolute(box_path).string();
      std::snprintf(g_crash_path, sizeof(g_crash_path), "%s", path.c_str());
      g_crash_box.store(box);
      struct sigaction action {};
      action.sa_handler = on_crash_signal;
      sigemptyset(&action.sa_mask);
      for (std::size_t i = 0; i < std::size(kCrashSignals); ++i) {
        sigaction(kCrashSignals[i], &action, &g_previous_crash[i]);
      }
    }
  }
  ~SignalScope() {
    if (stop_signals_) {
      sigaction(SIGINT, &previous_int_, nullptr);
      sigaction(SIGTERM, &previous_term_, nullptr);
      g_wake_word.store(nullptr);
    }
    if (crash_) {
      g_crash_box.store(nullptr);
      for (std::size_t i = 0; i < std::size(kCrashSignals); ++i) {
        sigaction(kCrashSignals[i], &g_previous_crash[i], nullptr);
      }
    }
  }
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

 private:
  bool stop_signals_;
  bool crash_;
  struct sigaction previous_int_ {};
  struct sigaction previous_term_ {};
};

std::string exception_text(std::exception_ptr error) {
  try {
    std::rethrow_exception(error);
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "unknown exception";
  }
}

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

std::int64_t next_on_grid(std::int64_t release, std::int64_t period, std::int64_t now) {
  std::int64_t next = release + period;
  if (next <= now) next += ((now - next) / period + 1) * period;
  return next;
}

}  // namespace

// Marks the scheduler busy for the duration of a run/tick call; a second concurrent call is a
// usage error.
class SchedulerImpl::Activity {
 public:
  Activity(SchedulerImpl& s, bool loop) : s_(s), loop_(loop) {
    bool expected = false;
    if (!s.active_.compare_exchange_strong(expected, true)) {
      throw Error("horus::Scheduler '" + s.config_.name() +
                  "': already running (run/tick_once/tick_for called concurrently or from a tick)");
    }
    if (s.finished_) {
      s.active_.store(false);
      throw Error("horus::Scheduler '" + s.config_.name() +
                  "': its nodes have already been shut down; build a new scheduler");
    }
    if (loop_) s.in_loop_.store(true, std::memory_order_release);
  }
  ~Activity() {
    if (loop_) s_.in_loop_.store(false, std::memory_order_release);
    s_.active_.store(false);
  }
  Activity(const Activity&) = delete;
  Activity& operator=(const Activity&) = delete;

 private:
  SchedulerImpl& s_;
  bool loop_;
};

// ---- one node ---------------------------------------------------------------------------------

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
  const bool watched = slot.watchdog_ns > 0 && !deterministic;
  const std::int64_t start = deterministic ? monotonic_ns() : mono;
  ctx.tick_start_ns = start;
  ctx.release_ns = deterministic ? start : release;
  if (watched) {
    slot.watchdog_level.store(0, std::memory_order_relaxed);
    slot.tick_started_ns.store(start, std::memory_order_release);
  }
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
  // Wall-clock enforcement would make a deterministic run depend on the machine's load.
  if (deterministic) return;

  if (ctx.budget_ns > 0 && duration > ctx.budget_ns) {
    slot.budget_overruns.fetch_add(1, std::memory_order_relaxed);
    total_overruns_.fetch_add(1, std::memory_order_relaxed);
    record(BlackboxEventKind::BudgetOverrun, slot, duration);
  }
  if (watched) {
    const std::int64_t level = std::min<std::int64_t>(duration / slot.watchdog_ns, 3);
    if (level > 0) escalate(slot, static_cast<std::uint8_t>(level));
    if (slot.health.load(std::memory_order_acquire) != NodeHealthState::Isolated) {
      const std::uint8_t reached = slot.watchdog_level.load(std::memory_order_acquire);
      const NodeHealthState after = reached == 0   ? NodeHealthState::Healthy
                                    : reached == 1 ? NodeHealthState::Warning
                                                   : NodeHealthState::Unhealthy;
      set_health(slot, after);
      if (after == NodeHealthState::Unhealthy) slot.unhealthy_until_ns = end + slot.watchdog_ns;
    }
    if (slot.pending_safe_state.exchange(false, std::memory_order_acq_rel)) enter_safe(slot);
  }
  const std::int64_t deadline = slot.deadline_ns.load(std::memory_order_relaxed);
  if (deadline > 0 && end - release > deadline) deadline_missed(slot, end - release - deadline);
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
    log(LogLevel::Error, "node '%s': on_error() threw while handling: %s", slot.name.c_str(), what.c_str());
  }
  if (phase == Phase::Shutdown) return;

  char reason[160];
  const FailurePolicy& policy = slot.config.failure_policy;
  switch (policy.kind()) {
    case FailurePolicy::Kind::Fatal:
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

void SchedulerImpl::deadline_missed(NodeSlot& slot, std::int64_t late_ns) noexcept {
  const std::uint64_t mine = slot.deadline_misses.fetch_add(1, std::memory_order_relaxed) + 1;
  const std::uint64_t total = total_misses_.fetch_add(1, std::memory_order_relaxed) + 1;
  record(BlackboxEventKind::DeadlineMiss, slot, late_ns, to_string(slot.config.on_miss));
  char reason[160];
  switch (slot.config.on_miss) {
    case Miss::Warn:
      slot.warnings.fetch_add(1, std::memory_order_relaxed);
      if (mine == 1 || config_.verbose()) {
        log(LogLevel::Warn, "node '%s' missed its deadline by %lld us%s", slot.name.c_str(),
            static_cast<long long>(late_ns / 1000),
            mine == 1 ? " (further misses counted only)" : "");
      }
      break;
    case Miss::Skip:
      slot.skip_next = true;
      break;
    case Miss::SafeMode:
      enter_safe(slot);
      break;
    case Miss::Stop:
      std::snprintf(reason, sizeof(reason), "node '%s' missed its deadline (Miss::Stop)",
                    slot.name.c_str());
      request_stop(reason, true);
      break;
  }
  if (const auto limit = config_.max_deadline_misses(); limit && total >= *limit) {
    std::snprintf(reason, sizeof(reason), "max_deadline_misses (%llu) reached",
                  static_cast<unsigned long long>(*limit));
    request_stop(reason, true);
  }
}

void SchedulerImpl::escalate(NodeSlot& slot, std::uint8_t level) noexcept {
  std::uint8_t previous = slot.watchdog_level.load(std::memory_order_acquire);
  while (previous < level &&
         !slot.watchdog_level.compare_exchange_weak(previous, level, std::memory_order_acq_rel)) {
  }
  if (previous >= level) return;
  if (previous == 0) {
    slot.watchdog_expirations.fetch_add(1, std::memory_order_relaxed);
    total_watchdog_.fetch_add(1, std::memory_order_relaxed);
  }
  record(BlackboxEventKind::WatchdogExpired, slot, level);
  const NodeHealthState target = level >= 3 && slot.critical ? NodeHealthState::Isolated
                                 : level >= 2                ? NodeHealthState::Unhealthy
                                                             : NodeHealthState::Warning;
  NodeHealthState current = slot.health.load(std::memory_order_acquire);
  while (current < target &&
         !slot.health.compare_exchange_weak(current, target, std::memory_order_acq_rel)) {
  }
  if (current >= target) return;
  record(BlackboxEventKind::HealthChange, slot, static_cast<std::int64_t>(target),
         to_string(target));
  if (target == NodeHealthState::Warning) slot.warnings.fetch_add(1, std::memory_order_relaxed);
  if (target == NodeHealthState::Isolated) {
    // A frozen critical node puts the whole system in its safe state. Each node enters it on its
    // own thread at its next release, never concurrently with its own tick().
    log(LogLevel::Error, "critical node '%s' frozen (3x watchdog): isolating it, all nodes to safe state",
        slot.name.c_str());
    slot.pending_safe_state.store(true, std::memory_order_release);
    for (const SlotPtr& other : loop_slots_) {
      if (other.get() != &slot) other->pending_safe_state.store(true, std::memory_order_release);
    }
  } else if (config_.verbose() || target == NodeHealthState::Unhealthy) {
    log(LogLevel::Warn, "node '%s' exceeded %dx its watchdog timeout: %s", slot.name.c_str(), level,
        std::string(to_string(target)).c_str());
  }
}

void SchedulerImpl::set_health(NodeSlot& slot, NodeHealthState health) noexcept {
  const NodeHealthState previous = slot.health.exchange(health, std::memory_order_acq_rel);
  if (previous != health) {
    record(BlackboxEventKind::HealthChange, slot, static_cast<std::int64_t>(health),
           to_string(health));
  }
}

void SchedulerImpl::enter_safe(NodeSlot& slot) noexcept {
  if (slot.state.load() != NodeState::Running) return;
  try {
    TickContextScope scope(&slot.context);
    slot.node->enter_safe_state();
  } catch (...) {
    log(LogLevel::Error, "node '%s': enter_safe_state() threw", slot.name.c_str());
  }
  set_health(slot, NodeHealthState::Isolated);
  record(BlackboxEventKind::SafeStateEntered, slot);
}

void SchedulerImpl::request_stop(std::string_view reason, bool failure) noexcept {
  if (failure) failed_.store(true);
  bool expected = false;
  if (stop_requested_.compare_exchange_strong(expected, true)) {
    std::snprintf(stop_reason_, sizeof(stop_reason_), "%.*s", static_cast<int>(reason.size()),
                  reason.data());
    stop_reason_set_.store(true, std::memory_order_release);
    record_scheduler(BlackboxEventKind::StopRequested, reason);
    if (failure || config_.verbose()) {
      log(failure ? LogLevel::Error : LogLevel::Info, "stopping: %s", stop_reason_);
    }
  }
  wake(wake_word_);
}

void SchedulerImpl::check_signal() noexcept {
  const int signo = g_signal.exchange(0);
  if (signo != 0) {
    char reason[48];
    std::snprintf(reason, sizeof(reason), "received %s", signo == SIGINT ? "SIGINT" : "SIGTERM");
    request_stop(reason, false);
  }
}

// ---- shutdown -----------------------------------------------------------------------------------

void SchedulerImpl::shutdown_node(const SlotPtr& slot, bool removing) noexcept {
  NodeSlot& s = *slot;
  if (s.initialized && !s.shut_down)
    s.stopped_at_ns.store(monotonic_ns(), std::memory_order_relaxed);
  if (s.initialized && !s.shut_down) {
    if (s.tick_started_ns.load(std::memory_order_acquire) != 0) {
      // Its thread is still inside tick() (detached at teardown): calling shutdown() now would
      // run two methods of one node at once.
      record(BlackboxEventKind::NodeShutdownFailed, s, 0, "still inside tick(); skipped");
      log(LogLevel::Error, "node '%s' never returned from tick(); shutdown() skipped", s.name.c_str());
      s.state.store(NodeState::Error);
      s.shut_down = true;
    } else {
      // A crashed node is still shut down (to zero its actuators) but keeps its failure state.
      const NodeState before = s.state.load();
      const bool failed_before = before == NodeState::Crashed || before == NodeState::Error;
      s.state.store(NodeState::Stopping);
      struct Outcome {
        std::mutex mutex;
        std::condition_variable done_cv;
        bool done = false;
        std::exception_ptr error;
      };
      auto outcome = std::make_shared<Outcome>();
      bool finished = false;
      try {
        // A helper thread bounds a hanging shutdown(): it is abandoned (and the node leaked)
        // after shutdown_timeout so the other nodes still shut down.
        std::thread worker([slot, outcome, self = shared_from_this()] {
          std::exception_ptr error;
          {
            TickContextScope scope(&slot->context);
            try {
              slot->node->shutdown();
            } catch (...) {
              error = std::current_exception();
            }
          }
          std::lock_guard lock(outcome->mutex);
          outcome->error = error;
          outcome->done = true;
          outcome->done_cv.notify_all();
        });
        {
          std::unique_lock lock(outcome->mutex);
          finished = outcome->done_cv.wait_for(lock, config_.shutdown_timeout(),
                                               [&] { return outcome->done; });
        }
        if (finished) {
          worker.join();
        } else {
          worker.detach();
        }
      } catch (...) {
        log(LogLevel::Error, "node '%s': could not start its shutdown thread", s.name.c_str());
      }
      s.shut_down = true;
      if (!finished) {
        const long long ms = static_cast<long long>(config_.shutdown_timeout().count() / 1'000'000);
        char why[96];
        std::snprintf(why, sizeof(why), "shutdown() did not return within %lld ms; abandoned", ms);
        handle_failure(s, Phase::Shutdown, why, 0);
        s.state.store(NodeState::Error);
      } else if (outcome->error) {
        handle_failure(s, Phase::Shutdown, exception_text(outcome->error), 0);
        s.state.store(failed_before ? before : NodeState::Stopped);
      } else {
        s.state.store(failed_before ? before : NodeState::Stopped);
        record(BlackboxEventKind::NodeShutdown, s);
      }
    }
  } else if (!s.initialized) {
    s.state.store(s.state.load() == NodeState::Error ? NodeState::Error : NodeState::Stopped);
  }
  if (removing) {
    s.removed.store(true, std::memory_order_release);
    record(BlackboxEventKind::NodeRemoved, s);
  }
}

void SchedulerImpl::shutdown_all() noexcept {
  std::vector<SlotPtr> slots;
  {
    std::lock_guard lock(mutex_);
    slots = slots_;
  }
  for (auto it = slots.rbegin(); it != slots.rend(); ++it) {
    if (!(*it)->removed.load()) shutdown_node(*it, false);
  }
}

void SchedulerImpl::purge_removed() noexcept {
  if (!removals_pending_.exchange(false, std::memory_order_acq_rel)) return;
  std::vector<SlotPtr> pending;
  {
    std::lock_guard lock(mutex_);
    for (const SlotPtr& s : slots_) {
      if (s->remove_requested.load() && !s->removed.load()) pending.push_back(s);
    }
  }
  for (const SlotPtr& s : pending) shutdown_node(s, true);
  std::lock_guard lock(mutex_);
  std::erase_if(slots_, [](const SlotPtr& s) { return s->removed.load(); });
  structure_version_.fetch_add(1, std::memory_order_release);
}

void SchedulerImpl::finish() noexcept {
  request_stop("scheduler destroyed", false);
  if (active_.load()) return;  // a loop on another thread still owns the nodes
  if (prepared_ && !finished_) {
    shutdown_all();
    finished_ = true;
  }
}

// ---- loops --------------------------------------------------------------------------------------

bool SchedulerImpl::sleep_until(std::int64_t target) noexcept {
  for (;;) {
    if (loop_ending()) return false;
    const std::int64_t now = monotonic_ns();
    if (now >= target) return true;
    const std::int64_t until = std::min(target, now + kMaxSleepNs);
    timespec abs{};
    abs.tv_sec = static_cast<time_t>(until / 1'000'000'000);
    abs.tv_nsec = static_cast<long>(until % 1'000'000'000);
    // An absolute CLOCK_MONOTONIC sleep that stop() can cut short through the same word.
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&wake_word_),
            FUTEX_WAIT_BITSET | FUTEX_PRIVATE_FLAG, 0, &abs, nullptr, FUTEX_BITSET_MATCH_ANY);
  }
}

void SchedulerImpl::pass_once(const std::vector<std::string>* names) {
  const bool deterministic = config_.deterministic();
  refresh_loop_slots();
  const std::vector<SlotPtr>& slots = loop_slots_;
  if (names != nullptr) {
    for (const std::string& n : *names) {
      if (std::none_of(slots.begin(), slots.end(),
                       [&](const SlotPtr& s) { return s->name == n; })) {
        throw Error("tick_once: no node named '" + n + "'");
      }
    }
  }
  std::int64_t mono = monotonic_ns();
  const std::int64_t pass_start = mono;
  for (const SlotPtr& slot : slots) {
    NodeSlot& s = *slot;
    if (names != nullptr && std::find(names->begin(), names->end(), s.name) == names->end())
      continue;
    if (s.execution_class == ExecutionClass::Event) {
      if (s.notifier->wait(std::chrono::nanoseconds(0))) service(s, mono, mono);
    } else if (deterministic) {
      if (s.next_release_ns <= sim_now_ns_) {
        const std::int64_t release = s.next_release_ns;
        service(s, release, mono);
        s.next_release_ns = next_on_grid(release, s.period_ns.load(), sim_now_ns_);
      }
    } else {
      service(s, pass_start, mono);
    }
    if (stop_requested_.load(std::memory_order_relaxed)) break;
  }
  cycle_.fetch_add(1, std::memory_order_relaxed);
  if (deterministic) sim_now_ns_ += tick_period_ns_;
}

void SchedulerImpl::tick_once(const std::vector<std::string>* names) {
  Activity activity(*this, false);
  prepare();
  if (stop_requested_.load()) return;
  pass_once(names);
  purge_removed();
}

void SchedulerImpl::tick_for(std::int64_t duration_ns, const std::vector<std::string>* names) {
  if (duration_ns < 0) throw Error("tick_for: duration must not be negative");
  Activity activity(*this, true);
  prepare();
  real_loop(duration_ns, names);
  purge_removed();
}

int SchedulerImpl::run(std::optional<std::int64_t> duration_ns) {
  if (duration_ns && *duration_ns < 0) throw Error("run_for: duration must not be negative");
  {
    Activity activity(*this, true);
    prepare();
    real_loop(duration_ns, nullptr);
    purge_removed();
    check_signal();
    shutdown_all();
    {
      std::lock_guard lock(mutex_);
      finished_ = true;
    }
    record_scheduler(BlackboxEventKind::SchedulerStop, stop_reason());
  }
  if (failed_.load() && blackbox_) {
    try {
      blackbox_->write_to(blackbox_path_);
      log(LogLevel::Error, "blackbox written to %s", blackbox_path_.c_str());
    } catch (const Error& e) {
      log(LogLevel::Error, "%s", e.what());
    }
  }
  log::flush();  // the run's lines precede whatever the caller prints next
  if (config_.verbose()) std::fprintf(stderr, "%s", timing_report().c_str());
  return failed_.load() ? 1 : 0;
}

void SchedulerImpl::real_loop(std::optional<std::int64_t> duration_ns,
                              const std::vector<std::string>* names) {
  if (stop_requested_.load()) return;
  SignalScope signals(config_.handle_signals(), wake_word_, blackbox_.get(), blackbox_path_);
  refresh_loop_slots();
  std::vector<SlotPtr> slots = loop_slots_;
  if (names != nullptr) {
    for (const std::string& n : *names) {
      if (std::none_of(slots.begin(), slots.end(),
                       [&](const SlotPtr& s) { return s->name == n; })) {
        throw Error("tick_for: no node named '" + n + "'");
      }
    }
    std::erase_if(slots, [&](const SlotPtr& s) {
      return std::find(names->begin(), names->end(), s->name) == names->end();
    });
  }

  if (config_.deterministic()) {
    // Simulated time: as fast as possible, on this thread, in order.
    const std::int64_t end =
        duration_ns ? sim_now_ns_ + *duration_ns : std::numeric_limits<std::int64_t>::max();
    while (!stop_requested_.load() && sim_now_ns_ < end) {
      check_signal();
      if (stop_requested_.load()) break;
      pass_once(names);
    }
    return;
  }

  const std::int64_t loop_start = monotonic_ns();
  const std::int64_t end =
      duration_ns ? loop_start + *duration_ns : std::numeric_limits<std::int64_t>::max();

  // Partition the nodes among executors by execution class.
  auto main = std::make_shared<Executor>();
  main->label = "main";
  main->main = true;
  std::vector<std::shared_ptr<Executor>> executors;
  std::map<std::tuple<std::int64_t, int, int>, std::shared_ptr<Executor>> rt_groups;
  std::vector<SlotPtr> compute;
  std::vector<SlotPtr> events;
  std::vector<SlotPtr> watched;
  for (const SlotPtr& s : slots) {
    s->next_release_ns = loop_start;
    if (s->watchdog_ns > 0) watched.push_back(s);
    switch (s->execution_class) {
      case ExecutionClass::BestEffort:
        main->slots.push_back(s);
        break;
      case ExecutionClass::Rt: {
        const auto key = std::make_tuple(s->period_ns.load(), s->config.core.value_or(-1),
                                         s->config.priority.value_or(0));
        auto& ex = rt_groups[key];
        if (!ex) {
          ex = std::make_shared<Executor>();
          ex->label = "rt:" + s->name;
          ex->realtime = true;
          ex->priority = s->config.priority;
          ex->core = s->config.core;
          executors.push_back(ex);
        }
        ex->slots.push_back(s);
        break;
      }
      case ExecutionClass::Compute:
        compute.push_back(s);
        break;
      case ExecutionClass::Event:
        events.push_back(s);
        break;
      case ExecutionClass::AsyncIo: {
        auto ex = std::make_shared<Executor>();
        ex->label = "io:" + s->name;
        ex->core = s->config.core;
        ex->slots.push_back(s);
        executors.push_back(ex);
        break;
      }
    }
  }
  if (!compute.empty()) {
    const std::size_t cpus = std::max(1U, std::thread::hardware_concurrency());
    const std::size_t workers =
        std::min(compute.size(), config_.compute_threads() > 0 ? config_.compute_threads() : cpus);
    std::vector<std::shared_ptr<Executor>> pool;
    for (std::size_t i = 0; i < workers; ++i) {
      auto ex = std::make_shared<Executor>();
      ex->label = "compute:" + std::to_string(i);
      pool.push_back(ex);
      executors.push_back(ex);
    }
    for (std::size_t i = 0; i < compute.size(); ++i) pool[i % workers]->slots.push_back(compute[i]);
  }
  for (const SlotPtr& s : slots) {
    if (s->config.priority && !config_.rt()) {
      add_degradation("priority " + std::to_string(*s->config.priority) + " of node '" + s->name +
                      "' ignored: rt is off");
    }
  }

  // Threads: stop signals go to the thread that called run(), never to a node's thread.
  sigset_t blocked;
  sigset_t previous_mask;
  sigemptyset(&blocked);
  sigaddset(&blocked, SIGINT);
  sigaddset(&blocked, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &blocked, &previous_mask);
  struct Running {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> exited;
  };
  std::vector<Running> threads;
  auto self = shared_from_this();
  const auto spawn = [&](auto body) {
    auto exited = std::make_shared<std::atomic<bool>>(false);
    threads.push_back({std::thread([body, exited, self] {
                         body();
                         exited->store(true, std::memory_order_release);
                       }),
                       exited});
  };
  try {
    for (const auto& ex : executors) {
      spawn([this, ex, end] { run_executor(*ex, end); });
    }
    for (const SlotPtr& s : events) {
      spawn([this, s, end] {
        Executor ex;
        ex.label = "event:" + s->name;
        ex.core = s->config.core;
        apply_thread_settings(ex);
        run_event(*s, end);
      });
    }
    if (!watched.empty()) {
      spawn([this, watched, end] { run_watchdog(watched, end); });
    }
  } catch (...) {
    pthread_sigmask(SIG_SETMASK, &previous_mask, nullptr);
    request_stop("could not start the scheduler's threads", true);
    for (auto& t : threads) t.thread.join();
    throw;
  }
  pthread_sigmask(SIG_SETMASK, &previous_mask, nullptr);

  // The main loop: BestEffort nodes on the scheduler's tick grid.
  cpu_set_t previous_affinity;
  const bool pinned =
      !config_.cores().empty() &&
      pthread_getaffinity_np(pthread_self(), sizeof(previous_affinity), &previous_affinity) == 0;
  if (pinned) apply_thread_settings(*main);
  std::int64_t next_cycle = loop_start;
  for (;;) {
    const bool on_time = sleep_until(std::min(next_cycle, end));
    check_signal();
    if (!on_time || stop_requested_.load()) break;
    std::int64_t mono = monotonic_ns();
    if (mono >= end) break;
    cycle_.fetch_add(1, std::memory_order_relaxed);
    for (const SlotPtr& slot : main->slots) {
      NodeSlot& s = *slot;
      if (s.next_release_ns > mono) continue;
      const std::int64_t release = s.next_release_ns;
      service(s, release, mono);
      s.next_release_ns = next_on_grid(release, s.period_ns.load(std::memory_order_relaxed), mono);
    }
    next_cycle = next_on_grid(next_cycle, tick_period_ns_, mono);
  }
  if (pinned) pthread_setaffinity_np(pthread_self(), sizeof(previous_affinity), &previous_affinity);

  // Teardown: end every thread; one stuck in a node's tick is abandoned after shutdown_timeout.
  wake(wake_word_);
  for (const SlotPtr& s : events) s->notifier->interrupt();
  const std::int64_t give_up = monotonic_ns() + config_.shutdown_timeout().count();
  for (auto& t : threads) {
    while (!t.exited->load(std::memory_order_acquire) && monotonic_ns() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (t.exited->load(std::memory_order_acquire)) {
      t.thread.join();
    } else {
      t.thread.detach();
      log(LogLevel::Error, "a scheduler thread did not finish within the shutdown timeout; detached");
    }
  }
  // Ready for another loop (tick_for may be called again) unless a stop was requested.
  if (!stop_requested_.load()) wake_word_.store(0, std::memory_order_release);
}

void SchedulerImpl::apply_thread_settings(const Executor& ex) noexcept {
  try {
    cpu_set_t cpus;
    CPU_ZERO(&cpus);
    bool pin = false;
    if (ex.core) {
      CPU_SET(static_cast<unsigned>(*ex.core), &cpus);
      pin = true;
    } else if (!config_.cores().empty()) {
      for (const int c : config_.cores()) CPU_SET(static_cast<unsigned>(c), &cpus);
      pin = true;
    }
    if (pin) {
      if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof(cpus), &cpus); rc != 0) {
        add_degradation("could not pin thread " + ex.label + ": " + detail::errno_text(rc));
      }
    }
    if (ex.realtime && config_.rt()) {
      sched_param param{};
      param.sched_priority = ex.priority.value_or(50);
      if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) != 0) {
        add_degradation("SCHED_FIFO unavailable (no CAP_SYS_NICE) - using SCHED_OTHER");
      }
    }
  } catch (...) {
    log(LogLevel::Warn, "could not apply thread settings to %s", ex.label.c_str());
  }
}

void SchedulerImpl::run_executor(Executor& ex, std::int64_t end) noexcept {
  apply_thread_settings(ex);
  while (!loop_ending()) {
    std::int64_t earliest = end;
    for (const SlotPtr& s : ex.slots) earliest = std::min(earliest, s->next_release_ns);
    if (!sleep_until(earliest)) break;
    std::int64_t mono = monotonic_ns();
    if (mono >= end) break;
    for (const SlotPtr& slot : ex.slots) {
      NodeSlot& s = *slot;
      if (s.next_release_ns > mono) continue;
      const std::int64_t release = s.next_release_ns;
      service(s, release, mono);
      s.next_release_ns = next_on_grid(release, s.period_ns.load(std::memory_order_relaxed), mono);
    }
  }
}

void SchedulerImpl::run_event(NodeSlot& slot, std::int64_t end) noexcept {
  while (!loop_ending()) {
    const std::int64_t now = monotonic_ns();
    if (now >= end) break;
    const std::int64_t slice = std::min(end - now, kEventWaitSliceNs);
    if (slot.notifier->wait(std::chrono::nanoseconds(slice)) && !loop_ending()) {
      std::int64_t mono = monotonic_ns();
      service(slot, mono, mono);
    }
  }
}

void SchedulerImpl::run_watchdog(const std::vector<SlotPtr>& watched, std::int64_t end) noexcept {
  std::int64_t shortest = std::numeric_limits<std::int64_t>::max();
  for (const SlotPtr& s : watched) shortest = std::min(shortest, s->watchdog_ns);
  const std::int64_t interval = std::clamp<std::int64_t>(shortest / 4, 1'000'000, 50'000'000);
  std::int64_t next = monotonic_ns() + interval;
  while (sleep_until(std::min(next, end))) {
    const std::int64_t now = monotonic_ns();
    if (now >= end) break;
    for (const SlotPtr& s : watched) {
      const std::int64_t started = s->tick_started_ns.load(std::memory_order_acquire);
      if (started == 0 || now - started < s->watchdog_ns) continue;
      escalate(*s, static_cast<std::uint8_t>(
                       std::min<std::int64_t>((now - started) / s->watchdog_ns, 3)));
    }
    next = next_on_grid(next, interval, now);
  }
}

}  // namespace horus::detail
