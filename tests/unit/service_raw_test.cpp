// Byte-level services (horus/raw_service.hpp) against typed ones: the frames are the typed
// frames, and a raw client or server meets a typed counterpart, POD and serialized. Each test
// has its own namespace; every wait is bounded.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <horus/codec.hpp>
#include <horus/detail/service_frame.hpp>
#include <horus/raw_service.hpp>
#include <horus/service.hpp>
#include <horus/topic_registry.hpp>
#include <horus/type_description.hpp>
#include <service_test/compute.hpp>
#include <service_test/echo.hpp>

namespace {

using namespace std::chrono_literals;
using horus::ServiceErrorKind;
using service_test::Compute;
using service_test::ComputeRequest;
using service_test::ComputeResponse;
using service_test::Echo;
using service_test::EchoRequest;
using service_test::EchoResponse;

constexpr auto kLong = 10s;

template <class T>
std::vector<std::byte> bytes_of(const T& message) {
  const std::vector<std::uint8_t> encoded = horus::encode(message);
  const auto* first = reinterpret_cast<const std::byte*>(encoded.data());
  return {first, first + encoded.size()};
}

template <class T>
T message_of(const std::vector<std::byte>& bytes) {
  return horus::decode<T>(
      std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
}

class ServiceRawTest : public ::testing::Test {
 protected:
  ServiceRawTest() {
    name_ = "svcraw" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ::setenv("HORUS_NAMESPACE", name_.c_str(), 1);
    horus::remove_namespace(name_);
  }
  ~ServiceRawTest() override {
    horus::remove_namespace(name_);
    ::unsetenv("HORUS_NAMESPACE");
  }

  std::string name_;
};

template <class Frame, class Payload>
void expect_frame_type_of(bool response) {
  using Info = horus::TypeInfo<Frame>;
  const horus::TypeIdentity frame =
      horus::service_frame_type(horus::type_identity<Payload>(), response);
  EXPECT_EQ(frame.name, Info::name);
  EXPECT_EQ(frame.schema, Info::schema);
  EXPECT_EQ(frame.fingerprint, Info::fingerprint);
  EXPECT_EQ(frame.is_pod, Info::is_pod);
  if (Info::is_pod) {
    EXPECT_EQ(frame.size, Info::size);
    EXPECT_EQ(frame.alignment, Info::alignment);
  }
  EXPECT_EQ(frame.description, std::string_view(Info::description));
}

/// The description of a frame type is the frame's: its identity, its fields with the struct's
/// layout, its payload's description beside it; a message written from it is a frame.
template <class Frame, class Payload>
void expect_described_frame() {
  using Info = horus::TypeInfo<Frame>;
  SCOPED_TRACE(std::string(Info::name));
  const horus::TypeDescription description = horus::TypeDescription::decode(Info::description);
  EXPECT_EQ(description.root, Info::name);
  const horus::MessageType& frame = description.root_message();
  EXPECT_EQ(frame.package, "horus");
  EXPECT_EQ(frame.fingerprint, Info::fingerprint);
  EXPECT_EQ(frame.schema, Info::schema);
  EXPECT_EQ(frame.is_pod, Info::is_pod);
  ASSERT_NE(description.find_message(horus::TypeInfo<Payload>::name), nullptr);
  std::vector<std::string> names;
  std::vector<std::size_t> offsets;
  Frame value{};
  Info::visit(value, [&](std::string_view name, auto& field) {
    names.emplace_back(name);
    offsets.push_back(static_cast<std::size_t>(reinterpret_cast<const std::byte*>(&field) -
                                               reinterpret_cast<const std::byte*>(&value)));
  });
  ASSERT_EQ(frame.fields.size(), names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(frame.fields[i].name, names[i]);
    if (Info::is_pod) {
      EXPECT_EQ(frame.fields[i].offset, offsets[i]) << names[i];
    }
  }
  if (Info::is_pod) {
    EXPECT_EQ(frame.size, sizeof(Frame));
    EXPECT_EQ(frame.alignment, alignof(Frame));
  }
  const std::vector<std::uint8_t> zero = horus::zero_message(description, frame);
  EXPECT_EQ(horus::decode<Frame>(zero), Frame{});
  // The description written back is byte for byte the one it was read from.
  EXPECT_EQ(description.encode(), std::string_view(Info::description));
}

TEST(ServiceRawFrames, AreDescribedFromTheirPayloadsDescriptions) {
  using horus::detail::ServiceRequestFrame;
  using horus::detail::ServiceResponseFrame;
  expect_described_frame<ServiceRequestFrame<ComputeRequest>, ComputeRequest>();
  expect_described_frame<ServiceResponseFrame<ComputeResponse>, ComputeResponse>();
  expect_described_frame<ServiceRequestFrame<EchoRequest>, EchoRequest>();
  expect_described_frame<ServiceResponseFrame<EchoResponse>, EchoResponse>();
}

TEST(ServiceRawFrames, TheRegistrationIsDescribedWithItsLayout) {
  using Info = horus::TypeInfo<horus::ServiceRegistration>;
  const horus::TypeDescription description = horus::TypeDescription::decode(Info::description);
  const horus::MessageType& registration = description.root_message();
  EXPECT_EQ(registration.name, Info::name);
  EXPECT_EQ(registration.fingerprint, Info::fingerprint);
  EXPECT_EQ(registration.schema, Info::schema);
  EXPECT_EQ(registration.size, sizeof(horus::ServiceRegistration));
  ASSERT_EQ(registration.fields.size(), Info::field_count);
  EXPECT_EQ(registration.fields[2].offset, offsetof(horus::ServiceRegistration, request_type));
  EXPECT_EQ(registration.fields[3].offset, offsetof(horus::ServiceRegistration, response_type));
  EXPECT_EQ(registration.fields[4].offset, offsetof(horus::ServiceRegistration, server_pid));
  EXPECT_TRUE(registration.padding.empty());
}

TEST(ServiceRawFrames, APayloadDescriptionOfAnotherTypeIsRefused) {
  horus::TypeIdentity payload = horus::type_identity<EchoRequest>();
  payload.description = horus::type_identity<ComputeRequest>().description;
  EXPECT_THROW(horus::service_frame_type(payload, false), horus::TypeDescriptionError);
}

// The frames' identity as a reply topic records it, read back into the payload's: POD and
// serialized, requests and responses.
template <class Payload>
void expect_payload_read_back(bool response) {
  const horus::TypeIdentity payload = horus::type_identity<Payload>();
  const horus::TypeIdentity read =
      horus::service_payload_type(horus::service_frame_type(payload, response), response);
  EXPECT_EQ(read.name, payload.name);
  EXPECT_EQ(read.fingerprint, payload.fingerprint);
  EXPECT_EQ(read.schema, payload.schema);
  EXPECT_EQ(read.is_pod, payload.is_pod);
  EXPECT_EQ(read.size, payload.is_pod ? payload.size : 0U);
  EXPECT_EQ(read.alignment, payload.is_pod ? payload.alignment : 1U);
  EXPECT_EQ(horus::TypeDescription::decode(read.description).encode(),
            horus::TypeDescription::decode(payload.description).encode());
}

TEST(ServiceRawFrames, GiveTheirPayloadTypeBack) {
  expect_payload_read_back<ComputeRequest>(false);
  expect_payload_read_back<ComputeResponse>(true);
  expect_payload_read_back<EchoRequest>(false);
  expect_payload_read_back<EchoResponse>(true);
}

TEST(ServiceRawFrames, WhatIsNotTheirFramesGivesNoPayloadType) {
  const horus::TypeIdentity requests =
      horus::service_frame_type(horus::type_identity<EchoRequest>(), false);
  EXPECT_THROW(horus::service_payload_type(requests, true), horus::Error);  // not responses
  EXPECT_THROW(horus::service_payload_type(horus::type_identity<EchoRequest>(), false),
               horus::Error);
  horus::TypeIdentity forged = requests;
  forged.fingerprint ^= 1;
  EXPECT_THROW(horus::service_payload_type(forged, false), horus::Error);
  forged = requests;
  forged.description =
      horus::service_frame_type(horus::type_identity<ComputeRequest>(), false).description;
  EXPECT_THROW(horus::service_payload_type(forged, false), horus::Error);
}

TEST(ServiceRawFrames, AreTheTypedFrames) {
  using horus::detail::ServiceRequestFrame;
  using horus::detail::ServiceResponseFrame;
  expect_frame_type_of<ServiceRequestFrame<ComputeRequest>, ComputeRequest>(false);
  expect_frame_type_of<ServiceResponseFrame<ComputeResponse>, ComputeResponse>(true);
  expect_frame_type_of<ServiceRequestFrame<EchoRequest>, EchoRequest>(false);
  expect_frame_type_of<ServiceResponseFrame<EchoResponse>, EchoResponse>(true);
  EXPECT_TRUE(horus::is_service_type("horus.ServiceRequest<service_test.EchoRequest>"));
  EXPECT_TRUE(horus::is_service_type("horus.ServiceRegistration"));
  EXPECT_FALSE(horus::is_service_type("service_test.EchoRequest"));
}

TEST(ServiceRawFrames, ReadWhatTheTypedFramesHold) {
  const horus::ServiceFrameCodec echoes(horus::type_identity<EchoResponse>(), true);
  horus::detail::ServiceResponseFrame<EchoResponse> typed{};
  typed.client_id = 300;
  typed.request_id = 70000;
  typed.status = horus::detail::kStatusTimeout;
  typed.error = "late";
  const std::vector<std::byte> frame = bytes_of(typed);
  const std::optional<horus::RawResponseFrame> read = echoes.read_response(frame);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->client_id, 300U);
  EXPECT_EQ(read->request_id, 70000U);
  EXPECT_EQ(read->failure, horus::ServiceError::timeout("late"));
  const auto ids = horus::service_frame_ids(frame, false);
  ASSERT_TRUE(ids);
  EXPECT_EQ(*ids, (std::array<std::uint64_t, 3>{300, 70000, horus::detail::kStatusTimeout}));

  // A failure made from any frame of the type is the typed failure frame.
  const std::vector<std::byte> failed = horus::with_service_failure(
      frame, false, {5, 6, 0}, horus::ServiceError::no_server("none there"));
  auto decoded = message_of<horus::detail::ServiceResponseFrame<EchoResponse>>(failed);
  EXPECT_EQ(decoded.client_id, 5U);
  EXPECT_EQ(decoded.request_id, 6U);
  EXPECT_EQ(decoded.status, horus::detail::kStatusNoServer);
  EXPECT_EQ(decoded.error, "none there");

  const horus::ServiceFrameCodec computes(horus::type_identity<ComputeRequest>(), false);
  const ComputeRequest request{4, 5, 0, 0};
  const std::vector<std::byte> pod = computes.request({1, 2, 3}, bytes_of(request));
  const auto typed_request = message_of<horus::detail::ServiceRequestFrame<ComputeRequest>>(pod);
  EXPECT_EQ(typed_request, (horus::detail::ServiceRequestFrame<ComputeRequest>{1, 2, 3, request}));
  const std::vector<std::uint64_t> others{8, 9};
  const auto moved =
      horus::service_frame_ids(horus::with_service_frame_ids(pod, true, others), true);
  EXPECT_EQ(*moved, (std::array<std::uint64_t, 3>{8, 9, 3}));
  EXPECT_FALSE(computes.read_request(std::span(pod).first(10)));
}

TEST_F(ServiceRawTest, RawClientCallsATypedServerPodAndSerialized) {
  auto compute =
      horus::ServiceServerBuilder<Compute>()
          .on_request([](const ComputeRequest& r) -> horus::HandlerResult<ComputeResponse> {
            if (r.behaviour == 1) return std::string("cannot add ") + std::to_string(r.a);
            return ComputeResponse{r.a + r.b, 7};
          })
          .build();
  auto echo = horus::ServiceServerBuilder<Echo>()
                  .on_request([](const EchoRequest& r) { return EchoResponse{r.text + r.text}; })
                  .build();
  horus::RawServiceClient computes(horus::raw_service_type<Compute>());
  horus::RawServiceClient echoes(horus::raw_service_type<Echo>());
  auto sum = computes.call(bytes_of(ComputeRequest{2, 40, 0, 0}), kLong);
  ASSERT_TRUE(sum) << sum.error().to_string();
  EXPECT_EQ(message_of<ComputeResponse>(*sum).sum, 42);
  auto refused = computes.call(bytes_of(ComputeRequest{3, 0, 0, 1}), kLong);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error(), horus::ServiceError::service_failed("cannot add 3"));
  auto twice = echoes.call(bytes_of(EchoRequest{"ab"}), kLong);
  ASSERT_TRUE(twice) << twice.error().to_string();
  EXPECT_EQ(message_of<EchoResponse>(*twice).text, "abab");
}

