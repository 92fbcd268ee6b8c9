// Event nodes (on(topic)): ticked once per message, never polled.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "horus/literals.hpp"
#include "horus/message.hpp"
#include "horus/scheduler.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"

using namespace horus::literals;

namespace sched_test_msgs {
struct EStop {
  std::uint64_t seq{};
  std::array<std::uint8_t, 16> reason{};
  std::string log_summary() const { return "EStop { seq: " + std::to_string(seq) + " }"; }
  bool operator==(const EStop&) const = default;
};
}  // namespace sched_test_msgs

template <>
struct horus::TypeInfo<sched_test_msgs::EStop> {
  using type = sched_test_msgs::EStop;
  static constexpr std::string_view name = "sched_test_msgs.EStop";
  static constexpr std::string_view package = "sched_test_msgs";
  static constexpr std::uint64_t fingerprint = 0x5c4ed0e57a11b001ULL;
  static constexpr bool is_pod = true;
  static constexpr std::size_t size = sizeof(type);
  static constexpr std::size_t alignment = alignof(type);
  static constexpr std::string_view schema =
      "message sched_test_msgs.EStop {\n  seq: u64,\n  reason: [u8; 16],\n}\n";
  // Written by hand, so without the generator's description: a segment then stores none.
  static constexpr std::string_view description{};
  static constexpr std::size_t field_count = 2;
  static constexpr std::array<horus::PaddingRange, 0> padding{};
  template <class Msg, class Fn>
  static constexpr void visit(Msg& m, Fn&& fn) {
    fn("seq", m.seq);
    fn("reason", m.reason);
  }
};

namespace {

class EStopHandler : public horus::Node {
 public:
  EStopHandler() : topic_("emergency.stop") {}
  std::string_view name() const override { return "estop"; }
  void tick() override {
    ticks.fetch_add(1);
    while (auto msg = topic_.try_recv()) last_seq.store(msg->seq);
  }
  std::atomic<int> ticks{0};
  std::atomic<std::uint64_t> last_seq{0};

 private:
  horus::Topic<sched_test_msgs::EStop> topic_;
};

// Each test runs in its own topic namespace, removed afterwards.
class SchedulerEvent : public ::testing::Test {
 protected:
  void SetUp() override {
    namespace_ = "sched_event_" + std::to_string(::getpid()) + "_" +
                 ::testing::UnitTest::GetInstance()->current_test_info()->name();
    setenv("HORUS_NAMESPACE", namespace_.c_str(), 1);
  }
  void TearDown() override {
    horus::remove_namespace(namespace_);
    unsetenv("HORUS_NAMESPACE");
  }
  std::string namespace_;
};

bool wait_for(const std::function<bool()>& condition) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (!condition()) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::sleep_for(1_ms);
  }
  return true;
}

}  // namespace

TEST_F(SchedulerEvent, TickOnceTicksAnEventNodeOnlyWhenItsTopicReceived) {
  horus::Scheduler sched;
  auto node = std::make_unique<EStopHandler>();
  EStopHandler* handler = node.get();
  sched.add(std::move(node)).on("emergency.stop").build();
  horus::Topic<sched_test_msgs::EStop> publisher("emergency.stop");
  sched.tick_once();
  sched.tick_once();
  EXPECT_EQ(handler->ticks.load(), 0);
  publisher.send({.seq = 7, .reason = {}});
  sched.tick_once();
  sched.tick_once();
  EXPECT_EQ(handler->ticks.load(), 1);
  EXPECT_EQ(handler->last_seq.load(), 7U);
}

