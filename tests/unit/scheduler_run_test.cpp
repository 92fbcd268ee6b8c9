// Node::request_stop() (from a tick, from another thread) and the horus::run one-liner.
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/run.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

class Counter : public horus::Node {
 public:
  explicit Counter(std::string name, std::function<void(Counter&)> body = {})
      : name_(std::move(name)), body_(std::move(body)) {}
  std::string_view name() const override { return name_; }
  void tick() override {
    ticks.fetch_add(1);
    if (body_) body_(*this);
  }
  std::atomic<int> ticks{0};
  std::atomic<bool> shut_down{false};
  void shutdown() override { shut_down = true; }

 private:
  std::string name_;
  std::function<void(Counter&)> body_;
};

horus::SchedulerConfig simulated() {
  return horus::SchedulerConfig{}.deterministic(true).tick_rate(100_hz).handle_signals(false);
}

}  // namespace

TEST(RequestStop, FromATickEndsTheRunAndShutsEveryNodeDown) {
  auto estop = std::make_shared<Counter>("estop", [](Counter& self) {
    if (self.ticks == 5) self.request_stop();
  });
  auto motor = std::make_shared<Counter>("motor");
  horus::Scheduler sched{simulated()};
  sched.add(estop).order(0).build();
  sched.add(motor).order(1).build();
  EXPECT_EQ(sched.run(), 0);
  EXPECT_EQ(estop->ticks, 5);
  EXPECT_EQ(motor->ticks, 4);  // the pass that asked to stop ends at the node that asked
  EXPECT_EQ(sched.stop_reason(), "node 'estop' called request_stop()");
  EXPECT_TRUE(estop->shut_down);
  EXPECT_TRUE(motor->shut_down);
  EXPECT_EQ(sched.status(), horus::SchedulerStatus::Stopped);
}

TEST(RequestStop, FromAnotherThreadEndsARealRun) {
  auto sensor = std::make_shared<Counter>("sensor");
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(1000_hz).handle_signals(false)};
  sched.add(sensor).build();
  int result = -1;
  std::thread runner([&] { result = sched.run(); });
  while (sensor->ticks == 0) std::this_thread::yield();
  sensor->request_stop();
  runner.join();
  EXPECT_EQ(result, 0);
  EXPECT_EQ(sched.stop_reason(), "node 'sensor' called request_stop()");
  EXPECT_TRUE(sensor->shut_down);
}

TEST(RequestStop, ANodeNoSchedulerHoldsIgnoresIt) {
  Counter loose("loose");
  loose.request_stop();  // nothing to stop, and no crash
  auto gone = std::make_shared<Counter>("gone");
  {
    horus::Scheduler sched;
    sched.add(gone).build();
  }
  gone->request_stop();
  SUCCEED();
}

TEST(Run, RunsEveryNodeAtItsRateForTheDuration) {
  auto slow = std::make_shared<Counter>("slow");
  auto fast = std::make_shared<Counter>("fast");
  EXPECT_EQ(horus::run({horus::RunNode(slow).order(1).rate(10_hz), fast}, simulated(), 1_s), 0);
  EXPECT_EQ(slow->ticks, 10);
  EXPECT_EQ(fast->ticks, 100);
  EXPECT_TRUE(slow->shut_down);
  EXPECT_TRUE(fast->shut_down);
}

TEST(Run, KeepsTheGivenOrder) {
  std::string trace;
  auto a = std::make_shared<Counter>("a", [&](Counter&) { trace += 'a'; });
  auto b = std::make_shared<Counter>("b", [&](Counter& self) {
    trace += 'b';
    if (self.ticks == 2) self.request_stop();
  });
  EXPECT_EQ(horus::run({horus::RunNode(b).order(0), horus::RunNode(a).order(1)}, simulated()), 0);
  EXPECT_EQ(trace, "bab");
}

TEST(Run, RejectsAnInvalidNodeSetting) {
  auto node = std::make_shared<Counter>("bad");
  try {
    horus::run({horus::RunNode(node).budget(2_ms).deadline(1_ms)}, simulated(), 1_s);
    FAIL() << "expected horus::Error";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("budget 2ms exceeds deadline 1ms"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(node->ticks, 0);
}

TEST(Run, ReturnsOneWhenAFailureStopsIt) {
  auto broken =
      std::make_shared<Counter>("broken", [](Counter&) { throw std::runtime_error("x"); });
  EXPECT_EQ(horus::run({broken}, simulated(), 1_s), 1);
  EXPECT_EQ(broken->ticks, 1);
}
