// Changing a running scheduler: nodes added from another thread or from a tick (initialised,
// ticking at their rate, visible to introspection and presence, shut down in reverse order),
// add_critical_node while running, add() chained as seed 001 writes it, and timestamp_now().
// Real threads throughout: run under ThreadSanitizer (label transport). Waits are bounded polls
// on what the scheduler reports, never assertions on timing.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "horus/clock.hpp"
#include "horus/literals.hpp"
#include "horus/presence.hpp"
#include "horus/run.hpp"
#include "horus/scheduler.hpp"
#include "test_journal.hpp"
#include "topic_test_support.hpp"

using namespace horus::literals;

namespace {

using horus_test::Journal;

class Probe : public horus::Node {
 public:
  Probe(std::string name, Journal& journal, std::function<void(Probe&)> body = {})
      : name_(std::move(name)), journal_(journal), body_(std::move(body)) {}
  std::string_view name() const override { return name_; }
  void init() override { journal_.add("init:" + name_); }
  void tick() override {
    if (ticks.load() == 0) journal_.add("tick:" + name_);
    stamps_.push_back(horus::timestamp_now());
    ticks.fetch_add(1);
    if (body_) body_(*this);
  }
  void shutdown() override { journal_.add("shutdown:" + name_); }
  void enter_safe_state() override { safe_states.fetch_add(1); }
  // Read only once the scheduler is done with the node (its thread joined).
  const std::vector<std::uint64_t>& stamps() const { return stamps_; }

  std::atomic<int> ticks{0};
  std::atomic<int> safe_states{0};

 private:
  std::string name_;
  Journal& journal_;
  std::function<void(Probe&)> body_;
  std::vector<std::uint64_t> stamps_;
};

/// Polls `done` until it holds or 20 s pass (a stuck scheduler fails the test, not the suite).
bool eventually(const std::function<bool()>& done) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!done()) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

horus::SchedulerConfig real() {
  return horus::SchedulerConfig{}.tick_rate(500_hz).handle_signals(false);
}

bool announced(const std::string& node) {
  for (const horus::PresenceInfo& info : horus::list_presence()) {
    if (info.alive && info.snapshot_json.find("\"name\":\"" + node + "\"") != std::string::npos) {
      return true;
    }
  }
  return false;
}

}  // namespace

TEST(RuntimeAdd, FromAnotherThreadStartsEachClassAndShutsDownInReverseOrder) {
  topic_test::PrivateNamespace ns;
  Journal journal;
  horus::Scheduler sched{real()};
  sched.add(std::make_shared<Probe>("base", journal)).order(0).build();
  sched.add(std::make_shared<Probe>("sensor", journal)).order(40).rate(200_hz).build();
  std::thread loop([&] { EXPECT_EQ(sched.run(), 0); });
  EXPECT_TRUE(eventually([&] { return sched.node_metrics("sensor")->total_ticks >= 3; }));

  auto best_effort = std::make_shared<Probe>("logger", journal);
  auto rt = std::make_shared<Probe>("attitude", journal);
  auto compute = std::make_shared<Probe>("planner", journal);
  auto io = std::make_shared<Probe>("uploader", journal);
  EXPECT_NO_THROW({
    sched.add(best_effort).order(50).build();
    sched.add(rt).order(10).rate(100_hz).build();
    sched.add(compute).order(30).rate(50_hz).compute().build();
    sched.add(io).order(60).rate(50_hz).async_io().build();
  });

  // Visible at once, in execution order.
  EXPECT_EQ(sched.node_names(), (std::vector<std::string>{"base", "attitude", "planner", "sensor",
                                                          "logger", "uploader"}));
  for (const auto& node : {best_effort, rt, compute, io}) {
    EXPECT_TRUE(eventually([&] { return node->ticks.load() >= 3; })) << node->name();
  }
  EXPECT_EQ(sched.node_info("attitude")->execution_class, horus::ExecutionClass::Rt);
  EXPECT_EQ(sched.node_info("attitude")->rate, 100_hz);
  EXPECT_EQ(sched.node_info("planner")->execution_class, horus::ExecutionClass::Compute);
  EXPECT_EQ(sched.node_info("uploader")->execution_class, horus::ExecutionClass::AsyncIo);
  EXPECT_EQ(sched.node_info("logger")->state, horus::NodeState::Running);
  EXPECT_TRUE(eventually([] { return announced("attitude") && announced("logger"); }));

  sched.stop();
  loop.join();
  for (const std::string name : {"logger", "attitude", "planner", "uploader"}) {
    EXPECT_LT(journal.index_of("init:" + name), journal.index_of("tick:" + name)) << name;
  }
  EXPECT_EQ(journal.only("shutdown:"),
            (std::vector<std::string>{"shutdown:uploader", "shutdown:logger", "shutdown:sensor",
                                      "shutdown:planner", "shutdown:attitude", "shutdown:base"}));
  EXPECT_EQ(sched.node_info("attitude")->state, horus::NodeState::Stopped);
}

