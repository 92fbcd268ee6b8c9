// The loops: the release grid, the executors' threads, and the main, simulated and single-pass
// loops that run nodes on them.
#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <csignal>
#include <limits>
#include <map>
#include <thread>
#include <tuple>

#include "horus/error.hpp"
#include "horus/internal/errno_text.hpp"
#include "scheduler_impl.hpp"
#include "signals.hpp"

namespace horus::detail {
namespace {

constexpr std::int64_t kMaxSleepNs = 3'600'000'000'000;  // an hour: avoids timespec overflow
constexpr std::int64_t kEventWaitSliceNs = 200'000'000;

/// Throws horus::Error naming the first of `names` that is not a node of `slots`.
void check_names(const std::vector<SlotPtr>& slots, const std::vector<std::string>& names,
                 const char* caller) {
  for (const std::string& n : names) {
    if (std::none_of(slots.begin(), slots.end(), [&](const SlotPtr& s) { return s->name == n; })) {
      throw Error(std::string(caller) + ": no node named '" + n + "'");
    }
  }
}

bool named(const std::vector<std::string>* names, const std::string& name) {
  return names == nullptr || std::find(names->begin(), names->end(), name) != names->end();
}

}  // namespace

/// The scheduler's threads for one loop. Stop signals stay with the thread that called run():
/// they are blocked while the threads start, so the threads inherit a mask without them.
class ThreadGroup {
 public:
  explicit ThreadGroup(std::shared_ptr<void> keep_alive) : keep_alive_(std::move(keep_alive)) {
    pthread_sigmask(SIG_BLOCK, &stop_signals(), &previous_mask_);
  }
  ~ThreadGroup() { unblock_signals(); }
  ThreadGroup(const ThreadGroup&) = delete;
  ThreadGroup& operator=(const ThreadGroup&) = delete;

  template <class Body>
  void spawn(Body body) {
    // A thread started later in the loop (a node added while running) is started masked too.
    sigset_t previous;
    const bool mask = !blocking_;
    if (mask) pthread_sigmask(SIG_BLOCK, &stop_signals(), &previous);
    auto exited = std::make_shared<std::atomic<bool>>(false);
    try {
      threads_.push_back({std::thread([body, exited, keep = keep_alive_] {
                            body();
                            exited->store(true, std::memory_order_release);
                          }),
                          exited});
    } catch (...) {
      if (mask) pthread_sigmask(SIG_SETMASK, &previous, nullptr);
      throw;
    }
    if (mask) pthread_sigmask(SIG_SETMASK, &previous, nullptr);
  }

  void unblock_signals() noexcept {
    if (blocking_) pthread_sigmask(SIG_SETMASK, &previous_mask_, nullptr);
    blocking_ = false;
  }

  /// Joins every thread that ends by `give_up_ns`; the others (stuck in a node's tick) are
  /// detached, still holding the scheduler alive. Returns how many were abandoned.
  std::size_t join_until(std::int64_t give_up_ns) {
    std::size_t abandoned = 0;
    for (Running& t : threads_) {
      while (!t.exited->load(std::memory_order_acquire) && monotonic_ns() < give_up_ns) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      if (t.exited->load(std::memory_order_acquire)) {
        t.thread.join();
      } else {
        t.thread.detach();
        ++abandoned;
      }
    }
    threads_.clear();
    return abandoned;
  }

 private:
  struct Running {
    std::thread thread;
    std::shared_ptr<std::atomic<bool>> exited;
  };
  static const sigset_t& stop_signals() {
    static const sigset_t set = [] {
      sigset_t signals;
      sigemptyset(&signals);
      sigaddset(&signals, SIGINT);
      sigaddset(&signals, SIGTERM);
      return signals;
    }();
    return set;
  }
  std::shared_ptr<void> keep_alive_;
  std::vector<Running> threads_;
  sigset_t previous_mask_{};
  bool blocking_ = true;
};

bool SchedulerImpl::sleep_until(std::int64_t target, const std::vector<SlotPtr>* slots) noexcept {
  // While this thread sleeps, the parameter service calls its nodes' on_param_change() itself.
  const auto lend = [slots](void (ParamOwner::*step)()) {
    if (slots == nullptr) return;
    for (const SlotPtr& slot : *slots) {
      if (slot->params) (slot->params.get()->*step)();
    }
  };
  lend(&ParamOwner::idle);
  bool on_time = false;
  for (;;) {
    if (loop_ending()) break;
    lend(&ParamOwner::deliver_while_idle);
    const std::int64_t now = monotonic_ns();
    if (now >= target) {
      on_time = true;
      break;
    }
    const std::int64_t until = std::min(target, now + kMaxSleepNs);
    timespec abs{};
    abs.tv_sec = static_cast<time_t>(until / 1'000'000'000);
    abs.tv_nsec = static_cast<long>(until % 1'000'000'000);
    // An absolute CLOCK_MONOTONIC sleep that stop() can cut short through the same word.
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&wake_word_),
            FUTEX_WAIT_BITSET | FUTEX_PRIVATE_FLAG, 0, &abs, nullptr, FUTEX_BITSET_MATCH_ANY);
  }
  lend(&ParamOwner::hold);
  return on_time;
}

void SchedulerImpl::wake_for_params(NodeSlot& slot) noexcept {
  // Every thread of the loop sleeps on the one word: each delivers its own nodes' changes and
  // sleeps on (the word itself stays 0, so no loop ends).
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&wake_word_), FUTEX_WAKE | FUTEX_PRIVATE_FLAG,
          INT_MAX, nullptr, nullptr, 0);
  if (slot.notifier) slot.notifier->interrupt();
}

