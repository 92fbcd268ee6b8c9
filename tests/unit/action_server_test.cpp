// Action servers between threads of one process: goals with feedback, the three policies with
// two clients each, rejections' reasons, tick mode, get_result and stop(). Each test has its own
// namespace; every wait is bounded.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/action.hpp>
#include <horus/service.hpp>
#include <horus/topic_registry.hpp>
#include <horus_test/action/navigate.hpp>

#include "action_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::ActionPolicy;
using horus::GoalState;
using horus_test::action::Navigate;

constexpr auto kLong = 5s;

Navigate::Goal navigate_goal(double x, double y, std::uint32_t count = 20,
                             std::uint32_t period_us = 2000) {
  Navigate::Goal goal{};
  goal.x = x;
  goal.y = y;
  goal.feedback_count = count;
  goal.period_us = period_us;
  return goal;
}

using ActionServerTest = action_test::ActionTest;
using action_test::drive;

TEST_F(ActionServerTest, NavigateGoalSendsTwentyFeedbacksThenSucceeds) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  horus::ActionClient<Navigate> client;
  std::mutex seen_mutex;  // the callbacks run on the client's pump thread
  std::vector<std::uint32_t> steps;
  std::vector<GoalState> states;
  horus::GoalCallbacks<Navigate> callbacks;
  callbacks.on_feedback = [&](const Navigate::Feedback& feedback) {
    std::lock_guard lock(seen_mutex);
    steps.push_back(feedback.step);
  };
  callbacks.on_state = [&](GoalState state, std::string_view) {
    std::lock_guard lock(seen_mutex);
    states.push_back(state);
  };
  auto handle = client.send_goal(navigate_goal(3.0, 4.0), kLong, callbacks);
  ASSERT_TRUE(handle) << handle.error().to_string();
  EXPECT_EQ(handle->id().client_id, client.client_id());
  EXPECT_EQ(handle->id().sequence, 1u);
  auto outcome = handle->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Succeeded);
  EXPECT_EQ(outcome->reason, "");
  EXPECT_TRUE(outcome->result.reached);
  EXPECT_EQ(outcome->result.final_x, 3.0);
  EXPECT_EQ(outcome->result.feedback_sent, 20u);
  std::vector<std::uint32_t> pulled;
  std::optional<Navigate::Feedback> last;
  while (auto feedback = handle->try_feedback()) {
    pulled.push_back(feedback->step);
    last = feedback;
  }
  ASSERT_EQ(pulled.size(), 20u);
  for (std::uint32_t i = 0; i < 20; ++i) EXPECT_EQ(pulled[i], i + 1);
  EXPECT_EQ(last->remaining_m, 0.0);
  EXPECT_EQ(handle->latest_feedback()->step, 20u);
  EXPECT_EQ(handle->lost_feedback(), 0u);
  // The result and its callback both come from the pump: the callbacks ran by now or soon.
  for (auto until = std::chrono::steady_clock::now() + kLong;;) {
    {
      std::lock_guard lock(seen_mutex);
      if (!states.empty() && states.back() == GoalState::Succeeded) break;
    }
    ASSERT_LT(std::chrono::steady_clock::now(), until);
    std::this_thread::sleep_for(1ms);
  }
  {
    std::lock_guard lock(seen_mutex);
    EXPECT_EQ(steps.size(), 20u);
    // Accepted may come before the answer or not at all (the pump saw Executing first).
    EXPECT_NE(std::find(states.begin(), states.end(), GoalState::Executing), states.end());
  }
  const horus::ActionServerStats stats = server.stats();
  EXPECT_EQ(stats.goals, 1u);
  EXPECT_EQ(stats.accepted, 1u);
  EXPECT_EQ(stats.succeeded, 1u);
  EXPECT_EQ(stats.feedback_sent, 20u);
}

TEST_F(ActionServerTest, AbortWithReasonAndGetResultAfterTheEnd) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  horus::ActionClient<Navigate> client;
  Navigate::Goal goal = navigate_goal(1.0, 0.0);
  goal.abort_with = "blocked by a pallet";
  auto handle = client.send_goal(goal, kLong);
  ASSERT_TRUE(handle);
  auto outcome = handle->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Aborted);
  EXPECT_EQ(outcome->reason, "blocked by a pallet");

  horus::ServiceClient<Navigate::GetResult> get_result;
  Navigate::GetResult::Request request{};
  request.goal_id = handle->id().to_bytes();
  auto answer = get_result.call(request, kLong);
  ASSERT_TRUE(answer);
  EXPECT_EQ(answer->state, static_cast<std::uint8_t>(GoalState::Aborted));
  EXPECT_EQ(answer->reason, "blocked by a pallet");

  request.goal_id = horus::GoalId{42, 7}.to_bytes();
  answer = get_result.call(request, kLong);
  ASSERT_TRUE(answer);
  EXPECT_EQ(answer->state, static_cast<std::uint8_t>(GoalState::Unknown));
}

