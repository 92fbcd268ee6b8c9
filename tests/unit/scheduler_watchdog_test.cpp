// The graduated watchdog: Warning at 1x, Unhealthy (skipped, then probation) at 2x, Isolated at 3x
// for critical nodes with enter_safe_state and a system-wide safe state; a frozen node is isolated
// while the others keep ticking. Slow ticks sleep far beyond the thresholds, so no outcome depends
// on the machine's speed.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "horus/blackbox.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;
using horus::NodeHealthState;

namespace {

class Sleepy : public horus::Node {
 public:
  explicit Sleepy(std::string name) : name_(std::move(name)) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    ticks.fetch_add(1);
    if (sleep.count() > 0) std::this_thread::sleep_for(sleep);
    while (frozen.load()) std::this_thread::sleep_for(1_ms);
  }
  void enter_safe_state() override {
    safe_entries.fetch_add(1);
    safe_entry_while_frozen = frozen.load();
  }

  std::chrono::nanoseconds sleep{0};
  std::atomic<bool> frozen{false};
  std::atomic<int> ticks{0};
  std::atomic<int> safe_entries{0};
  std::atomic<bool> safe_entry_while_frozen{false};

 private:
  std::string name_;
};

Sleepy* add(horus::Scheduler& sched, const std::string& name) {
  auto node = std::make_unique<Sleepy>(name);
  Sleepy* raw = node.get();
  sched.add(std::move(node)).build();
  return raw;
}

bool wait_for(const std::function<bool()>& condition, std::chrono::milliseconds limit = 5000_ms) {
  const auto give_up = std::chrono::steady_clock::now() + limit;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::sleep_for(1_ms);
  }
  return true;
}

}  // namespace

TEST(SchedulerWatchdog, OneTimeoutIsAWarningThatClearsOnAGoodTick) {
  horus::Scheduler sched{horus::SchedulerConfig{}.watchdog(20_ms)};
  Sleepy* node = add(sched, "slow");
  node->sleep = 25_ms;
  sched.tick_once();
  EXPECT_EQ(sched.node_info("slow")->health, NodeHealthState::Warning);
  EXPECT_EQ(sched.safety_stats().watchdog_expirations, 1U);
  node->sleep = 0_ms;
  sched.tick_once();
  EXPECT_EQ(sched.node_info("slow")->health, NodeHealthState::Healthy);
  EXPECT_EQ(node->ticks.load(), 2);
}

TEST(SchedulerWatchdog, TwoTimeoutsMakeItUnhealthySkippedThenOnProbation) {
  horus::Scheduler sched{horus::SchedulerConfig{}.watchdog(100_ms)};
  Sleepy* node = add(sched, "slow");
  node->sleep = 210_ms;
  sched.tick_once();
  EXPECT_EQ(sched.node_info("slow")->health, NodeHealthState::Unhealthy);
  node->sleep = 0_ms;
  sched.tick_once();  // within the rest period (one timeout after the slow tick ended)
  EXPECT_EQ(node->ticks.load(), 1) << "an Unhealthy node is skipped";
  EXPECT_EQ(sched.node_metrics("slow")->skipped_ticks, 1U);
  std::this_thread::sleep_for(110_ms);
  sched.tick_once();
  EXPECT_EQ(node->ticks.load(), 2) << "after resting it is ticked on probation";
  EXPECT_EQ(sched.node_info("slow")->health, NodeHealthState::Healthy);
}

TEST(SchedulerWatchdog, NonCriticalNodeIsNeverIsolated) {
  horus::Scheduler sched{horus::SchedulerConfig{}.watchdog(10_ms)};
  Sleepy* node = add(sched, "slow");
  node->sleep = 40_ms;
  sched.tick_once();
  EXPECT_EQ(sched.node_info("slow")->health, NodeHealthState::Unhealthy);
  EXPECT_EQ(node->safe_entries.load(), 0);
}