void SchedulerImpl::release_if_due(NodeSlot& slot, std::int64_t& mono) noexcept {
  if (slot.next_release_ns > sched_now(mono)) return;
  const std::int64_t release = slot.next_release_ns;
  service(slot, release, mono);
  slot.next_release_ns =
      next_on_grid(release, slot.period_ns.load(std::memory_order_relaxed), sched_now(mono));
}

void SchedulerImpl::pass_once(const std::vector<std::string>* names) {
  const bool deterministic = config_.deterministic();
  // Nodes added while running (from a tick, say) start here, on the thread that runs them all.
  if (changes_pending_.load(std::memory_order_acquire) && changes_pending_.exchange(false)) {
    start_nodes(unstarted_slots());
  }
  refresh_loop_slots();
  const std::vector<SlotPtr>& slots = loop_slots_;
  if (names != nullptr) check_names(slots, *names, "tick_once");
  // What no recorded reader received reaches its topics by cycle; what a reader received, just
  // before its tick of the same number (service()).
  const std::uint64_t cycle = cycle_.load(std::memory_order_relaxed);
  if (replayer_) replayer_->deliver_before_cycle(cycle);
  std::int64_t mono = monotonic_ns();
  const std::int64_t pass_start = mono;
  for (const SlotPtr& slot : slots) {
    NodeSlot& s = *slot;
    if (!named(names, s.name)) continue;
    if (s.execution_class == ExecutionClass::Event) {
      if (replayer_) replayer_->deliver_ahead_of_tick(s.name);
      if (s.notifier->wait(std::chrono::nanoseconds(0))) service(s, mono, mono);
    } else if (deterministic) {
      release_if_due(s, mono);
    } else {
      service(s, pass_start, mono);
    }
    if (stop_requested_.load(std::memory_order_relaxed)) break;
  }
  cycle_.fetch_add(1, std::memory_order_relaxed);
  if (deterministic) {
    sim_now_ns_ += tick_period_ns_;
    sim_clock_ns_.store(sim_now_ns_, std::memory_order_relaxed);
    // Simulated time outruns the recording thread: the pass waits for the recording instead.
    std::shared_ptr<Recorder> recorder;
    {
      std::lock_guard lock(mutex_);
      recorder = recorder_;
    }
    if (recorder) recorder->drain();
  }
}

void SchedulerImpl::real_loop(std::optional<std::int64_t> duration_ns,
                              const std::vector<std::string>* names) {
  if (stop_requested_.load()) return;
  SignalScope signals(config_.handle_signals(), wake_word_, blackbox_.get(), blackbox_path_);
  if (config_.deterministic()) return simulated_loop(duration_ns, names);
  refresh_loop_slots();
  std::vector<SlotPtr> slots = loop_slots_;
  if (names != nullptr) {
    check_names(slots, *names, "tick_for");
    std::erase_if(slots, [&](const SlotPtr& s) { return !named(names, s->name); });
  }
  // A node added during init() is not started yet: the main loop adopts it at its first cycle.
  std::erase_if(slots, [](const SlotPtr& s) { return !s->init_attempted; });
  LoopPlan plan = plan_loop(slots);
  ThreadGroup threads(shared_from_this());
  auto clock = std::make_shared<LoopClock>();
  start_threads(plan, clock, threads);
  // The clock starts once every thread exists: making one costs milliseconds under rt's mlockall
  // (its whole stack is locked and faulted in, holding the address space's lock that other
  // threads' page faults wait for), which would make the first releases that late.
  const std::int64_t loop_start = monotonic_ns();
  const std::int64_t end =
      duration_ns ? loop_start + *duration_ns : std::numeric_limits<std::int64_t>::max();
  for (const SlotPtr& s : slots) {
    s->next_release_ns = loop_start;
    s->warm_up = true;
  }
  clock->start(end);
  run_main_loop(plan, threads, loop_start, end, names);

  // Teardown: end every thread; one stuck in a node's tick is abandoned after shutdown_timeout.
  wake(wake_word_);
  for (const SlotPtr& s : plan.events) s->notifier->interrupt();
  if (threads.join_until(monotonic_ns() + config_.shutdown_timeout().count()) > 0) {
    log(LogLevel::Error, "a scheduler thread did not finish within the shutdown timeout; detached");
  }
  // Ready for another loop (tick_for may be called again) unless a stop was requested.
  if (!stop_requested_.load()) wake_word_.store(0, std::memory_order_release);
}