TEST_F(ActionServerTest, RejectPolicyRefusesASecondClientWhileOneExecutes) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  horus::ActionClient<Navigate> first;
  horus::ActionClient<Navigate> second;
  auto running = first.send_goal(navigate_goal(1.0, 0.0, 20, 10000), kLong);
  ASSERT_TRUE(running);
  auto refused = second.send_goal(navigate_goal(2.0, 0.0), kLong);
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->state(), GoalState::Rejected);
  EXPECT_EQ(refused->reason(), "busy: goal " + running->id().to_string() + " is executing");
  EXPECT_EQ(refused->try_result()->state, GoalState::Rejected);
  EXPECT_EQ(running->result(kLong)->state, GoalState::Succeeded);
  EXPECT_EQ(server.stats().rejected, 1u);
}

TEST_F(ActionServerTest, PreemptPolicyCancelsTheRunningGoalForTheNewOne) {
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_execute(drive)
                    .policy(ActionPolicy::Preempt)
                    .build();
  horus::ActionClient<Navigate> first;
  horus::ActionClient<Navigate> second;
  auto old_goal = first.send_goal(navigate_goal(1.0, 0.0, 200, 5000), kLong);
  ASSERT_TRUE(old_goal);
  ASSERT_TRUE(old_goal->next_feedback(kLong));
  auto new_goal = second.send_goal(navigate_goal(2.0, 0.0, 3, 1000), kLong);
  ASSERT_TRUE(new_goal);
  EXPECT_NE(new_goal->state(), GoalState::Rejected);
  auto old_outcome = old_goal->result(kLong);
  ASSERT_TRUE(old_outcome);
  EXPECT_EQ(old_outcome->state, GoalState::Canceled);
  EXPECT_EQ(old_outcome->reason, "preempted by goal " + new_goal->id().to_string());
  EXPECT_LT(old_outcome->result.feedback_sent, 200u);
  auto new_outcome = new_goal->result(kLong);
  ASSERT_TRUE(new_outcome);
  EXPECT_EQ(new_outcome->state, GoalState::Succeeded);
  EXPECT_EQ(new_outcome->result.feedback_sent, 3u);
}

TEST_F(ActionServerTest, QueuePolicyRunsGoalsInOrderUpToItsCapacity) {
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_execute(drive)
                    .policy(ActionPolicy::Queue)
                    .queue_capacity(1)
                    .build();
  horus::ActionClient<Navigate> first;
  horus::ActionClient<Navigate> second;
  auto running = first.send_goal(navigate_goal(1.0, 0.0, 10, 5000), kLong);
  ASSERT_TRUE(running);
  ASSERT_TRUE(running->next_feedback(kLong));  // executing: the queue is empty again
  auto queued = second.send_goal(navigate_goal(2.0, 0.0, 2, 1000), kLong);
  ASSERT_TRUE(queued);
  EXPECT_NE(queued->state(), GoalState::Rejected);
  auto overflow = second.send_goal(navigate_goal(3.0, 0.0, 2, 1000), kLong);
  ASSERT_TRUE(overflow);
  EXPECT_EQ(overflow->state(), GoalState::Rejected);
  EXPECT_EQ(overflow->reason(), "queue full (1 goals waiting)");
  auto first_outcome = running->result(kLong);
  ASSERT_TRUE(first_outcome);
  EXPECT_EQ(first_outcome->state, GoalState::Succeeded);
  auto queued_outcome = queued->result(kLong);
  ASSERT_TRUE(queued_outcome);
  EXPECT_EQ(queued_outcome->state, GoalState::Succeeded);
  EXPECT_EQ(queued_outcome->result.final_x, 2.0);
}

TEST_F(ActionServerTest, CancelOfAWaitingGoalEndsItAtOnce) {
  auto server =
      horus::ActionServerBuilder<Navigate>().on_execute(drive).policy(ActionPolicy::Queue).build();
  horus::ActionClient<Navigate> client;
  auto running = client.send_goal(navigate_goal(1.0, 0.0, 1000, 5000), kLong);
  auto waiting = client.send_goal(navigate_goal(2.0, 0.0), kLong);
  ASSERT_TRUE(running && waiting);
  auto code = waiting->cancel(kLong);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, horus::CancelCode::Accepted);
  auto outcome = waiting->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Canceled);
  EXPECT_EQ(outcome->reason, "canceled by a client");
  EXPECT_EQ(outcome->result.feedback_sent, 0u);  // it never ran
  EXPECT_FALSE(running->is_done());
  code = running->cancel(kLong);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, horus::CancelCode::Accepted);
  EXPECT_EQ(running->result(kLong)->state, GoalState::Canceled);
}

