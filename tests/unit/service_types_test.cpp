// The value types of the services API and the identity of the frames that carry services.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>

#include <horus/detail/service_channel.hpp>
#include <horus/detail/service_frame.hpp>
#include <horus/service_error.hpp>
#include <horus/service_message.hpp>
#include <horus/service_result.hpp>
#include <horus/service_retry.hpp>
#include <service_test/compute.hpp>
#include <service_test/echo.hpp>
#include <service_test/get_robot_pose.hpp>

namespace {

using namespace std::chrono_literals;
using horus::RetryConfig;
using horus::ServiceError;
using horus::ServiceErrorKind;
using horus::ServiceRequest;
using horus::ServiceResponse;
using horus::ServiceResult;
using horus::detail::ServiceRequestFrame;
using horus::detail::ServiceResponseFrame;
using service_test::ComputeRequest;
using service_test::ComputeResponse;
using service_test::EchoResponse;
using service_test::GetRobotPoseRequest;
using service_test::GetRobotPoseResponse;

TEST(ServiceError, OnlyTimeoutAndTransportAreTransient) {
  EXPECT_TRUE(ServiceError::timeout().is_transient());
  EXPECT_TRUE(ServiceError::transport("lost").is_transient());
  EXPECT_FALSE(ServiceError::no_server().is_transient());
  EXPECT_FALSE(ServiceError::service_failed("bad").is_transient());
}

TEST(ServiceError, TextNamesTheKindAndTheMessage) {
  EXPECT_EQ(ServiceError::timeout().to_string(), "Timeout");
  EXPECT_EQ(ServiceError::service_failed("unknown robot").to_string(),
            "ServiceFailed: unknown robot");
  EXPECT_EQ(ServiceError::no_server().kind(), ServiceErrorKind::NoServer);
  EXPECT_EQ(ServiceError::transport("x").message(), "x");
}

TEST(ServiceResult, HoldsAValueOrAnError) {
  ServiceResult<int> value = 7;
  ASSERT_TRUE(value.has_value());
  EXPECT_EQ(value.value(), 7);
  EXPECT_EQ(*value, 7);
  EXPECT_THROW(static_cast<void>(value.error()), horus::Error);

  ServiceResult<int> error = ServiceError::timeout();
  ASSERT_FALSE(error);
  EXPECT_EQ(error.error().kind(), ServiceErrorKind::Timeout);
  EXPECT_EQ(error.value_or(3), 3);
  EXPECT_THROW(static_cast<void>(error.value()), horus::Error);
}

TEST(ServiceResult, AnEmptyOptionalIsAValue) {
  ServiceResult<std::optional<int>> none = std::nullopt;
  ASSERT_TRUE(none.has_value());
  EXPECT_FALSE(none->has_value());
}

TEST(RetryConfig, DefaultIsThreeRetriesFromTenMillisecondsDoubling) {
  const RetryConfig config;
  EXPECT_EQ(config.max_retries(), 3U);
  EXPECT_EQ(config.backoff(0), 10ms);
  EXPECT_EQ(config.backoff(1), 20ms);
  EXPECT_EQ(config.backoff(2), 40ms);
}

TEST(RetryConfig, BackoffGrowsByTheMultiplierUpToTheCap) {
  const RetryConfig config = RetryConfig(5, 50ms).multiplier(3.0).max_backoff(1s);
  EXPECT_EQ(config.max_retries(), 5U);
  EXPECT_EQ(config.backoff(0), 50ms);
  EXPECT_EQ(config.backoff(1), 150ms);
  EXPECT_EQ(config.backoff(2), 450ms);
  EXPECT_EQ(config.backoff(3), 1s);
  EXPECT_EQ(config.backoff(30), 1s);
}

TEST(RetryConfig, RejectsAShrinkingMultiplierAndNegativeDurations) {
  RetryConfig config;
  EXPECT_THROW(config.multiplier(0.5), horus::Error);
  EXPECT_THROW(config.initial_backoff(-1ms), horus::Error);
  EXPECT_THROW(config.max_backoff(-1ms), horus::Error);
}

TEST(ServiceFrames, ArePodExactlyWhenTheirPayloadIs) {
  static_assert(horus::PodMessage<ServiceRequestFrame<ComputeRequest>>);
  static_assert(horus::PodMessage<ServiceResponseFrame<ComputeResponse>>);
  static_assert(horus::SerializedMessage<ServiceRequestFrame<GetRobotPoseRequest>>);
  static_assert(horus::PodMessage<ServiceResponseFrame<GetRobotPoseResponse>>);
  static_assert(horus::SerializedMessage<ServiceResponseFrame<EchoResponse>>);
  EXPECT_EQ(offsetof(ServiceResponseFrame<ComputeResponse>, payload), 256U);
}

TEST(ServiceFrames, NameAndFingerprintFollowThePayload) {
  using Info = horus::TypeInfo<ServiceRequestFrame<GetRobotPoseRequest>>;
  EXPECT_EQ(Info::name, "horus.ServiceRequest<service_test.GetRobotPoseRequest>");
  EXPECT_NE(Info::schema.find("payload: service_test.GetRobotPoseRequest,"),
            std::string_view::npos);
  EXPECT_NE(Info::schema.find("message service_test.GetRobotPoseRequest {"),
            std::string_view::npos);
  EXPECT_NE(Info::fingerprint, horus::TypeInfo<ServiceRequestFrame<ComputeRequest>>::fingerprint);
  EXPECT_NE(horus::TypeInfo<ServiceResponseFrame<ComputeResponse>>::fingerprint,
            horus::TypeInfo<ServiceResponseFrame<GetRobotPoseResponse>>::fingerprint);
}

TEST(ServiceFrames, SerializedFramesRoundTrip) {
  ServiceRequestFrame<GetRobotPoseRequest> frame{3, 9, 2, GetRobotPoseRequest{"arm_1"}};
  const auto bytes = horus::encode(frame);
  EXPECT_EQ(horus::decode<ServiceRequestFrame<GetRobotPoseRequest>>(bytes), frame);
}

TEST(ServiceFrames, PodErrorTextIsCutAtACharacterBoundary) {
  ServiceResponseFrame<ComputeResponse> frame;
  // 235 ASCII bytes then a 2-byte character: it does not fit whole in 236 bytes.
  const std::string text = std::string(235, 'x') + "\xc3\xa9" + "tail";
  horus::detail::set_error(frame, text);
  EXPECT_EQ(std::string_view(frame.error), std::string(235, 'x'));

  ServiceResponseFrame<EchoResponse> serialized;
  horus::detail::set_error(serialized, text);
  EXPECT_EQ(serialized.error, text);
}

TEST(ServiceResponse, SuccessCarriesThePayloadAndFailureTheError) {
  const auto done = ServiceResponse<ComputeResponse>::success(4, ComputeResponse{5, 77});
  EXPECT_EQ(done.request_id, 4U);
  EXPECT_TRUE(done.ok);
  ASSERT_TRUE(done.payload.has_value());
  EXPECT_EQ(done.payload->sum, 5);
  EXPECT_FALSE(done.error.has_value());

  const auto failed = ServiceResponse<ComputeResponse>::failure(6, "unknown robot");
  EXPECT_EQ(failed.request_id, 6U);
  EXPECT_FALSE(failed.ok);
  EXPECT_FALSE(failed.payload.has_value());
  EXPECT_EQ(failed.error, "unknown robot");
}

TEST(ServiceResponse, BecomesTheCallersResult) {
  ServiceResult<ComputeResponse> value =
      ServiceResponse<ComputeResponse>::success(1, ComputeResponse{9, 1}).into_result();
  ASSERT_TRUE(value);
  EXPECT_EQ(value->sum, 9);

  ServiceResult<ComputeResponse> failed =
      ServiceResponse<ComputeResponse>::failure(1, "no such key").into_result();
  ASSERT_FALSE(failed);
  EXPECT_EQ(failed.error().kind(), ServiceErrorKind::ServiceFailed);
  EXPECT_EQ(failed.error().message(), "no such key");

  ServiceResponse<ComputeResponse> malformed;
  malformed.ok = true;
  ServiceResult<ComputeResponse> empty = std::move(malformed).into_result();
  ASSERT_FALSE(empty) << "a success without a payload is not a value";
  EXPECT_EQ(empty.error().kind(), ServiceErrorKind::ServiceFailed);
}

TEST(ServiceFrames, AForwardingServersStatusIsTheKindTheCallerGets) {
  // A server that forwards calls (the DDS bridge's stand-in for a remote service) answers with
  // the kind its own call failed with; the caller sees that kind, with the text.
  using Channel = horus::detail::ServiceChannel<service_test::Compute>;
  const auto answer = [](std::uint32_t status) {
    ServiceResponseFrame<ComputeResponse> frame{};
    frame.status = status;
    frame.error.try_assign("on the server's host: why");
    return Channel::to_result(std::move(frame));
  };
  for (const auto& [status, kind] :
       {std::pair{horus::detail::kStatusNoServer, ServiceErrorKind::NoServer},
        std::pair{horus::detail::kStatusTimeout, ServiceErrorKind::Timeout},
        std::pair{horus::detail::kStatusTransport, ServiceErrorKind::Transport},
        std::pair{horus::detail::kStatusFailed, ServiceErrorKind::ServiceFailed},
        std::pair{std::uint32_t{99}, ServiceErrorKind::ServiceFailed}}) {
    const ServiceResult<ComputeResponse> result = answer(status);
    ASSERT_FALSE(result) << status;
    EXPECT_EQ(result.error().kind(), kind) << status;
    EXPECT_EQ(result.error().message(), "on the server's host: why") << status;
  }
  EXPECT_TRUE(answer(horus::detail::kStatusOk));
}

TEST(ServiceFrames, CarryTheRequestAndResponseShapesBothWays) {
  const ServiceRequestFrame<GetRobotPoseRequest> request = horus::detail::request_frame(
      11, 2, ServiceRequest<GetRobotPoseRequest>{8, GetRobotPoseRequest{"arm_1"}});
  EXPECT_EQ(request, (ServiceRequestFrame<GetRobotPoseRequest>{11, 8, 2, {"arm_1"}}));

  ServiceResponseFrame<EchoResponse> answer = horus::detail::response_frame(
      11, ServiceResponse<EchoResponse>::success(8, EchoResponse{"hello"}));
  EXPECT_EQ(answer.client_id, 11U);
  EXPECT_EQ(answer.status, horus::detail::kStatusOk);
  EXPECT_EQ(horus::detail::response_of(std::move(answer)),
            ServiceResponse<EchoResponse>::success(8, EchoResponse{"hello"}));

  ServiceResponseFrame<ComputeResponse> refusal = horus::detail::response_frame(
      11, ServiceResponse<ComputeResponse>::failure(9, std::string(300, 'e')));
  EXPECT_EQ(refusal.status, horus::detail::kStatusFailed);
  EXPECT_EQ(horus::detail::response_of(std::move(refusal)),
            ServiceResponse<ComputeResponse>::failure(9, std::string(236, 'e')))
      << "a POD frame cuts the text to its capacity";
}

}  // namespace