TEST_F(ServiceRawTest, TypedClientCallsARawServerWhichAnswersWithEveryKind) {
  horus::RawServiceServer server(horus::raw_service_type<Echo>());
  std::thread serving([&server] {
    while (!server.stopped()) {
      std::optional<horus::RawServiceServer::Request> request = server.next(1s);
      if (!request) continue;
      const std::string text = message_of<EchoRequest>(request->payload).text;
      if (text == "fail") {
        server.fail(request->caller, horus::ServiceError::service_failed("no"));
      } else if (text == "elsewhere") {
        server.fail(request->caller, horus::ServiceError::timeout("the other server was late"));
      } else {
        server.answer(request->caller, bytes_of(EchoResponse{text + "!"}));
      }
    }
  });
  horus::ServiceClient<Echo> client;
  auto answered = client.call(EchoRequest{"hi"}, kLong);
  ASSERT_TRUE(answered) << answered.error().to_string();
  EXPECT_EQ(answered->text, "hi!");
  EXPECT_EQ(client.call(EchoRequest{"fail"}, kLong).error(),
            horus::ServiceError::service_failed("no"));
  EXPECT_EQ(client.call(EchoRequest{"elsewhere"}, kLong).error(),
            horus::ServiceError::timeout("the other server was late"));
  server.stop();
  serving.join();
  server.withdraw();
  EXPECT_EQ(client.call(EchoRequest{"hi"}, kLong).error().kind(), ServiceErrorKind::NoServer);
}

