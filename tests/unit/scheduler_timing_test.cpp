// Rates, release grids, budgets, deadlines and miss policies. Rate limiting is checked in
// simulated time; misses are provoked with ticks that sleep far past a tiny deadline, so the
// outcome never depends on how fast or loaded the machine is.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "horus/clock.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;
using std::chrono::milliseconds;

namespace {

class Probe : public horus::Node {
 public:
  explicit Probe(std::string name) : name_(std::move(name)) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    ticks.push_back(std::chrono::duration_cast<milliseconds>(horus::elapsed()).count());
    remaining = horus::budget_remaining();
    late = horus::lateness();
    if (sleep.count() > 0) std::this_thread::sleep_for(sleep);
  }
  bool is_safe_state() const override { return safe.load(); }
  void enter_safe_state() override { ++safe_entries; }

  std::vector<long> ticks;
  std::chrono::nanoseconds sleep{0};
  std::chrono::nanoseconds remaining{0};
  std::chrono::nanoseconds late{-1};
  std::atomic<bool> safe{true};
  int safe_entries = 0;

 private:
  std::string name_;
};

struct Added {
  Probe* node;
  horus::NodeBuilder builder;
};

Added add(horus::Scheduler& sched, const std::string& name) {
  auto node = std::make_unique<Probe>(name);
  Probe* raw = node.get();
  return {raw, sched.add(std::move(node))};
}

}  // namespace

TEST(SchedulerTiming, PerNodeRatesOnAFixedGridInSimulatedTime) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).deterministic(true)};
  auto fast = add(sched, "fast");
  fast.builder.rate(100_hz).build();
  auto slow = add(sched, "slow");
  slow.builder.rate(10_hz).build();
  auto odd = add(sched, "odd");
  odd.builder.rate(25_hz).build();
  auto every = add(sched, "every_cycle");
  every.builder.build();
  EXPECT_EQ(sched.run_for(1_s), 0);
  EXPECT_EQ(fast.node->ticks.size(), 100U);
  EXPECT_EQ(slow.node->ticks, (std::vector<long>{0, 100, 200, 300, 400, 500, 600, 700, 800, 900}));
  EXPECT_EQ(odd.node->ticks.size(), 25U);
  EXPECT_EQ(odd.node->ticks[1], 40);
  EXPECT_EQ(odd.node->ticks[24], 960);
  EXPECT_EQ(every.node->ticks.size(), 100U);
  EXPECT_EQ(sched.current_tick(), 100U);
}

TEST(SchedulerTiming, SetNodeRateTakesEffectOnTheNextRelease) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).deterministic(true)};
  auto sensor = add(sched, "sensor");
  sensor.builder.rate(50_hz).build();
  sched.tick_for(100_ms);
  EXPECT_EQ(sensor.node->ticks, (std::vector<long>{0, 20, 40, 60, 80}));
  sched.set_node_rate("sensor", 10_hz);
  sched.tick_for(200_ms);
  EXPECT_EQ(sensor.node->ticks, (std::vector<long>{0, 20, 40, 60, 80, 100, 200}));
}

TEST(SchedulerTiming, WarnCountsMissesAndBudgetOverruns) {
  horus::Scheduler sched;
  auto motor = add(sched, "motor");
  motor.node->sleep = 3_ms;
  motor.builder.rate(1000_hz).budget(50_us).deadline(100_us).build();
  sched.tick_once();
  sched.tick_once();
  const auto m = sched.node_metrics("motor");
  EXPECT_EQ(m->total_ticks, 2U);
  EXPECT_EQ(m->deadline_misses, 2U);
  EXPECT_EQ(m->budget_overruns, 2U);
  EXPECT_EQ(m->warnings_count, 2U);
  EXPECT_GE(m->max_tick_duration, 3_ms);
  const auto stats = sched.safety_stats();
  EXPECT_EQ(stats.deadline_misses, 2U);
  EXPECT_EQ(stats.budget_overruns, 2U);
  EXPECT_EQ(sched.stop_reason(), "");
}

TEST(SchedulerTiming, DeadlineCountsFromTheReleaseNotFromTheTickStart) {
  horus::Scheduler sched;
  auto slow = add(sched, "slow_neighbour");
  slow.node->sleep = 3_ms;
  slow.builder.order(0).build();
  auto quick = add(sched, "quick");
  quick.builder.order(1).rate(1000_hz).deadline(1_ms).build();
  sched.tick_once();
  // quick's own tick is short, but it was released with the cycle, 3 ms before it ran.
  EXPECT_GE(quick.node->late, 3_ms);
  EXPECT_EQ(sched.node_metrics("quick")->deadline_misses, 1U);
  EXPECT_EQ(sched.node_metrics("quick")->budget_overruns, 0U);
}

TEST(SchedulerTiming, SkipDropsTheNextRelease) {
  horus::Scheduler sched;
  auto motor = add(sched, "motor");
  motor.node->sleep = 2_ms;
  motor.builder.rate(1000_hz).deadline(100_us).on_miss(horus::Miss::Skip).build();
  for (int i = 0; i < 4; ++i) sched.tick_once();
  const auto m = sched.node_metrics("motor");
  EXPECT_EQ(m->total_ticks, 2U);
  EXPECT_EQ(m->skipped_ticks, 2U);
}

