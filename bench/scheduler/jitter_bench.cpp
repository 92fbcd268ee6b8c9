// Release jitter of a 1 kHz node: lateness of each tick's start behind its release on the grid
// (p50/p99/max, from horus::lateness()), with and without a busy neighbour, against a bare
// clock_nanosleep loop measured in the same run under the same conditions. Also the run loop's own
// cost per node tick.
//
//   sched_jitter_bench [seconds per measurement, default 10]
#include <time.h>

#include <pthread.h>
#include <sched.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "horus/clock.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

constexpr std::int64_t kPeriodNs = 1'000'000;  // 1 kHz

std::int64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct Stats {
  std::size_t samples = 0;
  double p50_us = 0, p99_us = 0, max_us = 0;
};

Stats summarise(std::vector<std::int64_t> lateness) {
  Stats s;
  if (lateness.empty()) return s;
  std::sort(lateness.begin(), lateness.end());
  const auto at = [&](double q) {
    return static_cast<double>(
               lateness[static_cast<std::size_t>(q * static_cast<double>(lateness.size() - 1))]) /
           1e3;
  };
  s.samples = lateness.size();
  s.p50_us = at(0.50);
  s.p99_us = at(0.99);
  s.max_us = static_cast<double>(lateness.back()) / 1e3;
  return s;
}

// The reference: what the OS gives a plain absolute-sleep loop, on its own thread with the same
// SCHED_FIFO priority the scheduler's Rt thread asks for (when the machine allows it).
std::vector<std::int64_t> bare_loop(double seconds, bool& fifo) {
  std::vector<std::int64_t> lateness;
  lateness.reserve(static_cast<std::size_t>(seconds * 1000) + 16);
  std::thread worker([&] {
    sched_param param{};
    param.sched_priority = 50;
    fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
    const std::int64_t start = mono_ns() + kPeriodNs;
    const std::int64_t end = start + static_cast<std::int64_t>(seconds * 1e9);
    for (std::int64_t release = start; release < end; release += kPeriodNs) {
      timespec ts{static_cast<time_t>(release / 1'000'000'000),
                  static_cast<long>(release % 1'000'000'000)};
      while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
      }
      lateness.push_back(mono_ns() - release);
    }
  });
  worker.join();
  return lateness;
}

// A 1 kHz node that records how late each tick started after its release.
class Stamp : public horus::Node {
 public:
  explicit Stamp(std::size_t expected) { lateness.reserve(expected); }
  std::string_view name() const override { return "motor"; }
  void tick() override { lateness.push_back(horus::lateness().count()); }
  std::vector<std::int64_t> lateness;
};

// Burns CPU for 45 ms of every 50 ms: the planner of the demo robot.
class Busy : public horus::Node {
 public:
  std::string_view name() const override { return "busy_planner"; }
  void tick() override {
    const std::int64_t until = mono_ns() + 45'000'000;
    while (mono_ns() < until) {
    }
  }
};

std::vector<std::int64_t> scheduler_loop(double seconds, bool busy_neighbour) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).rt(true).name("jitter")};
  auto stamp = std::make_unique<Stamp>(static_cast<std::size_t>(seconds * 1000) + 16);
  Stamp* raw = stamp.get();
  sched.add(std::move(stamp)).order(0).rate(1000_hz).build();
  if (busy_neighbour) sched.add(std::make_unique<Busy>()).order(50).rate(20_hz).compute().build();
  sched.run_for(std::chrono::nanoseconds(static_cast<std::int64_t>(seconds * 1e9)));
  return raw->lateness;
}

class BusyThread {
 public:
  BusyThread()
      : thread_([this] {
          while (!stop_.load()) {
            const std::int64_t until = mono_ns() + 45'000'000;
            while (mono_ns() < until && !stop_.load()) {
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
          }
        }) {}
  ~BusyThread() {
    stop_ = true;
    thread_.join();
  }

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

void row(const char* what, const Stats& s) {
  std::printf("| %-44s | %8zu | %8.1f | %8.1f | %9.1f |\n", what, s.samples, s.p50_us, s.p99_us,
              s.max_us);
}

// The run loop (not tick_once): N trivial nodes on the main loop at a rate it can never keep,
// so it never sleeps; time per cycle / N is the scheduler's cost per node tick in production.
class Trivial : public horus::Node {
 public:
  explicit Trivial(int i) {
    char name[16];
    std::snprintf(name, sizeof(name), "n%d", i);
    name_ = name;
  }
  std::string_view name() const override { return name_; }
  void tick() override { ++count_; }
  std::uint64_t count_ = 0;

 private:
  std::string name_;
};

void run_loop_overhead() {
  std::printf(
      "\n| run loop, trivial BestEffort nodes | cycles/s | ns per node tick |\n|---|---:|---:|\n");
  for (const int n : {1, 10, 100}) {
    horus::Scheduler sched{
        horus::SchedulerConfig{}.tick_rate(horus::Rate::hz(1e9)).max_deadline_misses(std::nullopt)};
    for (int i = 0; i < n; ++i) sched.add(std::make_unique<Trivial>(i)).build();
    const std::int64_t start = mono_ns();
    sched.run_for(std::chrono::milliseconds(500));
    const double seconds = static_cast<double>(mono_ns() - start) / 1e9;
    const double cycles = static_cast<double>(sched.current_tick());
    std::printf("| %d node%s | %.0f | %.1f |\n", n, n == 1 ? "" : "s", cycles / seconds,
                seconds * 1e9 / cycles / n);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 10.0;
  if (seconds <= 0) {
    std::fprintf(stderr, "usage: sched_jitter_bench [seconds > 0]\n");
    return 2;
  }
  {
    horus::Scheduler probe{horus::SchedulerConfig{}.rt(true)};
    std::printf("RT: %s\n", probe.has_full_rt() ? "full" : "degraded");
    for (const auto& d : probe.degradations()) std::printf("  - %s\n", d.c_str());
  }
  std::printf("\n1 kHz release lateness over %.0f s per row (microseconds)\n\n", seconds);
  std::printf("| %-44s | %8s | %8s | %8s | %9s |\n|---|---:|---:|---:|---:|\n", "loop", "ticks",
              "p50", "p99", "max");
  bool fifo = false;
  row("bare clock_nanosleep loop, quiet", summarise(bare_loop(seconds, fifo)));
  row("scheduler Rt node, quiet", summarise(scheduler_loop(seconds, false)));
  {
    BusyThread busy;
    row("bare clock_nanosleep loop, busy neighbour", summarise(bare_loop(seconds, fifo)));
  }
  row("scheduler Rt node, busy compute neighbour", summarise(scheduler_loop(seconds, true)));
  std::printf("\nBoth the bare loop and the scheduler's Rt thread ran %s.\n",
              fifo ? "under SCHED_FIFO 50" : "under SCHED_OTHER (SCHED_FIFO not permitted)");
  std::printf(
      "Lateness: tick start (horus::lateness()) or wake-up (bare loop) minus the release.\n");
  run_loop_overhead();
  return 0;
}