TEST(RuntimeAdd, FromATickOfARealTimeThreadDoesNotDeadlock) {
  topic_test::PrivateNamespace ns;
  Journal journal;
  horus::Scheduler sched{real()};
  std::atomic<bool> added{false};
  std::shared_ptr<Probe> child;
  auto parent = std::make_shared<Probe>("parent", journal, [&](Probe& self) {
    if (self.ticks.load() == 3) {
      child = std::make_shared<Probe>("child", journal);
      sched.add(child).order(1).rate(250_hz).build();
      sched.add(std::make_shared<Probe>("child_main", journal)).order(2).build();
      added = true;
    }
  });
  sched.add(parent).order(0).rate(250_hz).build();
  std::thread loop([&] { EXPECT_EQ(sched.run(), 0); });
  if (!eventually([&] { return added.load(); })) {
    sched.stop();
    loop.join();
    FAIL() << "the tick could not add its nodes: " << sched.stop_reason();
  }
  EXPECT_TRUE(eventually([&] { return child->ticks.load() >= 3; }));
  EXPECT_TRUE(eventually([&] { return sched.node_metrics("child_main")->total_ticks >= 3; }));
  sched.stop();
  loop.join();
  EXPECT_EQ(journal.only("shutdown:"),
            (std::vector<std::string>{"shutdown:child_main", "shutdown:child", "shutdown:parent"}));
}

TEST(RuntimeAdd, FromATickInDeterministicModeTicksAtItsRateFromTheNextCycle) {
  topic_test::PrivateNamespace ns;
  Journal journal;
  horus::Scheduler sched{
      horus::SchedulerConfig{}.deterministic(true).tick_rate(100_hz).handle_signals(false)};
  std::shared_ptr<Probe> late;
  auto spawner = std::make_shared<Probe>("spawner", journal, [&](Probe& self) {
    if (self.ticks.load() == 3) {
      late = std::make_shared<Probe>("late", journal);
      sched.add(late).order(5).rate(25_hz).build();
    }
  });
  sched.add(spawner).order(0).build();
  EXPECT_EQ(sched.run_for(std::chrono::seconds(1)), 0);
  ASSERT_NE(late, nullptr);
  // Added during the third pass (at 20 ms), started at the next one: every 40 ms from 30 ms.
  ASSERT_EQ(late->stamps().size(), 25U);
  EXPECT_EQ(late->stamps().front(), 30'000'000U);
  for (std::size_t i = 1; i < late->stamps().size(); ++i) {
    EXPECT_EQ(late->stamps()[i] - late->stamps()[i - 1], 40'000'000U) << i;
  }
  EXPECT_EQ(journal.only("shutdown:"),
            (std::vector<std::string>{"shutdown:late", "shutdown:spawner"}));
}

TEST(RuntimeAdd, ANodeAddedWithoutBuildStaysOutOfTheRunningLoop) {
  topic_test::PrivateNamespace ns;
  Journal journal;
  horus::Scheduler sched{real()};
  sched.add(std::make_shared<Probe>("base", journal)).build();
  std::thread loop([&] { sched.run(); });
  EXPECT_TRUE(eventually([&] { return sched.node_metrics("base")->total_ticks >= 2; }));
  auto pending = std::make_shared<Probe>("pending", journal);
  EXPECT_NO_THROW({
    auto builder = sched.add(pending);
    builder.rate(100_hz);
    EXPECT_FALSE(sched.has_node("pending"));
    builder.build();
  });
  EXPECT_TRUE(sched.has_node("pending"));
  EXPECT_TRUE(eventually([&] { return pending->ticks.load() >= 1; }));
  sched.stop();
  loop.join();
}

