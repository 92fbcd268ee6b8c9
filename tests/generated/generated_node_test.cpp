// Node base classes generated from tests/schemas/test_nodes/*.hnode: they compile, report exactly
// the declared topics and settings, hold the declared data, and run in a scheduler.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"
#include "pair_nodes.hpp"
#include "test_nodes.hpp"
#include "topic_test_support.hpp"

using namespace horus::literals;
using horus::TopicMetadata;

namespace {

using test_nodes_user::Listener;
using test_nodes_user::Talker;

class Tracker : public test_nodes::TrackerBase {
 public:
  void init() override {
    serve_where_is([this](const test_msgs::GetRobotPoseRequest& request) {
      test_msgs::GetRobotPoseResponse response{};
      response.x = request.robot_name == "agv" ? gain_ * 4.0 : -1.0;
      return response;
    });
  }
  void tick() override {}

  // The generated data members, as the derived class sees them.
  double gain() const { return gain_; }
  test_msgs::Mode mode() const { return mode_; }
  std::string_view label() const { return label_.view(); }
  std::array<float, 3> history() const { return history_; }
  bool enabled() const { return enabled_; }
  bool has_note() const { return note_.has_value(); }
  std::size_t seen() const { return seen_.size(); }
  double last_pose_theta() const { return last_pose_.theta; }
  std::size_t pose_capacity() const { return pose_.capacity(); }
  std::size_t samples_capacity() const { return samples_.capacity(); }
  bool serving() const { return where_is_.has_value() && where_is_->is_running(); }
};

class Reporter : public test_nodes::ReporterBase {
 public:
  void tick() override {}
  horus::ServiceResult<test_msgs::GetRobotPoseResponse> ask(std::string name) {
    test_msgs::GetRobotPoseRequest request;
    request.robot_name = std::move(name);
    return where_is_.call(request, std::chrono::seconds(5));
  }
};

TEST(GeneratedNode, ReportsExactlyTheDeclaredNameAndTopics) {
  topic_test::PrivateNamespace ns;
  const Tracker tracker;
  EXPECT_EQ(tracker.name(), "tracker");
  EXPECT_EQ(tracker.publishers(),
            (std::vector<TopicMetadata>{{"tracker.last", "test_msgs.Point2"}}));
  EXPECT_EQ(tracker.subscribers(),
            (std::vector<TopicMetadata>{{"tracker.pose", "test_msgs.Pose2"},
                                        {"samples", "test_msgs.Serialized"}}));
  const Talker talker;
  EXPECT_EQ(talker.name(), "talker");
  EXPECT_TRUE(talker.subscribers().empty());
  EXPECT_EQ(talker.publishers(), (std::vector<TopicMetadata>{{"pair.pose", "test_msgs.Pose2"}}));
  // Without `name:`, a node runs under its declaration's name, as the seed's default does.
  class Planner : public test_nodes::PlannerBase {
    void tick() override {}
  };
  EXPECT_EQ(Planner{}.name(), "Planner");
}

TEST(GeneratedNode, HoldsTheDeclaredDataWithItsDefaults) {
  topic_test::PrivateNamespace ns;
  const Tracker tracker;
  EXPECT_EQ(tracker.gain(), 0.5);
  EXPECT_EQ(tracker.mode(), test_msgs::Mode::Run);
  EXPECT_EQ(tracker.label(), "tracker");
  EXPECT_EQ(tracker.history(), (std::array<float, 3>{1.0f, 2.0f, 3.0f}));
  EXPECT_TRUE(tracker.enabled());
  EXPECT_FALSE(tracker.has_note());
  EXPECT_EQ(tracker.seen(), 0U);
  EXPECT_EQ(tracker.last_pose_theta(), 0.0f);
  const Talker talker;
  EXPECT_EQ(talker.step(), 0.25);
  EXPECT_EQ(talker.sent(), 0U);
}

TEST(GeneratedNode, OpensTopicsWithTheDeclaredCapacity) {
  topic_test::PrivateNamespace ns;
  const Tracker tracker;
  EXPECT_EQ(tracker.pose_capacity(), 16U);
  EXPECT_EQ(tracker.samples_capacity(), horus::TopicOptions{}.capacity);
}

TEST(GeneratedNode, NodeConfigHoldsTheDeclaredSettings) {
  const horus::NodeConfig tracker = test_nodes::TrackerBase::node_config();
  EXPECT_EQ(tracker.order, 5);
  ASSERT_TRUE(tracker.rate.has_value());
  EXPECT_EQ(tracker.rate->hz(), 250.0);
  EXPECT_EQ(tracker.budget, std::chrono::nanoseconds(1'000'000));
  EXPECT_EQ(tracker.deadline, std::chrono::nanoseconds(2'500'000));
  EXPECT_EQ(tracker.watchdog, std::chrono::nanoseconds(100'000'000));
  EXPECT_EQ(tracker.on_miss, horus::Miss::Skip);
  ASSERT_EQ(tracker.failure_policy.kind(), horus::FailurePolicy::Kind::Skip);
  EXPECT_EQ(tracker.failure_policy.skip()->max_failures, 4U);
  EXPECT_EQ(tracker.failure_policy.skip()->cooldown, std::chrono::nanoseconds(20'000'000));
  EXPECT_EQ(tracker.priority, 10);
  EXPECT_EQ(tracker.core, 0);
  EXPECT_FALSE(tracker.compute || tracker.async_io || tracker.on_topic.has_value());

  const horus::NodeConfig planner = test_nodes::PlannerBase::node_config();
  EXPECT_TRUE(planner.compute);
  EXPECT_EQ(planner.order, horus::NodeConfig{}.order);
  EXPECT_FALSE(planner.rate.has_value());
  ASSERT_EQ(planner.failure_policy.kind(), horus::FailurePolicy::Kind::Restart);
  EXPECT_EQ(planner.failure_policy.restart()->max_restarts, 2U);
  EXPECT_EQ(planner.failure_policy.restart()->initial_backoff, std::chrono::nanoseconds(5'000'000));

  const horus::NodeConfig reporter = test_nodes::ReporterBase::node_config();
  EXPECT_TRUE(reporter.async_io);
  EXPECT_EQ(reporter.failure_policy.kind(), horus::FailurePolicy::Kind::Ignore);

  const horus::NodeConfig listener = test_nodes::ListenerBase::node_config();
  EXPECT_EQ(listener.on_topic, "pair.pose");
  EXPECT_EQ(listener.order, 20);
}

TEST(GeneratedNode, AddToRegistersTheDeclaredSettingsAndTheDataFlows) {
  topic_test::PrivateNamespace ns;
  horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true).tick_rate(200_hz)};
  // The listener first: it creates "pair.pose" with its declared 8 slots (a topic's creator
  // sets its capacity; the talker then opens it as it is).
  auto listener = std::make_shared<Listener>();
  auto talker = std::make_shared<Talker>();
  EXPECT_EQ(listener->pose_capacity(), 8U);
  test_nodes::TalkerBase::add_to(sched, talker).build();
  test_nodes::ListenerBase::add_to(sched, listener).build();

  for (int i = 0; i < 5; ++i) sched.tick_once();

  EXPECT_EQ(talker->sent(), 5U);
  EXPECT_EQ(listener->received(), 5U);
  EXPECT_EQ(listener->last_x(), 1.25);
  const auto talker_info = sched.node_info("talker");
  ASSERT_TRUE(talker_info.has_value());
  EXPECT_EQ(talker_info->order, 10);
  ASSERT_TRUE(talker_info->rate.has_value());
  EXPECT_EQ(talker_info->rate->hz(), 200.0);
  EXPECT_EQ(talker_info->publishers, talker->publishers());
  const auto listener_info = sched.node_info("listener");
  ASSERT_TRUE(listener_info.has_value());
  EXPECT_EQ(listener_info->execution_class, horus::ExecutionClass::Event);
  EXPECT_EQ(listener_info->on_topic, "pair.pose");
  EXPECT_EQ(listener_info->subscribers,
            (std::vector<TopicMetadata>{{"pair.pose", "test_msgs.Pose2"}}));
  EXPECT_EQ(listener_info->publishers,
            (std::vector<TopicMetadata>{{"pair.echo", "test_msgs.Point2"}}));
}

TEST(GeneratedNode, RunNodeCarriesTheDeclaredSettings) {
  topic_test::PrivateNamespace ns;
  const horus::RunNode run = test_nodes::TrackerBase::run_node(std::make_shared<Tracker>());
  EXPECT_EQ(run.config().order, 5);
  EXPECT_EQ(run.config().budget, std::chrono::nanoseconds(1'000'000));
  EXPECT_EQ(run.node()->name(), "tracker");
}

TEST(GeneratedNode, ServerStartedInInitAnswersTheClientMember) {
  topic_test::PrivateNamespace ns;
  horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true)};
  auto tracker = std::make_shared<Tracker>();
  auto reporter = std::make_shared<Reporter>();
  // The declared settings ask for SCHED_FIFO priority and core 0; this test checks services only.
  sched.add(tracker).build();
  sched.add(reporter).build();
  EXPECT_FALSE(tracker->serving());
  sched.tick_once();  // init(): the tracker starts serving
  ASSERT_TRUE(tracker->serving());
  const auto answer = reporter->ask("agv");
  ASSERT_TRUE(answer) << answer.error().message();
  EXPECT_EQ(answer->x, 2.0);
}

}  // namespace