void SchedulerImpl::simulated_loop(std::optional<std::int64_t> duration_ns,
                                   const std::vector<std::string>* names) {
  // Simulated time: as fast as possible, on this thread, in order.
  if (names != nullptr) {
    refresh_loop_slots();
    check_names(loop_slots_, *names, "tick_for");
  }
  const std::int64_t end =
      duration_ns ? sim_now_ns_ + *duration_ns : std::numeric_limits<std::int64_t>::max();
  while (!stop_requested_.load() && sim_now_ns_ < end) {
    check_signal();
    if (stop_requested_.load()) break;
    pass_once(names);
  }
}

LoopPlan SchedulerImpl::plan_loop(const std::vector<SlotPtr>& slots) {
  LoopPlan plan;
  plan.main = std::make_shared<Executor>();
  plan.main->label = "main";
  plan.main->main = true;
  std::map<std::tuple<std::int64_t, int, int>, std::shared_ptr<Executor>> rt_groups;
  std::vector<SlotPtr> compute;
  for (const SlotPtr& s : slots) {
    if (s->watchdog_ns.load() > 0) plan.watched.push_back(s);
    switch (s->execution_class) {
      case ExecutionClass::BestEffort:
        plan.main->slots.push_back(s);
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
          plan.executors.push_back(ex);
        }
        ex->slots.push_back(s);
        break;
      }
      case ExecutionClass::Compute:
        compute.push_back(s);
        break;
      case ExecutionClass::Event:
        plan.events.push_back(s);
        break;
      case ExecutionClass::AsyncIo: {
        auto ex = std::make_shared<Executor>();
        ex->label = "io:" + s->name;
        ex->core = s->config.core;
        ex->slots.push_back(s);
        plan.executors.push_back(ex);
        break;
      }
    }
    if (s->config.priority && !config_.rt()) {
      add_degradation("priority " + std::to_string(*s->config.priority) + " of node '" + s->name +
                      "' ignored: rt is off");
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
      plan.executors.push_back(ex);
    }
    std::size_t next = 0;  // round robin over the workers
    for (auto& slot : compute) {
      pool[next]->slots.push_back(slot);
      next = next + 1 == workers ? 0 : next + 1;
    }
  }
  return plan;
}

void LoopClock::start(std::int64_t end) noexcept {
  end_ns = end;
  started.store(true, std::memory_order_release);
  started.notify_all();
}

std::int64_t LoopClock::wait() const noexcept {
  started.wait(false, std::memory_order_acquire);
  return end_ns;
}

void SchedulerImpl::start_threads(const LoopPlan& plan, const std::shared_ptr<LoopClock>& clock,
                                  ThreadGroup& threads) {
  try {
    for (const auto& ex : plan.executors) {
      threads.spawn([this, ex, clock] {
        apply_thread_settings(*ex);
        run_executor(*ex, clock->wait());
      });
    }
    for (const SlotPtr& s : plan.events) spawn_event(s, clock, threads);
    if (!plan.watched.empty()) {
      threads.spawn(
          [this, watched = plan.watched, clock] { run_watchdog(watched, clock->wait()); });
    }
    if (telemetry_) threads.spawn([this, clock] { run_telemetry(clock->wait()); });
    if (presence_) threads.spawn([this, clock] { run_presence(clock->wait()); });
  } catch (...) {
    threads.unblock_signals();
    request_stop("could not start the scheduler's threads", true);
    clock->start(monotonic_ns());
    threads.join_until(std::numeric_limits<std::int64_t>::max());
    throw;
  }
  threads.unblock_signals();
}

void SchedulerImpl::spawn_event(const SlotPtr& slot, const std::shared_ptr<LoopClock>& clock,
                                ThreadGroup& threads) {
  threads.spawn([this, slot, clock] {
    Executor ex;
    ex.label = "event:" + slot->name;
    ex.core = slot->config.core;
    apply_thread_settings(ex);
    run_event(*slot, clock->wait());
  });
}

