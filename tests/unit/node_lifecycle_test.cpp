// Node lifecycle under the scheduler: lazy ordered init, exclusion on init failure (and a failed
// run once every node is excluded), reverse-order shutdown that survives throwing and hanging
// nodes, removal, selective ticking, topic metadata.
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"
#include "test_journal.hpp"

using namespace horus::literals;

namespace {

using horus_test::Journal;

class Recorder : public horus::Node {
 public:
  Recorder(std::string name, Journal& journal) : name_(std::move(name)), journal_(journal) {}
  std::string_view name() const override { return name_; }
  void init() override {
    journal_.add("init:" + name_);
    if (init_throws) throw std::runtime_error("no device on /dev/ttyUSB0");
  }
  void tick() override { journal_.add("tick:" + name_); }
  void shutdown() override {
    journal_.add("shutdown:" + name_);
    if (shutdown_throws) throw std::runtime_error("motor driver unreachable");
    while (hang_shutdown.load()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  void on_error(std::string_view error) override {
    journal_.add("error:" + name_ + ":" + std::string(error));
  }
  std::vector<horus::TopicMetadata> publishers() const override {
    return {{"scan", "horus.msg.LaserScan"}};
  }

  bool init_throws = false;
  bool shutdown_throws = false;
  std::atomic<bool> hang_shutdown{false};

 private:
  std::string name_;
  Journal& journal_;
};

Recorder* add(horus::Scheduler& sched, Journal& journal, const std::string& name, int order,
              horus::FailurePolicy policy = {}) {
  auto node = std::make_unique<Recorder>(name, journal);
  Recorder* raw = node.get();
  sched.add(std::move(node)).order(order).failure_policy(policy).build();
  return raw;
}

}  // namespace

TEST(NodeLifecycle, InitIsLazyAndInOrder) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "motor", 20);
  add(sched, journal, "safety", 0);
  add(sched, journal, "lidar", 10);
  EXPECT_TRUE(journal.entries().empty()) << "init must wait for the first tick";
  sched.tick_once();
  EXPECT_EQ(journal.entries(),
            (std::vector<std::string>{"init:safety", "init:lidar", "init:motor", "tick:safety",
                                      "tick:lidar", "tick:motor"}));
  sched.tick_once();
  EXPECT_EQ(journal.only("init:").size(), 3U) << "init runs once";
  EXPECT_EQ(sched.node_info("lidar")->state, horus::NodeState::Running);
  EXPECT_EQ(sched.node_info("lidar")->publishers,
            (std::vector<horus::TopicMetadata>{{"scan", "horus.msg.LaserScan"}}));
}

TEST(NodeLifecycle, FailedInitExcludesTheNodeAndOthersContinue) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "lidar", 0, horus::FailurePolicy::Skip{})->init_throws = true;
  add(sched, journal, "motor", 1);
  sched.tick_once();
  sched.tick_once();
  EXPECT_EQ(journal.only("tick:"), (std::vector<std::string>{"tick:motor", "tick:motor"}));
  EXPECT_EQ(journal.only("error:"),
            (std::vector<std::string>{"error:lidar:no device on /dev/ttyUSB0"}));
  const auto info = sched.node_info("lidar");
  EXPECT_EQ(info->state, horus::NodeState::Error);
  EXPECT_EQ(info->last_error, "init(): no device on /dev/ttyUSB0");
  EXPECT_EQ(sched.stop_reason(), "");
  EXPECT_EQ(sched.run_for(0_ms), 0);
  EXPECT_EQ(journal.only("shutdown:"), (std::vector<std::string>{"shutdown:motor"}))
      << "a node whose init failed is never shut down";
}

TEST(NodeLifecycle, FatalInitFailureStopsTheScheduler) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "lidar", 0)->init_throws = true;  // FailurePolicy::Fatal is the default
  add(sched, journal, "motor", 1);
  EXPECT_EQ(sched.run(), 1);
  EXPECT_TRUE(journal.only("tick:").empty());
  EXPECT_TRUE(journal.only("init:motor").empty()) << "init stops at the fatal failure";
  EXPECT_NE(sched.stop_reason().find("node 'lidar' failed in init()"), std::string::npos)
      << sched.stop_reason();
  EXPECT_EQ(sched.status(), horus::SchedulerStatus::Stopped);
}

TEST(NodeLifecycle, FatalWithoutStopOnFailedInitExcludesTheNodeAndOthersContinue) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "lidar", 0, horus::FailurePolicy::Fatal{.stop_on_failed_init = false})
      ->init_throws = true;
  add(sched, journal, "motor", 1);
  sched.tick_once();
  EXPECT_EQ(journal.only("tick:"), (std::vector<std::string>{"tick:motor"}));
  EXPECT_EQ(sched.node_info("lidar")->state, horus::NodeState::Error);
  EXPECT_EQ(sched.node_info("lidar")->failure_policy, horus::FailurePolicy::Kind::Fatal);
  EXPECT_EQ(sched.stop_reason(), "");
}

TEST(NodeLifecycle, ARunWhoseEveryNodeFailedInitStopsWithAFailureInsteadOfIdling) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "lidar", 0, horus::FailurePolicy::Skip{})->init_throws = true;
  add(sched, journal, "motor", 1, horus::FailurePolicy::Fatal{.stop_on_failed_init = false})
      ->init_throws = true;
  EXPECT_EQ(sched.run(), 1) << "no node was left to run";
  EXPECT_EQ(sched.stop_reason(),
            "no node left to run: node 'lidar' failed in init(): no device on /dev/ttyUSB0; "
            "node 'motor' failed in init(): no device on /dev/ttyUSB0");
  EXPECT_TRUE(journal.only("tick:").empty());
}

