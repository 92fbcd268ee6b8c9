// Scheduler and node-builder configuration: validation errors, class inference, derived timing.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <memory>
#include <string>

#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;
using horus::ExecutionClass;

namespace {

class Named : public horus::Node {
 public:
  explicit Named(std::string name) : name_(std::move(name)) {}
  std::string_view name() const override { return name_; }
  void tick() override {}

 private:
  std::string name_;
};

namespace robot::sensors {
class ImuReader : public horus::Node {
 public:
  void tick() override {}
};
}  // namespace robot::sensors

std::unique_ptr<horus::Node> named(std::string name) {
  return std::make_unique<Named>(std::move(name));
}

std::string build_error(const std::function<void(horus::Scheduler&)>& configure) {
  horus::Scheduler sched;
  try {
    configure(sched);
  } catch (const horus::Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(SchedulerBuilder, DefaultNodeNameIsTheTypeNameWithoutNamespaces) {
  robot::sensors::ImuReader imu;
  EXPECT_EQ(imu.name(), "ImuReader");
}

TEST(SchedulerBuilder, DuplicateNamesAreRejectedAtBuild) {
  horus::Scheduler sched;
  sched.add(named("motor")).build();
  try {
    sched.add(named("motor")).order(3).build();
    FAIL() << "a duplicate name was accepted";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("duplicate node name 'motor'"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(sched.node_count(), 1U);  // the rejected node is not kept
}

TEST(SchedulerBuilder, InvalidNodeSettingsSayWhatIsWrong) {
  EXPECT_NE(build_error([](auto& s) {
              s.add(named("a")).rate(horus::Rate::hz(0)).build();
            }).find("node 'a': rate must be a positive"),
            std::string::npos);
  EXPECT_NE(build_error([](auto& s) {
              s.add(named("b")).budget(900_us).deadline(500_us).build();
            }).find("node 'b': budget 900us exceeds deadline 500us"),
            std::string::npos);
  EXPECT_NE(build_error([](auto& s) {
              s.add(named("c")).on("estop").rate(10_hz).build();
            }).find("cannot also have a rate()"),
            std::string::npos);
  EXPECT_NE(build_error([](auto& s) {
              s.add(named("d")).priority(120).build();
            }).find("priority must be 1..99"),
            std::string::npos);
  EXPECT_NE(build_error([](auto& s) {
              s.add(named("e")).core(4096).build();
            }).find("core 4096 does not exist"),
            std::string::npos);
  EXPECT_NE(build_error([](auto& s) {
              s.add(named("f")).compute().async_io().build();
            }).find("choose compute() or async_io()"),
            std::string::npos);
  EXPECT_NE(
      build_error([](auto& s) {
        s.add(named("g")).failure_policy(horus::FailurePolicy::Skip{.max_failures = 0}).build();
      }).find("max_failures must be >= 1"),
      std::string::npos);
  EXPECT_NE(build_error([](auto& s) { static_cast<void>(s.add(nullptr)); }).find("node is null"),
            std::string::npos);
}

TEST(SchedulerBuilder, InvalidSchedulerConfigThrows) {
  EXPECT_THROW(horus::Scheduler(horus::SchedulerConfig{}.tick_rate(horus::Rate::hz(-1))),
               horus::Error);
  EXPECT_THROW(horus::Scheduler(horus::SchedulerConfig{}.cores({9999})), horus::Error);
  EXPECT_THROW(horus::Scheduler(horus::SchedulerConfig{}.max_deadline_misses(0)), horus::Error);
}

TEST(SchedulerBuilder, NodeAddedWithoutBuildMakesTheFirstTickThrow) {
  horus::Scheduler sched;
  static_cast<void>(sched.add(named("forgotten")).order(1));
  try {
    sched.tick_once();
    FAIL() << "tick_once ran with an unbuilt node";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("'forgotten' was added but .build() was never called"),
              std::string::npos);
  }
}

TEST(SchedulerBuilder, ExecutionClassIsInferredFromSettings) {
  horus::Scheduler sched;
  sched.add(named("logger")).build();
  sched.add(named("motor")).rate(1000_hz).build();
  sched.add(named("safety")).budget(100_us).build();
  sched.add(named("planner")).rate(10_hz).compute().build();
  sched.add(named("estop")).on("emergency.stop").build();
  sched.add(named("fleet")).rate(1_hz).async_io().build();
  EXPECT_EQ(sched.node_info("logger")->execution_class, ExecutionClass::BestEffort);
  EXPECT_EQ(sched.node_info("motor")->execution_class, ExecutionClass::Rt);
  EXPECT_EQ(sched.node_info("safety")->execution_class, ExecutionClass::Rt);
  EXPECT_EQ(sched.node_info("planner")->execution_class, ExecutionClass::Compute);
  EXPECT_EQ(sched.node_info("estop")->execution_class, ExecutionClass::Event);
  EXPECT_EQ(sched.node_info("fleet")->execution_class, ExecutionClass::AsyncIo);
}

TEST(SchedulerBuilder, BudgetAndDeadlineDefaultTo80And95PercentOfThePeriod) {
  horus::Scheduler sched;
  sched.add(named("auto")).rate(1000_hz).build();
  sched.add(named("explicit")).rate(1000_hz).budget(300_us).deadline(900_us).build();
  sched.add(named("best_effort")).build();
  const auto a = sched.node_info("auto");
  EXPECT_EQ(a->budget, std::chrono::nanoseconds(800'000));
  EXPECT_EQ(a->deadline, std::chrono::nanoseconds(950'000));
  const auto e = sched.node_info("explicit");
  EXPECT_EQ(e->budget, std::chrono::microseconds(300));
  EXPECT_EQ(e->deadline, std::chrono::microseconds(900));
  EXPECT_FALSE(sched.node_info("best_effort")->budget.has_value());
}

TEST(SchedulerBuilder, NodesAreListedInOrderThenRegistration) {
  horus::Scheduler sched;
  sched.add(named("motor")).order(70).build();
  sched.add(named("safety")).order(0).build();
  sched.add(named("lidar")).order(10).build();
  sched.add(named("tracker")).order(10).build();
  EXPECT_EQ(sched.node_names(), (std::vector<std::string>{"safety", "lidar", "tracker", "motor"}));
  EXPECT_TRUE(sched.has_node("lidar"));
  EXPECT_FALSE(sched.has_node("camera"));
  EXPECT_EQ(sched.node_info("motor")->order, 70);
}

TEST(SchedulerBuilder, RatesAndLiterals) {
  EXPECT_EQ((100_hz).period(), std::chrono::milliseconds(10));
  EXPECT_EQ((2.5_hz).period(), std::chrono::milliseconds(400));
  EXPECT_EQ(horus::Rate::every(40_ms).period(), std::chrono::milliseconds(40));
  EXPECT_EQ(200_us, std::chrono::microseconds(200));
  EXPECT_EQ(3_s, std::chrono::seconds(3));
  EXPECT_FALSE(horus::Rate::hz(std::numeric_limits<double>::infinity()).valid());
}

TEST(SchedulerBuilder, RuntimeRateAndBudgetChangesRederiveAutomaticTiming) {
  horus::Scheduler sched;
  sched.add(named("sensor")).rate(100_hz).build();
  EXPECT_TRUE(sched.set_node_rate("sensor", 20_hz));
  auto info = sched.node_info("sensor");
  EXPECT_EQ(info->rate, 20_hz);
  EXPECT_EQ(info->budget, std::chrono::milliseconds(40));
  EXPECT_EQ(info->deadline, std::chrono::microseconds(47'500));
  EXPECT_TRUE(sched.set_tick_budget("sensor", 500_us));
  EXPECT_EQ(sched.node_info("sensor")->budget, std::chrono::microseconds(500));
  EXPECT_FALSE(sched.set_node_rate("nobody", 10_hz));
  EXPECT_THROW(sched.set_node_rate("sensor", horus::Rate::hz(0)), horus::Error);
}

TEST(SchedulerBuilder, CriticalNodeMustExist) {
  horus::Scheduler sched;
  sched.add(named("motor")).build();
  EXPECT_THROW(sched.add_critical_node("nobody", 100_ms), horus::Error);
  sched.add_critical_node("motor", 200_ms);
  EXPECT_TRUE(sched.node_info("motor")->critical);
  EXPECT_EQ(sched.node_info("motor")->watchdog, std::chrono::milliseconds(200));
}

TEST(SchedulerBuilder, RtDegradesGracefullyAndSaysWhat) {
  horus::Scheduler plain;
  EXPECT_FALSE(plain.has_full_rt());
  horus::Scheduler rt{horus::SchedulerConfig{}.rt(true)};
  const auto caps = rt.capabilities();
  const auto degradations = rt.degradations();
  EXPECT_EQ(rt.has_full_rt(), degradations.empty());
  EXPECT_EQ(caps.rt_scheduling,
            std::none_of(degradations.begin(), degradations.end(),
                         [](const auto& d) { return d.find("SCHED_FIFO") != std::string::npos; }));
  EXPECT_EQ(caps.memory_locking,
            std::none_of(degradations.begin(), degradations.end(),
                         [](const auto& d) { return d.find("mlockall") != std::string::npos; }));
}
