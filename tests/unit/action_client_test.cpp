// Action clients between threads of one process: cancel mid-goal, no server, cancel_all,
// closing with live goals, a serialized action, goal ids and states. Each test has its own
// namespace; every wait is bounded.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <thread>

#include <horus/action.hpp>
#include <horus/topic_registry.hpp>
#include <horus_test/action/echo.hpp>
#include <horus_test/action/navigate.hpp>

#include "action_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::CancelCode;
using horus::GoalId;
using horus::GoalState;
using horus_test::action::Echo;
using horus_test::action::Navigate;

constexpr auto kLong = 5s;

Navigate::Goal slow_goal() {
  Navigate::Goal goal{};
  goal.x = 1.0;
  goal.feedback_count = 1000;
  goal.period_us = 5000;
  return goal;
}

using ActionClientTest = action_test::ActionTest;
using action_test::drive;

TEST(GoalIdTest, BytesAndTextAreLittleEndianHalves) {
  const GoalId id{0x0102030405060708ULL, 1};
  const GoalId::Bytes bytes = id.to_bytes();
  EXPECT_EQ(bytes[0], 0x08);
  EXPECT_EQ(bytes[7], 0x01);
  EXPECT_EQ(bytes[8], 0x01);
  EXPECT_EQ(id.to_string(), "08070605040302010100000000000000");
  EXPECT_EQ(GoalId::from_bytes(bytes), id);
  EXPECT_TRUE(GoalId{}.is_all());
  EXPECT_FALSE(id.is_all());
  EXPECT_NE(std::hash<GoalId>{}(id), std::hash<GoalId>{}(GoalId{1, 1}));
}

TEST(GoalStateTest, NamesAndTerminalStates) {
  EXPECT_EQ(horus::to_string(GoalState::Canceling), "canceling");
  EXPECT_EQ(horus::to_string(GoalState::Rejected), "rejected");
  EXPECT_EQ(horus::to_string(static_cast<GoalState>(9)), "invalid");
  EXPECT_FALSE(horus::is_terminal(GoalState::Canceling));
  EXPECT_TRUE(horus::is_terminal(GoalState::Succeeded));
  EXPECT_TRUE(horus::is_terminal(GoalState::Rejected));
  EXPECT_EQ(static_cast<int>(GoalState::Aborted), 6);
  EXPECT_EQ(horus::to_string(CancelCode::AlreadyDone), "already done");
}

TEST_F(ActionClientTest, GoalWithoutServerIsRefusedAtOnce) {
  horus::ActionClient<Navigate> client;
  const auto start = std::chrono::steady_clock::now();
  auto handle = client.send_goal(slow_goal(), kLong);
  ASSERT_FALSE(handle);
  EXPECT_EQ(handle.error().kind(), horus::ServiceErrorKind::NoServer);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 100ms);
  EXPECT_FALSE(client.wait_for_server(10ms));
}

TEST_F(ActionClientTest, CancelMidGoal) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  horus::ActionClient<Navigate> client;
  ASSERT_TRUE(client.wait_for_server(kLong));
  auto handle = client.send_goal(slow_goal(), kLong);
  ASSERT_TRUE(handle);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(handle->next_feedback(kLong));
  auto code = handle->cancel();
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, CancelCode::Accepted);
  auto outcome = handle->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Canceled);
  EXPECT_EQ(outcome->reason, "canceled by a client");
  EXPECT_GE(outcome->result.feedback_sent, 3u);
  EXPECT_EQ(server.stats().canceled, 1u);
}

TEST_F(ActionClientTest, CancelAllCancelsEveryClientsGoals) {
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_execute(drive)
                    .policy(horus::ActionPolicy::Queue)
                    .build();
  horus::ActionClient<Navigate> first;
  horus::ActionClient<Navigate> second;
  auto running = first.send_goal(slow_goal(), kLong);
  auto waiting = second.send_goal(slow_goal(), kLong);
  ASSERT_TRUE(running && waiting);
  ASSERT_TRUE(running->next_feedback(kLong));
  auto code = second.cancel_all(kLong);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, CancelCode::Accepted);
  EXPECT_EQ(running->result(kLong)->state, GoalState::Canceled);
  EXPECT_EQ(waiting->result(kLong)->state, GoalState::Canceled);
  auto unknown = waiting->cancel(kLong);
  ASSERT_TRUE(unknown);
  EXPECT_EQ(*unknown, CancelCode::AlreadyDone);
}

TEST_F(ActionClientTest, ClosingTheClientCancelsItsGoals) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  std::optional<horus::GoalHandle<Navigate>> handle;
  {
    horus::ActionClient<Navigate> client;
    auto sent = client.send_goal(slow_goal(), kLong);
    ASSERT_TRUE(sent);
    handle.emplace(std::move(*sent));
    ASSERT_TRUE(handle->next_feedback(kLong));
  }
  auto outcome = handle->try_result();
  ASSERT_TRUE(outcome);
  EXPECT_TRUE(outcome->state == GoalState::Aborted || outcome->state == GoalState::Canceled);
  // The server heard the cancel: the next goal of another client runs.
  horus::ActionClient<Navigate> next;
  Navigate::Goal quick = slow_goal();
  quick.feedback_count = 2;
  quick.period_us = 1000;
  std::optional<horus::ServiceResult<horus::GoalHandle<Navigate>>> accepted;
  for (auto until = std::chrono::steady_clock::now() + kLong;;) {
    accepted.emplace(next.send_goal(quick, kLong));
    ASSERT_TRUE(*accepted);
    if ((*accepted)->state() != GoalState::Rejected) break;
    ASSERT_LT(std::chrono::steady_clock::now(), until);
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_EQ((*accepted)->result(kLong)->state, GoalState::Succeeded);
}

TEST_F(ActionClientTest, SerializedActionEchoes) {
  auto server = horus::ActionServerBuilder<Echo>()
                    .on_execute([](horus::ServerGoal<Echo>& goal) {
                      Echo::Feedback feedback;
                      for (std::uint32_t i = 0; i < goal.goal().repeat; ++i) {
                        feedback.partial.push_back(goal.goal().text);
                        goal.publish_feedback(feedback);
                      }
                      goal.succeed({goal.goal().text});
                    })
                    .build();
  horus::ActionClient<Echo> client;
  Echo::Goal goal;
  goal.text = "hello";
  auto handle = client.send_goal(goal, kLong);
  ASSERT_TRUE(handle);
  auto outcome = handle->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Succeeded);
  EXPECT_EQ(outcome->result.text, "hello");
  std::size_t received = 0;
  while (auto feedback = handle->try_feedback()) {
    ++received;
    EXPECT_EQ(feedback->partial.size(), received);
  }
  EXPECT_EQ(received, 3u);
}

TEST_F(ActionClientTest, ServerStoppingMidGoalAbortsIt) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  horus::ActionClient<Navigate> client;
  auto handle = client.send_goal(slow_goal(), kLong);
  ASSERT_TRUE(handle);
  ASSERT_TRUE(handle->next_feedback(kLong));
  std::thread stopper([&] { server.stop(); });
  auto outcome = handle->result(kLong);
  stopper.join();
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Aborted);
  EXPECT_EQ(outcome->reason, "the action server stopped");
}

}  // namespace
