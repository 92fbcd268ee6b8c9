// The loops: the release grid, the executors' threads, and the main, simulated and single-pass
// loops that run nodes on them.
#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <limits>
#include <map>
#include <thread>
#include <tuple>

#include "horus/detail/errno_text.hpp"
#include "horus/error.hpp"
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
    sigset_t blocked;
    sigemptyset(&blocked);
    sigaddset(&blocked, SIGINT);
    sigaddset(&blocked, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &blocked, &previous_mask_);
  }
  ~ThreadGroup() { unblock_signals(); }
  ThreadGroup(const ThreadGroup&) = delete;
  ThreadGroup& operator=(const ThreadGroup&) = delete;

  template <class Body>
  void spawn(Body body) {
    auto exited = std::make_shared<std::atomic<bool>>(false);
    threads_.push_back({std::thread([body, exited, keep = keep_alive_] {
                          body();
                          exited->store(true, std::memory_order_release);
                        }),
                        exited});
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
  std::shared_ptr<void> keep_alive_;
  std::vector<Running> threads_;
  sigset_t previous_mask_{};
  bool blocking_ = true;
};

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

void SchedulerImpl::release_if_due(NodeSlot& slot, std::int64_t& mono) noexcept {
  if (slot.next_release_ns > sched_now(mono)) return;
  const std::int64_t release = slot.next_release_ns;
  service(slot, release, mono);
  slot.next_release_ns =
      next_on_grid(release, slot.period_ns.load(std::memory_order_relaxed), sched_now(mono));
}

void SchedulerImpl::pass_once(const std::vector<std::string>* names) {
  const bool deterministic = config_.deterministic();
  refresh_loop_slots();
  const std::vector<SlotPtr>& slots = loop_slots_;
  if (names != nullptr) check_names(slots, *names, "tick_once");
  // What the recording received before this cycle began reaches its topics first, and what a
  // node of this name first received in this cycle, just before its tick.
  const std::uint64_t cycle = cycle_.load(std::memory_order_relaxed);
  if (replayer_) replayer_->deliver_before_cycle(cycle);
  std::int64_t mono = monotonic_ns();
  const std::int64_t pass_start = mono;
  for (const SlotPtr& slot : slots) {
    NodeSlot& s = *slot;
    if (!named(names, s.name)) continue;
    if (replayer_) replayer_->deliver_before_tick(cycle, s.name);
    if (s.execution_class == ExecutionClass::Event) {
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
  const std::int64_t loop_start = monotonic_ns();
  const std::int64_t end =
      duration_ns ? loop_start + *duration_ns : std::numeric_limits<std::int64_t>::max();
  const LoopPlan plan = plan_loop(slots, loop_start);

  ThreadGroup threads(shared_from_this());
  start_threads(plan, end, threads);
  run_main_loop(*plan.main, loop_start, end);

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

LoopPlan SchedulerImpl::plan_loop(const std::vector<SlotPtr>& slots, std::int64_t loop_start) {
  LoopPlan plan;
  plan.main = std::make_shared<Executor>();
  plan.main->label = "main";
  plan.main->main = true;
  std::map<std::tuple<std::int64_t, int, int>, std::shared_ptr<Executor>> rt_groups;
  std::vector<SlotPtr> compute;
  for (const SlotPtr& s : slots) {
    s->next_release_ns = loop_start;
    if (s->watchdog_ns > 0) plan.watched.push_back(s);
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

void SchedulerImpl::start_threads(const LoopPlan& plan, std::int64_t end, ThreadGroup& threads) {
  try {
    for (const auto& ex : plan.executors) {
      threads.spawn([this, ex, end] { run_executor(*ex, end); });
    }
    for (const SlotPtr& s : plan.events) {
      threads.spawn([this, s, end] {
        Executor ex;
        ex.label = "event:" + s->name;
        ex.core = s->config.core;
        apply_thread_settings(ex);
        run_event(*s, end);
      });
    }
    if (!plan.watched.empty()) {
      threads.spawn([this, watched = plan.watched, end] { run_watchdog(watched, end); });
    }
    if (telemetry_) threads.spawn([this, end] { run_telemetry(end); });
    if (presence_) threads.spawn([this, end] { run_presence(end); });
  } catch (...) {
    threads.unblock_signals();
    request_stop("could not start the scheduler's threads", true);
    threads.join_until(std::numeric_limits<std::int64_t>::max());
    throw;
  }
  threads.unblock_signals();
}

void SchedulerImpl::run_main_loop(const Executor& main, std::int64_t loop_start, std::int64_t end) {
  // BestEffort nodes on the scheduler's tick grid, on the thread that called run().
  cpu_set_t previous_affinity;
  const bool pinned =
      !config_.cores().empty() &&
      pthread_getaffinity_np(pthread_self(), sizeof(previous_affinity), &previous_affinity) == 0;
  if (pinned) apply_thread_settings(main);
  std::int64_t next_cycle = loop_start;
  for (;;) {
    const bool on_time = sleep_until(std::min(next_cycle, end));
    check_signal();
    if (!on_time || stop_requested_.load()) break;
    std::int64_t mono = monotonic_ns();
    if (mono >= end) break;
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
  apply_thread_settings(ex);
  while (!loop_ending()) {
    std::int64_t earliest = end;
    for (const SlotPtr& s : ex.slots) earliest = std::min(earliest, s->next_release_ns);
    if (!sleep_until(earliest)) break;
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
    if (slot.notifier->wait(std::chrono::nanoseconds(slice)) && !loop_ending()) {
      std::int64_t mono = monotonic_ns();
      service(slot, mono, mono);
    }
  }
}

}  // namespace horus::detail