TEST_F(ActionServerTest, OnGoalAndOnCancelDecide) {
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_goal([](const Navigate::Goal& goal) {
                      return goal.x < 0 ? horus::GoalDecision::reject("x must not be negative")
                                        : horus::GoalDecision::accept();
                    })
                    .on_cancel([](const horus::ServerGoal<Navigate>&) { return false; })
                    .on_execute(drive)
                    .build();
  horus::ActionClient<Navigate> client;
  auto refused = client.send_goal(navigate_goal(-1.0, 0.0), kLong);
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->state(), GoalState::Rejected);
  EXPECT_EQ(refused->reason(), "x must not be negative");
  auto unknown = refused->cancel(kLong);  // a rejected goal never entered the server's table
  ASSERT_TRUE(unknown);
  EXPECT_EQ(*unknown, horus::CancelCode::UnknownGoal);
  auto handle = client.send_goal(navigate_goal(1.0, 0.0, 5, 1000), kLong);
  ASSERT_TRUE(handle);
  auto code = handle->cancel(kLong);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, horus::CancelCode::Rejected);
  EXPECT_EQ(handle->result(kLong)->state, GoalState::Succeeded);
  code = handle->cancel(kLong);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, horus::CancelCode::AlreadyDone);
}

TEST_F(ActionServerTest, TickModeHandsOutGoalsOneAtATime) {
  auto server = horus::ActionServerBuilder<Navigate>().policy(ActionPolicy::Queue).build();
  horus::ActionClient<Navigate> client;
  EXPECT_FALSE(server.next_goal());
  auto first = client.send_goal(navigate_goal(1.0, 0.0), kLong);
  auto second = client.send_goal(navigate_goal(2.0, 0.0), kLong);
  ASSERT_TRUE(first && second);
  std::optional<horus::ServerGoal<Navigate>> goal = server.next_goal();
  ASSERT_TRUE(goal);
  EXPECT_EQ(goal->id(), first->id());
  EXPECT_EQ(goal->state(), GoalState::Executing);
  EXPECT_FALSE(server.next_goal());  // one executes at a time
  EXPECT_TRUE(goal->publish_feedback({1, 0.5}));
  ASSERT_TRUE(first->next_feedback(kLong));
  goal->succeed({true, 1.0, 0.0, 1});
  EXPECT_FALSE(goal->publish_feedback({2, 0.0}));
  EXPECT_EQ(first->result(kLong)->state, GoalState::Succeeded);
  goal = server.next_goal();
  ASSERT_TRUE(goal);
  EXPECT_EQ(goal->id(), second->id());
  goal.reset();  // dropped without an outcome
  auto outcome = second->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Aborted);
  EXPECT_EQ(outcome->reason, "the goal was dropped without an outcome");
}

TEST_F(ActionServerTest, ExecuteReturningWithoutAnOutcomeAborts) {
  auto server = horus::ActionServerBuilder<Navigate>()
                    .on_execute([](horus::ServerGoal<Navigate>&) {})
                    .build();
  horus::ActionClient<Navigate> client;
  auto handle = client.send_goal(navigate_goal(1.0, 0.0), kLong);
  ASSERT_TRUE(handle);
  auto outcome = handle->result(kLong);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->state, GoalState::Aborted);
  EXPECT_EQ(outcome->reason, "on_execute returned without an outcome");
}

TEST_F(ActionServerTest, StopAbortsLiveGoalsAndWithdraws) {
  auto server =
      horus::ActionServerBuilder<Navigate>().on_execute(drive).policy(ActionPolicy::Queue).build();
  horus::ActionClient<Navigate> client;
  auto running = client.send_goal(navigate_goal(1.0, 0.0, 1000, 5000), kLong);
  auto waiting = client.send_goal(navigate_goal(2.0, 0.0), kLong);
  ASSERT_TRUE(running && waiting);
  ASSERT_TRUE(running->next_feedback(kLong));
  server.stop();
  EXPECT_FALSE(server.is_running());
  for (auto* handle : {&*running, &*waiting}) {
    auto outcome = handle->result(kLong);
    ASSERT_TRUE(outcome);
    EXPECT_EQ(outcome->state, GoalState::Aborted);
    EXPECT_EQ(outcome->reason, "the action server stopped");
  }
  auto late = client.send_goal(navigate_goal(1.0, 0.0), kLong);
  ASSERT_FALSE(late);
  EXPECT_EQ(late.error().kind(), horus::ServiceErrorKind::NoServer);
}

TEST_F(ActionServerTest, SecondServerOfTheActionIsRefused) {
  auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
  EXPECT_THROW(horus::ActionServerBuilder<Navigate>().on_execute(drive).build(), horus::Error);
}

}  // namespace