TEST_F(ServiceRawTest, OneLiveServerAndNoServerAtOnce) {
  horus::RawServiceClient client(horus::raw_service_type<Compute>());
  const auto started = std::chrono::steady_clock::now();
  EXPECT_EQ(client.call(bytes_of(ComputeRequest{}), kLong).error().kind(),
            ServiceErrorKind::NoServer);
  EXPECT_LT(std::chrono::steady_clock::now() - started, 1s);
  EXPECT_FALSE(client.wait_for_server(20ms));
  horus::RawServiceServer server(horus::raw_service_type<Compute>());
  EXPECT_TRUE(client.wait_for_server(kLong));
  EXPECT_THROW(horus::RawServiceServer{horus::raw_service_type<Compute>()}, horus::Error);
  EXPECT_THROW(horus::ServiceServerBuilder<Compute>()
                   .on_request([](const ComputeRequest&) { return ComputeResponse{}; })
                   .build(),
               horus::Error);
  // Nobody serves: the call times out.
  EXPECT_EQ(client.call(bytes_of(ComputeRequest{}), 50ms).error().kind(),
            ServiceErrorKind::Timeout);
}

TEST_F(ServiceRawTest, AWrongSizedPodPayloadIsRefusedWithItsSizes) {
  horus::RawServiceServer server(horus::raw_service_type<Compute>());
  horus::RawServiceClient client(horus::raw_service_type<Compute>());
  const std::vector<std::byte> short_request(3);
  EXPECT_THROW(
      {
        try {
          client.call(short_request, kLong);
        } catch (const horus::Error& e) {
          EXPECT_NE(std::string(e.what()).find("not 3"), std::string::npos) << e.what();
          throw;
        }
      },
      horus::Error);
}

}  // namespace