TEST_F(SchedulerEvent, RunningEventNodeWakesOncePerMessageWithoutPolling) {
  horus::Scheduler sched{horus::SchedulerConfig{}.tick_rate(1000_hz)};
  auto node = std::make_unique<EStopHandler>();
  EStopHandler* handler = node.get();
  sched.add(std::move(node)).on("emergency.stop").build();
  horus::Topic<sched_test_msgs::EStop> publisher("emergency.stop");
  std::thread runner([&] { sched.run(); });
  ASSERT_TRUE(wait_for([&] { return sched.is_running(); }));
  std::this_thread::sleep_for(50_ms);  // 50 main-loop cycles: an event node must not tick
  EXPECT_EQ(handler->ticks.load(), 0);
  for (std::uint64_t seq = 1; seq <= 3; ++seq) {
    publisher.send({.seq = seq, .reason = {}});
    EXPECT_TRUE(wait_for([&] { return handler->last_seq.load() == seq; })) << "message " << seq;
  }
  std::this_thread::sleep_for(20_ms);
  sched.stop();
  runner.join();
  EXPECT_EQ(handler->ticks.load(), 3);
  EXPECT_EQ(sched.node_info("estop")->execution_class, horus::ExecutionClass::Event);
}

namespace {

class EStopSender : public horus::Node {
 public:
  explicit EStopSender(const std::string& topic = "emergency.stop") : topic_(topic) {}
  std::string_view name() const override { return "sender"; }
  void tick() override {
    for (int i = 0; i < 3; ++i) topic_.send(sched_test_msgs::EStop{++seq_, {}});
  }

 private:
  horus::Topic<sched_test_msgs::EStop> topic_;
  std::uint64_t seq_ = 0;
};

}  // namespace

TEST_F(SchedulerEvent, MetricsCountTheMessagesANodesTopicsSendAndReceiveInItsCallbacks) {
  horus::Scheduler sched;
  sched.add(std::make_unique<EStopSender>()).order(0).build();
  sched.add(std::make_unique<EStopHandler>()).order(1).build();
  horus::Topic<sched_test_msgs::EStop> outsider("emergency.stop");
  sched.tick_once();
  outsider.send(sched_test_msgs::EStop{100, {}});  // outside any callback: nobody's count
  sched.tick_once();
  const auto sender = sched.node_metrics("sender");
  const auto handler = sched.node_metrics("estop");
  ASSERT_TRUE(sender && handler);
  EXPECT_EQ(sender->messages_sent, 6U);
  EXPECT_EQ(sender->messages_received, 0U);
  EXPECT_EQ(handler->messages_received, 7U);
  EXPECT_EQ(handler->messages_sent, 0U);
  while (outsider.try_recv()) {
  }
  EXPECT_EQ(sched.node_metrics("estop")->messages_received, 7U);
}

namespace {

bool topic_listed(const std::string& namespace_name, const std::string& topic) {
  for (const auto& info : horus::list_topics(namespace_name)) {
    if (info.name == topic) return true;
  }
  return false;
}

}  // namespace

TEST_F(SchedulerEvent, DestroyingTheSchedulerRemovesTopicsThisProcessCreatedThatNobodyUses) {
  {
    horus::Scheduler sched;
    sched.add(std::make_unique<EStopSender>("only.mine")).build();
    sched.tick_once();
    EXPECT_TRUE(topic_listed(namespace_, "only.mine"));
  }
  EXPECT_FALSE(topic_listed(namespace_, "only.mine"));
}

TEST_F(SchedulerEvent, TopicsStillOpenOrKeptSurviveTheScheduler) {
  horus::Topic<sched_test_msgs::EStop> still_open("shared.topic");
  {
    horus::Scheduler sched;
    sched.add(std::make_unique<EStopSender>("shared.topic")).build();
    sched.tick_once();
  }
  EXPECT_TRUE(topic_listed(namespace_, "shared.topic"));
  EXPECT_EQ(still_open.try_recv()->seq, 1U);

  {
    horus::Scheduler sched{horus::SchedulerConfig{}.keep_topics(true)};
    sched.add(std::make_unique<EStopSender>("for.late.joiners")).build();
    sched.tick_once();
  }
  EXPECT_TRUE(topic_listed(namespace_, "for.late.joiners"));
  horus::Topic<sched_test_msgs::EStop> late("for.late.joiners");
  EXPECT_EQ(late.read_latest()->seq, 3U);
}
