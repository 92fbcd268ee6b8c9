// Generated C++ for an action (tests/schemas/test_actions/navigate.haction): the action's struct
// ties together ordinary generated messages and services, named as the action runtime expects.
#include <gtest/gtest.h>

#include <array>
#include <concepts>
#include <cstdint>
#include <horus/codec.hpp>
#include <horus/msgpack.hpp>
#include <horus/service_type.hpp>
#include <horus/type_info.hpp>
#include <horus_test/action.hpp>
#include <string>
#include <type_traits>
#include <vector>

namespace {

using horus_test::action::Echo;
using horus_test::action::Navigate;

TEST(GeneratedAction, NamesTheBlocksServicesAndTopics) {
  static_assert(std::same_as<Navigate::Goal, horus_test::action::NavigateGoal>);
  static_assert(std::same_as<Navigate::Result, horus_test::action::NavigateResult>);
  static_assert(std::same_as<Navigate::Feedback, horus_test::action::NavigateFeedback>);
  static_assert(std::same_as<Navigate::GetResult::Response, Navigate::ResultMessage>);
  static_assert(Navigate::name() == "Navigate");
  static_assert(Navigate::type_name() == "horus_test.action.Navigate");
  static_assert(Navigate::feedback_topic() == "Navigate.feedback");
  static_assert(Navigate::status_topic() == "Navigate.status");
  static_assert(Navigate::result_topic() == "Navigate.result");
  static_assert(Navigate::goal_type_name() == horus::TypeInfo<Navigate::Goal>::name);
  static_assert(Navigate::result_type_name() == "horus_test.action.NavigateResult");
  static_assert(Navigate::feedback_type_name() == "horus_test.action.NavigateFeedback");
  static_assert(noexcept(Navigate::fingerprint()));
  EXPECT_NE(Navigate::fingerprint(), Echo::fingerprint());
}

TEST(GeneratedAction, ServicesAreCalledByTheActionsName) {
  static_assert(horus::Service<Navigate::SendGoal> && horus::Service<Navigate::CancelGoal> &&
                horus::Service<Navigate::GetResult>);
  static_assert(Navigate::SendGoal::name() == "Navigate.send_goal");
  static_assert(Navigate::SendGoal::request_topic() == "Navigate.send_goal.request");
  static_assert(Navigate::SendGoal::response_topic() == "Navigate.send_goal.response");
  static_assert(Navigate::CancelGoal::name() == "Navigate.cancel_goal");
  static_assert(Navigate::GetResult::name() == "Navigate.get_result");
  static_assert(Navigate::GetResult::response_type_name() ==
                "horus_test.action.NavigateResultMessage");
  SUCCEED();
}

TEST(GeneratedAction, PodActionsWrapMessagesAsPod) {
  static_assert(horus::PodMessage<Navigate::SendGoal::Request>);
  static_assert(horus::PodMessage<Navigate::FeedbackMessage>);
  static_assert(horus::PodMessage<Navigate::ResultMessage>);
  static_assert(
      horus::PodMessage<Echo::Status>);  // never holds a block: POD whatever the blocks are
  static_assert(horus::PodMessage<Echo::CancelGoal::Request> &&
                horus::PodMessage<Echo::CancelGoal::Response>);
  static_assert(horus::PodMessage<Echo::SendGoal::Response>);
  static_assert(horus::SerializedMessage<Echo::SendGoal::Request>);
  static_assert(horus::SerializedMessage<Echo::FeedbackMessage>);
  static_assert(horus::SerializedMessage<Echo::ResultMessage>);
  static_assert(std::same_as<decltype(Navigate::Status::goal_id), std::array<std::uint8_t, 16>>);
  static_assert(std::same_as<decltype(Navigate::Status::state), std::uint8_t>);
  static_assert(std::same_as<decltype(Navigate::Status::stamp_ns), std::uint64_t>);
  static_assert(std::same_as<decltype(Navigate::Status::reason), horus::FixedString<192>>);
  SUCCEED();
}

TEST(GeneratedAction, GoalDefaultsComeFromTheSchema) {
  const Navigate::Goal goal{};
  EXPECT_EQ(goal.feedback_count, 20U);
  EXPECT_EQ(goal.period_us, 5000U);
  EXPECT_EQ(goal.abort_with.view(), "");
  EXPECT_EQ(Echo::Goal{}.repeat, 3U);
}

TEST(GeneratedAction, MessagesRoundTrip) {
  Navigate::SendGoal::Request request{};
  request.goal_id[0] = 7;
  request.goal_id[15] = 9;
  request.goal.x = 2.0;
  request.goal.abort_with = "blocked";
  EXPECT_EQ(horus::decode<Navigate::SendGoal::Request>(horus::encode(request)), request);

  Echo::ResultMessage result{};
  result.goal_id[3] = 1;
  result.state = 4;
  result.reason = "done";
  result.result.text = "hello hello hello";
  EXPECT_EQ(horus::decode<Echo::ResultMessage>(horus::encode(result)), result);

  Echo::FeedbackMessage feedback{};
  feedback.feedback.partial = {"a", "b"};
  EXPECT_EQ(horus::decode<Echo::FeedbackMessage>(horus::encode(feedback)), feedback);
}

}  // namespace
