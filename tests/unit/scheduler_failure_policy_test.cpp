// A throwing node under each FailurePolicy, in deterministic mode so that backoff and cooldown
// are measured in simulated time (exact, and independent of the machine's load).
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "horus/clock.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;
using std::chrono::milliseconds;

namespace {

// Throws from tick() while `failing(tick_index)` says so; records when init and tick ran.
class Flaky : public horus::Node {
 public:
  explicit Flaky(std::function<bool(int)> failing) : failing_(std::move(failing)) {}
  std::string_view name() const override { return "flaky"; }
  void init() override { init_times.push_back(ms(horus::elapsed())); }
  void tick() override {
    tick_times.push_back(ms(horus::elapsed()));
    if (failing_(ticks_++)) throw std::runtime_error("encoder read failed");
  }
  void on_error(std::string_view error) override { errors.emplace_back(error); }

  std::vector<long> init_times;
  std::vector<long> tick_times;
  std::vector<std::string> errors;

 private:
  static long ms(std::chrono::nanoseconds t) {
    return static_cast<long>(std::chrono::duration_cast<milliseconds>(t).count());
  }
  std::function<bool(int)> failing_;
  int ticks_ = 0;
};

horus::SchedulerConfig sim() {
  return horus::SchedulerConfig{}.tick_rate(100_hz).deterministic(true);
}

Flaky* add(horus::Scheduler& sched, std::function<bool(int)> failing, horus::FailurePolicy policy) {
  auto node = std::make_unique<Flaky>(std::move(failing));
  Flaky* raw = node.get();
  sched.add(std::move(node)).failure_policy(policy).build();
  return raw;
}

}  // namespace

TEST(FailurePolicy, FatalStopsTheSchedulerAndMarksTheNodeCrashed) {
  horus::Scheduler sched{sim()};
  Flaky* node = add(
      sched, [](int i) { return i == 2; }, horus::FailurePolicy::Fatal{});
  EXPECT_EQ(sched.run_for(1_s), 1);
  EXPECT_EQ(node->tick_times, (std::vector<long>{0, 10, 20}));
  EXPECT_EQ(node->errors, (std::vector<std::string>{"encoder read failed"}));
  EXPECT_EQ(sched.node_info("flaky")->state, horus::NodeState::Crashed);
  EXPECT_EQ(sched.stop_reason(),
            "node 'flaky' failed in tick(): encoder read failed (FailurePolicy::Fatal)");
  const auto m = sched.node_metrics("flaky");
  EXPECT_EQ(m->failed_ticks, 1U);
  EXPECT_EQ(m->successful_ticks, 2U);
}

TEST(FailurePolicy, RestartReinitialisesWithExponentialBackoffThenGivesUp) {
  horus::Scheduler sched{sim()};
  Flaky* node = add(
      sched, [](int) { return true; },
      horus::FailurePolicy::Restart{.max_restarts = 2, .initial_backoff = 20_ms});
  EXPECT_EQ(sched.run_for(1_s), 1);
  // init at 0; tick fails at 0 -> re-init after 20 ms; fails -> after 40 ms more; fails -> fatal.
  EXPECT_EQ(node->init_times, (std::vector<long>{0, 20, 60}));
  EXPECT_EQ(node->tick_times, (std::vector<long>{0, 20, 60}));
  EXPECT_EQ(sched.node_metrics("flaky")->restarts, 2U);
  EXPECT_EQ(sched.node_info("flaky")->state, horus::NodeState::Error);
  EXPECT_EQ(sched.stop_reason(),
            "node 'flaky' still failing after 2 restarts: encoder read failed");
}

TEST(FailurePolicy, RestartRecoversWhenTheNodeDoes) {
  horus::Scheduler sched{sim()};
  Flaky* node = add(
      sched, [](int i) { return i == 0; },
      horus::FailurePolicy::Restart{.max_restarts = 1, .initial_backoff = 30_ms});
  EXPECT_EQ(sched.run_for(60_ms), 0);
  EXPECT_EQ(node->init_times, (std::vector<long>{0, 30}));
  EXPECT_EQ(node->tick_times, (std::vector<long>{0, 30, 40, 50}));
}

TEST(FailurePolicy, SkipCoolsDownAfterMaxConsecutiveFailures) {
  horus::Scheduler sched{sim()};
  Flaky* node = add(
      sched, [](int) { return true; },
      horus::FailurePolicy::Skip{.max_failures = 2, .cooldown = 50_ms});
  EXPECT_EQ(sched.run_for(130_ms), 0);
  EXPECT_EQ(node->tick_times, (std::vector<long>{0, 10, 60, 70, 120}));
  const auto m = sched.node_metrics("flaky");
  EXPECT_EQ(m->errors_count, 5U);
  EXPECT_EQ(m->skipped_ticks, 8U);
  EXPECT_EQ(sched.node_info("flaky")->state, horus::NodeState::Stopped);
}

TEST(FailurePolicy, IgnoreKeepsTickingAndCountsErrors) {
  horus::Scheduler sched{sim()};
  Flaky* node = add(
      sched, [](int i) { return i % 2 == 0; }, horus::FailurePolicy::Ignore{});
  for (int i = 0; i < 6; ++i) sched.tick_once();
  EXPECT_EQ(node->tick_times.size(), 6U);
  EXPECT_EQ(node->errors.size(), 3U);
  const auto m = sched.node_metrics("flaky");
  EXPECT_EQ(m->failed_ticks, 3U);
  EXPECT_EQ(m->errors_count, 3U);
  EXPECT_EQ(sched.node_info("flaky")->last_error, "tick(): encoder read failed");
  EXPECT_EQ(sched.stop_reason(), "");
}

TEST(FailurePolicy, NonStandardExceptionsAreCaughtToo) {
  class ThrowsInt : public horus::Node {
   public:
    void tick() override { throw 42; }
    void on_error(std::string_view e) override { error = e; }
    std::string error;
  };
  horus::Scheduler sched{sim()};
  auto node = std::make_unique<ThrowsInt>();
  ThrowsInt* raw = node.get();
  sched.add(std::move(node)).failure_policy(horus::FailurePolicy::Ignore{}).build();
  sched.tick_once();
  EXPECT_EQ(raw->error, "unknown exception");
}