TEST(SchedulerWatchdog, CriticalNodePastThreeTimeoutsIsIsolatedAndEveryoneGoesSafe) {
  horus::Scheduler sched;
  Sleepy* motor = add(sched, "motor");
  Sleepy* lidar = add(sched, "lidar");
  sched.add_critical_node("motor", 10_ms);
  motor->sleep = 40_ms;
  sched.tick_once();
  EXPECT_EQ(sched.node_info("motor")->health, NodeHealthState::Isolated);
  EXPECT_EQ(motor->safe_entries.load(), 1) << "enter_safe_state right after the frozen tick";
  EXPECT_EQ(lidar->safe_entries.load(), 1) << "the others at their next release";
  EXPECT_EQ(lidar->ticks.load(), 1) << "and, being safe, they keep ticking";
  motor->sleep = 0_ms;
  sched.tick_once();
  EXPECT_EQ(lidar->safe_entries.load(), 1);
  // Default is_safe_state() is true: both recover and tick again.
  EXPECT_EQ(motor->ticks.load(), 2);
  EXPECT_EQ(lidar->ticks.load(), 2);
  EXPECT_EQ(sched.node_info("motor")->health, NodeHealthState::Healthy);
}

TEST(SchedulerWatchdog, FrozenNodeIsIsolatedWhileTheOthersKeepTicking) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(100_hz).blackbox_mb(1)};
  // Rt nodes of different rates get different threads; logger is on the main loop.
  auto add_rt = [&](const std::string& name, horus::Rate rate) {
    auto node = std::make_unique<Sleepy>(name);
    Sleepy* raw = node.get();
    sched.add(std::move(node)).rate(rate).build();
    return raw;
  };
  Sleepy* frozen = add_rt("frozen", 100_hz);
  Sleepy* steady = add_rt("steady", 200_hz);
  Sleepy* logger = add(sched, "logger");
  sched.add_critical_node("frozen", 30_ms);
  frozen->frozen = true;

  std::thread runner([&] { sched.run(); });
  const bool isolated =
      wait_for([&] { return sched.node_info("frozen")->health == NodeHealthState::Isolated; });
  EXPECT_TRUE(isolated) << "the watchdog never isolated the frozen node";
  const int steady_then = steady->ticks.load();
  const int logger_then = logger->ticks.load();
  EXPECT_TRUE(wait_for([&] { return steady->ticks.load() >= steady_then + 10; }))
      << "the Rt neighbour stopped ticking";
  EXPECT_TRUE(wait_for([&] { return logger->ticks.load() >= logger_then + 5; }))
      << "the main loop stopped ticking";
  EXPECT_EQ(frozen->ticks.load(), 1);
  EXPECT_EQ(frozen->safe_entries.load(), 0) << "never called while its tick is still running";
  EXPECT_EQ(steady->safe_entries.load(), 1) << "a frozen critical node puts everyone in safe state";
  EXPECT_EQ(sched.node_info("steady")->health, NodeHealthState::Healthy) << "and they recover";

  frozen->frozen = false;
  EXPECT_TRUE(wait_for([&] { return frozen->safe_entries.load() == 1; }));
  EXPECT_FALSE(frozen->safe_entry_while_frozen.load());
  sched.stop();
  runner.join();

  const auto stats = sched.safety_stats();
  EXPECT_GE(stats.watchdog_expirations, 1U);
  // The blackbox saw the graduated escalation in order.
  std::vector<std::string> frozen_health;
  for (const auto& e : sched.blackbox()->snapshot()) {
    if (e.kind == horus::BlackboxEventKind::HealthChange && e.node_name() == "frozen") {
      frozen_health.emplace_back(e.detail_text());
    }
  }
  ASSERT_GE(frozen_health.size(), 3U);
  EXPECT_EQ(frozen_health[0], "Warning");
  EXPECT_EQ(frozen_health[1], "Unhealthy");
  EXPECT_EQ(frozen_health[2], "Isolated");
}