TEST(AddCriticalNode, WhileRunningTheWatchdogIsolatesTheFrozenNode) {
  topic_test::PrivateNamespace ns;
  Journal journal;
  horus::Scheduler sched{real()};
  std::atomic<bool> freeze{false};
  enum class Frozen { Running, Isolated, NeverIsolated };
  std::atomic<Frozen> frozen{Frozen::Running};
  auto motor = std::make_shared<Probe>("motor", journal, [&](Probe&) {
    // Frozen until the watchdog thread (not the check after the tick) has isolated it.
    if (!freeze.exchange(false)) return;
    const bool isolated = eventually(
        [&] { return sched.node_info("motor")->health == horus::NodeHealthState::Isolated; });
    frozen = isolated ? Frozen::Isolated : Frozen::NeverIsolated;
  });
  auto wheel = std::make_shared<Probe>("wheel", journal);
  sched.add(motor).order(0).rate(100_hz).build();
  sched.add(wheel).order(1).rate(200_hz).build();
  std::thread loop([&] { sched.run(); });
  EXPECT_TRUE(eventually([&] { return motor->ticks.load() >= 2; }));
  EXPECT_FALSE(sched.node_info("motor")->watchdog.has_value());

  EXPECT_NO_THROW(sched.add_critical_node("motor", 20_ms));
  EXPECT_TRUE(sched.node_info("motor")->critical);
  EXPECT_EQ(sched.node_info("motor")->watchdog, 20_ms);
  // Let a main-loop cycle hand the node to a watchdog before it freezes.
  const std::uint64_t cycle = sched.current_tick();
  EXPECT_TRUE(eventually([&] { return sched.current_tick() > cycle + 2; }));
  freeze = true;
  EXPECT_TRUE(eventually([&] { return wheel->safe_states.load() >= 1; }));
  EXPECT_TRUE(eventually([&] { return frozen.load() != Frozen::Running; }));
  EXPECT_EQ(frozen.load(), Frozen::Isolated);
  EXPECT_GE(sched.safety_stats().watchdog_expirations, 1U);
  sched.stop();
  loop.join();
}

TEST(SchedulerAdd, ChainsAsSeed001Writes) {
  topic_test::PrivateNamespace ns;
  Journal journal;
  auto safety = horus::RunNode(std::make_shared<Probe>("safety", journal))
                    .rate(1000_hz)
                    .order(0)
                    .budget(100_us)
                    .deadline(200_us)
                    .on_miss(horus::Miss::Stop);
  auto lidar = horus::RunNode(std::make_shared<Probe>("lidar", journal)).rate(40_hz).order(10);
  auto planner =
      horus::RunNode(std::make_shared<Probe>("planner", journal)).rate(10_hz).order(50).compute();
  horus::RunNode battery(std::make_shared<Probe>("battery", journal));

  horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true)};
  sched.add(safety).add(lidar).add(planner).add(battery.order(100));
  sched.add_critical_node("safety", 100_ms);

  EXPECT_EQ(sched.node_names(),
            (std::vector<std::string>{"safety", "lidar", "planner", "battery"}));
  const auto info = sched.node_info("safety");
  EXPECT_EQ(info->budget, 100_us);
  EXPECT_EQ(info->deadline, 200_us);
  EXPECT_EQ(info->on_miss, horus::Miss::Stop);
  EXPECT_TRUE(info->critical);
  EXPECT_EQ(sched.node_info("planner")->execution_class, horus::ExecutionClass::Compute);
  // A chained node is built: an invalid one is refused at once.
  auto bad = horus::RunNode(std::make_shared<Probe>("bad", journal)).budget(2_ms).deadline(1_ms);
  EXPECT_THROW(sched.add(bad), horus::Error);
  EXPECT_FALSE(sched.has_node("bad"));
}

TEST(TimestampNow, IsNowInNanosecondsSinceTheEpochOrSimulatedTime) {
  const auto before = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          std::chrono::system_clock::now().time_since_epoch())
                          .count();
  const std::uint64_t stamp = horus::timestamp_now();
  const auto after = std::chrono::duration_cast<std::chrono::nanoseconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
  EXPECT_GE(stamp, static_cast<std::uint64_t>(before));
  EXPECT_LE(stamp, static_cast<std::uint64_t>(after));

  topic_test::PrivateNamespace ns;
  Journal journal;
  auto node = std::make_shared<Probe>("clock", journal);
  horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true).tick_rate(1000_hz)};
  sched.add(node).build();
  for (int i = 0; i < 3; ++i) sched.tick_once();
  EXPECT_EQ(node->stamps(), (std::vector<std::uint64_t>{0, 1'000'000, 2'000'000}));
}
