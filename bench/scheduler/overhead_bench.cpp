// Scheduler overhead per node tick: N trivial nodes ticked by the scheduler, against a plain loop
// calling the same virtual tick() on the same objects. Goal: <= 100 ns per node.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

class Trivial : public horus::Node {
 public:
  explicit Trivial(int i) {
    char name[16];
    std::snprintf(name, sizeof(name), "n%d", i);
    name_ = name;
  }
  std::string_view name() const override { return name_; }
  void tick() override { benchmark::DoNotOptimize(++count_); }

 private:
  std::string name_;
  std::uint64_t count_ = 0;
};

void per_node_counter(benchmark::State& state) {
  state.counters["per_node"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * static_cast<double>(state.range(0)),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_PlainLoop(benchmark::State& state) {
  std::vector<std::unique_ptr<horus::Node>> nodes;
  for (int i = 0; i < state.range(0); ++i) nodes.push_back(std::make_unique<Trivial>(i));
  for (auto _ : state) {
    for (auto& n : nodes) n->tick();
  }
  per_node_counter(state);
}

// BestEffort nodes: lifecycle, failure and health checks, tick timing and metrics.
void BM_SchedulerTickOnce(benchmark::State& state) {
  horus::Scheduler sched{horus::SchedulerConfig{}.handle_signals(false)};
  for (int i = 0; i < state.range(0); ++i) sched.add(std::make_unique<Trivial>(i)).build();
  sched.tick_once();
  for (auto _ : state) sched.tick_once();
  per_node_counter(state);
}

// Rt nodes: the same plus budget, deadline and watchdog checks on every tick.
void BM_SchedulerTickOnceTimed(benchmark::State& state) {
  // A 1 Hz rate gives a 950 ms deadline: preemption of the benchmark never turns into misses.
  horus::Scheduler sched{horus::SchedulerConfig{}.handle_signals(false).watchdog(1_s)};
  for (int i = 0; i < state.range(0); ++i) {
    sched.add(std::make_unique<Trivial>(i)).rate(1_hz).build();
  }
  sched.tick_once();
  for (auto _ : state) sched.tick_once();
  per_node_counter(state);
}

}  // namespace

BENCHMARK(BM_PlainLoop)->Arg(1)->Arg(10)->Arg(100);
BENCHMARK(BM_SchedulerTickOnce)->Arg(1)->Arg(10)->Arg(100);
BENCHMARK(BM_SchedulerTickOnceTimed)->Arg(1)->Arg(10)->Arg(100);
BENCHMARK_MAIN();