TEST(NodeLifecycle, ShutdownRunsInReverseOrderAndSurvivesAThrowingNode) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "safety", 0);
  add(sched, journal, "lidar", 10)->shutdown_throws = true;
  add(sched, journal, "motor", 20);
  EXPECT_EQ(sched.run_for(20_ms), 0);
  EXPECT_EQ(journal.only("shutdown:"),
            (std::vector<std::string>{"shutdown:motor", "shutdown:lidar", "shutdown:safety"}));
  EXPECT_EQ(journal.only("error:"),
            (std::vector<std::string>{"error:lidar:motor driver unreachable"}));
  EXPECT_EQ(sched.node_info("safety")->state, horus::NodeState::Stopped);
  EXPECT_THROW(sched.run(), horus::Error) << "a shut-down scheduler cannot run again";
}

TEST(NodeLifecycle, HangingShutdownIsAbandonedAndTheOthersStillShutDown) {
  Journal journal;
  Recorder* lidar = nullptr;
  {
    horus::Scheduler sched{horus::SchedulerConfig{}.shutdown_timeout(100_ms)};
    add(sched, journal, "safety", 0);
    lidar = add(sched, journal, "lidar", 10);
    lidar->hang_shutdown = true;
    add(sched, journal, "motor", 20);
    sched.tick_once();
    EXPECT_EQ(sched.run_for(0_ms), 0);
    EXPECT_EQ(journal.only("shutdown:"),
              (std::vector<std::string>{"shutdown:motor", "shutdown:lidar", "shutdown:safety"}));
    EXPECT_EQ(sched.node_info("lidar")->state, horus::NodeState::Error);
    EXPECT_NE(sched.node_info("lidar")->last_error.find("did not return within 100 ms"),
              std::string::npos);
    // The abandoned thread still uses the node: release it before the scheduler goes away.
    lidar->hang_shutdown = false;
  }
}

TEST(NodeLifecycle, DestructorShutsDownNodesThatTickOnceInitialised) {
  Journal journal;
  {
    horus::Scheduler sched;
    add(sched, journal, "a", 0);
    add(sched, journal, "b", 1);
    sched.tick_once();
  }
  EXPECT_EQ(journal.only("shutdown:"), (std::vector<std::string>{"shutdown:b", "shutdown:a"}));
}

TEST(NodeLifecycle, RemoveNodeShutsItDown) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "a", 0);
  add(sched, journal, "b", 1);
  sched.tick_once();
  EXPECT_TRUE(sched.remove_node("a"));
  EXPECT_FALSE(sched.remove_node("a"));
  EXPECT_EQ(journal.only("shutdown:"), (std::vector<std::string>{"shutdown:a"}));
  EXPECT_EQ(sched.node_names(), (std::vector<std::string>{"b"}));
  sched.tick_once();
  EXPECT_EQ(journal.only("tick:"), (std::vector<std::string>{"tick:a", "tick:b", "tick:b"}));
}

TEST(NodeLifecycle, RemoveNodeWhileRunningShutsItDownOnItsThread) {
  Journal journal;
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(200_hz)};
  add(sched, journal, "keeper", 0);
  add(sched, journal, "leaver", 1);
  std::thread runner([&] { sched.run(); });
  for (int i = 0; i < 2000 && journal.only("tick:leaver").empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_TRUE(sched.remove_node("leaver"));
  for (int i = 0; i < 2000 && journal.only("shutdown:leaver").empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const auto ticks_before = journal.only("tick:leaver").size();
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  sched.stop();
  runner.join();
  EXPECT_EQ(journal.only("tick:leaver").size(), ticks_before) << "no tick after removal";
  EXPECT_EQ(journal.only("shutdown:"),
            (std::vector<std::string>{"shutdown:leaver", "shutdown:keeper"}));
}

TEST(NodeLifecycle, TickOnceWithNamesTicksOnlyThose) {
  Journal journal;
  horus::Scheduler sched;
  add(sched, journal, "sensor", 0);
  add(sched, journal, "ctrl", 1);
  add(sched, journal, "motor", 2);
  sched.tick_once({"sensor", "motor"});
  EXPECT_EQ(journal.only("tick:"), (std::vector<std::string>{"tick:sensor", "tick:motor"}));
  EXPECT_THROW(sched.tick_once({"camera"}), horus::Error);
}

TEST(NodeLifecycle, StopFromInsideATickEndsRun) {
  class Stopper : public horus::Node {
   public:
    explicit Stopper(horus::Scheduler& s) : sched_(s) {}
    void tick() override {
      if (++ticks_ == 3) sched_.stop();
    }
    int ticks_ = 0;

   private:
    horus::Scheduler& sched_;
  };
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(1000_hz)};
  auto node = std::make_unique<Stopper>(sched);
  Stopper* raw = node.get();
  sched.add(std::move(node)).build();
  EXPECT_EQ(sched.run(), 0);
  EXPECT_EQ(raw->ticks_, 3);
  EXPECT_EQ(sched.stop_reason(), "stop() called");
  EXPECT_EQ(sched.node_info("Stopper")->state, horus::NodeState::Stopped);
}