TEST(SchedulerTiming, SafeModeEntersSafeStateAndRecoversWhenSafe) {
  horus::Scheduler sched;
  auto motor = add(sched, "motor");
  motor.node->sleep = 2_ms;
  motor.node->safe = false;
  motor.builder.rate(1000_hz).deadline(100_us).on_miss(horus::Miss::SafeMode).build();
  sched.tick_once();
  EXPECT_EQ(motor.node->safe_entries, 1);
  EXPECT_EQ(sched.node_info("motor")->health, horus::NodeHealthState::Isolated);
  sched.tick_once();
  EXPECT_EQ(motor.node->ticks.size(), 1U) << "an Isolated node does not tick while unsafe";
  motor.node->safe = true;
  motor.node->sleep = 0_ms;
  sched.tick_once();
  EXPECT_EQ(motor.node->ticks.size(), 2U);
  EXPECT_EQ(sched.node_info("motor")->health, horus::NodeHealthState::Healthy);
}

TEST(SchedulerTiming, StopPolicyStopsTheScheduler) {
  horus::Scheduler sched;
  auto safety = add(sched, "safety");
  safety.node->sleep = 2_ms;
  safety.builder.rate(1000_hz).deadline(100_us).on_miss(horus::Miss::Stop).build();
  sched.tick_once();
  EXPECT_EQ(sched.stop_reason(), "node 'safety' missed its deadline (Miss::Stop)");
  sched.tick_once();
  EXPECT_EQ(safety.node->ticks.size(), 1U) << "no tick after a stop";
  EXPECT_EQ(sched.run(), 1);
}

TEST(SchedulerTiming, MaxDeadlineMissesStopsAfterTheThresholdNamingNodesCountsAndSettings) {
  horus::Scheduler sched{horus::SchedulerConfig{}.max_deadline_misses(5)};
  auto a = add(sched, "a");
  a.node->sleep = 1_ms;
  a.builder.order(1).rate(1000_hz).deadline(50_us).build();
  auto b = add(sched, "b");
  b.node->sleep = 1_ms;
  b.builder.order(2).rate(1000_hz).deadline(50_us).build();
  sched.tick_once();
  sched.tick_once();
  EXPECT_EQ(sched.stop_reason(), "");
  sched.tick_once();
  const std::string reason = sched.stop_reason();
  EXPECT_EQ(
      reason.rfind("max_deadline_misses (5) reached: deadline misses by node 'a' 3, 'b' 2", 0), 0U)
      << reason;
  EXPECT_NE(reason.find("95 % of its period unless deadline() sets it"), std::string::npos)
      << reason;
  EXPECT_NE(reason.find("max_deadline_misses(std::nullopt)"), std::string::npos) << reason;
  EXPECT_EQ(sched.run(), 1) << "a stop by the miss limit is a failure";
}

TEST(SchedulerTiming, NoMissLimitNeverStops) {
  horus::Scheduler sched{horus::SchedulerConfig{}.max_deadline_misses(std::nullopt)};
  auto a = add(sched, "a");
  a.node->sleep = 1_ms;
  a.builder.rate(1000_hz).deadline(50_us).build();
  for (int i = 0; i < 3; ++i) sched.tick_once();
  EXPECT_EQ(sched.node_metrics("a")->deadline_misses, 3U);
  EXPECT_EQ(sched.stop_reason(), "");
}

TEST(SchedulerTiming, BudgetRemainingInsideTheTick) {
  horus::Scheduler sched;
  auto budgeted = add(sched, "budgeted");
  budgeted.builder.rate(1_hz).budget(1_s).build();
  auto free = add(sched, "free");
  free.builder.build();
  sched.tick_once();
  EXPECT_LE(budgeted.node->remaining, 1_s);
  EXPECT_GT(budgeted.node->remaining, 0_ms);
  EXPECT_EQ(free.node->remaining, std::chrono::nanoseconds::max());

  horus::Scheduler det{horus::SchedulerConfig{}.deterministic(true)};
  auto simulated = add(det, "simulated");
  simulated.builder.rate(100_hz).build();
  det.tick_once();
  EXPECT_EQ(simulated.node->remaining, 8_ms) << "80 % of the period, simulated time stands still";
}

TEST(SchedulerTiming, RealRunTicksEveryClass) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(200_hz)};
  auto main_node = add(sched, "main");
  main_node.builder.build();
  auto rt = add(sched, "rt");
  rt.builder.rate(500_hz).build();
  auto compute = add(sched, "compute");
  compute.builder.rate(100_hz).compute().build();
  auto io = add(sched, "io");
  io.builder.rate(50_hz).async_io().build();
  EXPECT_EQ(sched.run_for(100_ms), 0);
  for (const char* name : {"main", "rt", "compute", "io"}) {
    EXPECT_GE(sched.node_metrics(name)->total_ticks, 1U) << name;
    EXPECT_EQ(sched.node_info(name)->state, horus::NodeState::Stopped) << name;
  }
  EXPECT_GE(sched.current_tick(), 1U);
  EXPECT_EQ(sched.status(), horus::SchedulerStatus::Stopped);
}

TEST(SchedulerTiming, StopFromAnotherThreadEndsRun) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz)};
  auto slow = add(sched, "slow");
  slow.builder.rate(1_hz).build();  // its thread sleeps ~1 s between releases: stop must cut it
  std::thread stopper([&] {
    while (!sched.is_running()) std::this_thread::sleep_for(1_ms);
    std::this_thread::sleep_for(20_ms);
    sched.stop();
  });
  EXPECT_EQ(sched.run(), 0);
  stopper.join();
  EXPECT_EQ(sched.stop_reason(), "stop() called");
  EXPECT_EQ(slow.node->ticks.size(), 1U);
}