void SchedulerImpl::adopt_changes(LoopPlan& plan, ThreadGroup& threads, std::int64_t end,
                                  const std::vector<std::string>* names) {
  const std::vector<SlotPtr> fresh = unstarted_slots();
  start_nodes(fresh);
  std::vector<SlotPtr> watched;
  {
    std::lock_guard lock(mutex_);
    watched.swap(newly_critical_);
  }
  auto clock = std::make_shared<LoopClock>();
  clock->start(end);
  const std::int64_t now = monotonic_ns();
  for (const SlotPtr& s : fresh) {
    if (!s->init_attempted || !named(names, s->name)) continue;
    s->next_release_ns = now;
    s->warm_up = true;
    if (s->watchdog_ns.load() > 0 &&
        std::find(watched.begin(), watched.end(), s) == watched.end()) {
      watched.push_back(s);
    }
    switch (s->execution_class) {
      case ExecutionClass::BestEffort: {
        // In execution order among the main loop's nodes, which only this thread reads.
        auto& main = plan.main->slots;
        const auto before = [](const SlotPtr& a, const SlotPtr& b) {
          return std::tie(a->config.order, a->registration) <
                 std::tie(b->config.order, b->registration);
        };
        main.insert(std::upper_bound(main.begin(), main.end(), s, before), s);
        break;
      }
      case ExecutionClass::Event:
        plan.events.push_back(s);
        spawn_event(s, clock, threads);
        break;
      default: {
        // A thread of its own: an Rt group's or the compute pool's thread reads its node list
        // without a lock, so it cannot take one more.
        auto ex = std::make_shared<Executor>();
        ex->label = std::string(to_string(s->execution_class)) + ":" + s->name;
        ex->realtime = s->execution_class == ExecutionClass::Rt;
        ex->priority = s->config.priority;
        ex->core = s->config.core;
        ex->slots.push_back(s);
        threads.spawn([this, ex, end] {
          apply_thread_settings(*ex);
          run_executor(*ex, end);
        });
        break;
      }
    }
  }
  if (!watched.empty()) threads.spawn([this, watched, end] { run_watchdog(watched, end); });
}

void SchedulerImpl::run_main_loop(LoopPlan& plan, ThreadGroup& threads, std::int64_t loop_start,
                                  std::int64_t end, const std::vector<std::string>* names) {
  // BestEffort nodes on the scheduler's tick grid, on the thread that called run().
  const Executor& main = *plan.main;
  cpu_set_t previous_affinity;
  const bool pinned =
      !config_.cores().empty() &&
      pthread_getaffinity_np(pthread_self(), sizeof(previous_affinity), &previous_affinity) == 0;
  if (pinned) apply_thread_settings(main);
  std::int64_t next_cycle = loop_start;
  for (;;) {
    const bool on_time = sleep_until(std::min(next_cycle, end), &main.slots);
    check_signal();
    if (!on_time || stop_requested_.load()) break;
    std::int64_t mono = monotonic_ns();
    if (mono >= end) break;
    if (changes_pending_.load(std::memory_order_acquire) && changes_pending_.exchange(false)) {
      try {
        adopt_changes(plan, threads, end, names);
      } catch (const std::exception& e) {
        request_stop(std::string("could not start a node added while running: ") + e.what(), true);
        break;
      }
      mono = monotonic_ns();
    }
    cycle_.fetch_add(1, std::memory_order_relaxed);
    for (const SlotPtr& slot : main.slots) release_if_due(*slot, mono);
    next_cycle = next_on_grid(next_cycle, tick_period_ns_, mono);
  }
  if (pinned) pthread_setaffinity_np(pthread_self(), sizeof(previous_affinity), &previous_affinity);
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
    } else if (ex.realtime && config_.rt() && !capabilities_.isolated_cpus.empty()) {
      for (const int c : capabilities_.isolated_cpus) CPU_SET(static_cast<unsigned>(c), &cpus);
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
  while (!loop_ending()) {
    std::int64_t earliest = end;
    for (const SlotPtr& s : ex.slots) earliest = std::min(earliest, s->next_release_ns);
    if (!sleep_until(earliest, &ex.slots)) break;
    std::int64_t mono = monotonic_ns();
    if (mono >= end) break;
    for (const SlotPtr& slot : ex.slots) release_if_due(*slot, mono);
  }
}

void SchedulerImpl::run_event(NodeSlot& slot, std::int64_t end) noexcept {
  while (!loop_ending()) {
    const std::int64_t now = monotonic_ns();
    if (now >= end) break;
    const std::int64_t slice = std::min(end - now, kEventWaitSliceNs);
    if (slot.params) slot.params->idle();
    const bool arrived = slot.notifier->wait(std::chrono::nanoseconds(slice));
    if (slot.params) slot.params->hold();
    deliver_params(slot);
    if (arrived && !loop_ending()) {
      std::int64_t mono = monotonic_ns();
      service(slot, mono, mono);
    }
  }
}

}  // namespace horus::detail
