// bridges/core: what every bridge decides the same way. Globs as Python's fnmatchcase reads them
// (the Python bridge and horus.Network give the same patterns), the first matching rule, each
// name decided once and a name both directions match refused, identities compared by name and
// fingerprint, each peer allowed what a policy line names, local services called off the
// bridge's thread.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "horus/bridge/frame_source.hpp"
#include "horus/bridge/identity.hpp"
#include "horus/bridge/peer_policy.hpp"
#include "horus/bridge/service_relay.hpp"
#include "horus/bridge/topic_policy.hpp"
#include "horus/codec.hpp"
#include "horus/image.hpp"
#include "horus/pool_topic.hpp"
#include "horus/raw_service.hpp"
#include "horus/raw_topic.hpp"
#include "horus/tensor_pool.hpp"
#include "horus/topic_registry.hpp"
#include "service_test/echo.hpp"
#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::bridge::Claim;
using horus::bridge::glob_matches;
using horus::bridge::TopicIdentity;
using horus::bridge::TopicPolicy;

TEST(BridgeGlob, StarCrossesDotsAndQuestionMarkIsOneCharacter) {
  EXPECT_TRUE(glob_matches("arm.state", "arm.*"));
  EXPECT_TRUE(glob_matches("arm.joint.state", "arm.*"));
  EXPECT_TRUE(glob_matches("cmd_vel", "cmd_*"));
  EXPECT_TRUE(glob_matches("cmd_vel", "*"));
  EXPECT_TRUE(glob_matches("odom1", "odom?"));
  EXPECT_FALSE(glob_matches("odom", "odom?"));
  EXPECT_FALSE(glob_matches("arm", "arm.*"));
  EXPECT_FALSE(glob_matches("Cmd_vel", "cmd_*")) << "case counts";
}

TEST(BridgeGlob, SetsNegationAndNoEscapes) {
  EXPECT_TRUE(glob_matches("cam1", "cam[0-9]"));
  EXPECT_FALSE(glob_matches("camx", "cam[0-9]"));
  EXPECT_TRUE(glob_matches("camx", "cam[!0-9]"));
  EXPECT_TRUE(glob_matches("a\\b", "a\\b")) << "a backslash is itself, as in Python's globs";
  EXPECT_TRUE(glob_matches("-odd", "-odd"));
  EXPECT_FALSE(glob_matches("x", ""));
}

TEST(BridgeTopicPolicy, NothingIsCarriedThatNoPatternNames) {
  const TopicPolicy policy({"cmd_*"}, {"odom"});
  EXPECT_TRUE(policy.exported("cmd_vel"));
  EXPECT_FALSE(policy.exported("odom"));
  EXPECT_TRUE(policy.imported("odom"));
  EXPECT_FALSE(policy.imported("map"));
  EXPECT_FALSE(policy.exported("map"));
}

TEST(BridgeTopicPolicy, EachNameIsDecidedOnceAndBothWaysIsRefused) {
  TopicPolicy policy({"a*"}, {"ab*"});
  EXPECT_EQ(policy.claim("abc"), Claim::BothWays);
  EXPECT_EQ(policy.claim("abc"), Claim::Seen) << "refused once, then only seen";
  EXPECT_EQ(policy.claim("a1"), Claim::New);
  EXPECT_EQ(policy.claim("a1"), Claim::Seen);
  policy.settle("a2");
  EXPECT_TRUE(policy.decided("a2"));
  EXPECT_EQ(policy.claim("a2"), Claim::Seen);
  EXPECT_EQ(TopicPolicy::both_ways_refusal("abc"),
            "refusing topic 'abc': it matches both --export and --import (a bridge carries a "
            "topic one way)");
}

TEST(BridgeTopicPolicy, TheFirstMatchingDeadlineCountsAndLatchedTopicsArePatterns) {
  const TopicPolicy policy({"*"}, {}, {"map*"}, {{"cmd_*", 200ms}, {"cmd_vel", 50ms}, {"*", 2s}});
  EXPECT_EQ(policy.deadline("cmd_vel"), 200ms);
  EXPECT_EQ(policy.deadline("odom"), 2s);
  EXPECT_TRUE(policy.transient_local("map"));
  EXPECT_FALSE(policy.transient_local("odom"));
  const TopicPolicy none({"*"}, {});
  EXPECT_EQ(none.deadline("cmd_vel"), std::nullopt);
}

TEST(BridgeIdentity, TheSameTypeIsNameAndFingerprint) {
  const TopicIdentity cmd_vel{"horus.msg.CmdVel", 0x1234, "schema text"};
  EXPECT_TRUE(cmd_vel.same_type(TopicIdentity{"horus.msg.CmdVel", 0x1234, "other spelling"}));
  EXPECT_FALSE(cmd_vel.same_type(TopicIdentity{"horus.msg.CmdVel", 0x1235, "schema text"}));
  EXPECT_FALSE(cmd_vel.same_type(TopicIdentity{"horus.msg.Twist", 0x1234, "schema text"}));
}

TEST(BridgeIdentity, AMismatchNamesBothSides) {
  const TopicIdentity local{"horus.msg.Twist", 0xab, ""};
  const TopicIdentity remote{"horus.msg.CmdVel", 0xcd, ""};
  EXPECT_EQ(horus::bridge::identity_mismatch(local, local, "DDS", "x"), std::nullopt);
  EXPECT_EQ(horus::bridge::identity_mismatch(local, remote, "DDS", "horus::msg::dds_::CmdVel_"),
            "the local topic has type horus.msg.Twist (fingerprint 00000000000000ab), DDS "
            "carries horus.msg.CmdVel (fingerprint 00000000000000cd) as "
            "horus::msg::dds_::CmdVel_");
}

TEST(BridgePeerPolicy, OnlyWhatALineAllowsThatPeerIsAllowed) {
  using horus::bridge::Access;
  horus::bridge::PeerPolicy policy;
  EXPECT_TRUE(policy.empty());
  policy.add("laptop-* read arm.*", "--allow");
  policy.add("  laptop-1   call   reset ", "--allow");
  EXPECT_FALSE(policy.empty());
  EXPECT_TRUE(policy.knows("laptop-1"));
  EXPECT_FALSE(policy.knows("tablet")) << "no line names it: refused at the door";
  EXPECT_TRUE(policy.allows("laptop-2", Access::Read, "arm.joint.state"));
  EXPECT_FALSE(policy.allows("laptop-2", Access::Write, "arm.joint.state"))
      << "reading is not writing";
  EXPECT_FALSE(policy.allows("laptop-2", Access::Call, "reset")) << "the call is laptop-1's";
  EXPECT_TRUE(policy.allows("laptop-1", Access::Call, "reset"));
  EXPECT_FALSE(policy.allows("tablet", Access::Read, "arm.state"));
}

TEST(BridgePeerPolicy, ABadLineIsRefusedNamingWhereItCameFrom) {
  horus::bridge::PeerPolicy policy;
  try {
    policy.add("laptop read", "--allow");
    FAIL() << "a line without its pattern was taken";
  } catch (const std::invalid_argument& error) {
    EXPECT_STREQ(error.what(),
                 "--allow: 'laptop read' is not 'PEER read|write|call|param PATTERN'");
  }
  try {
    policy.add("laptop delete arm.*", "rules:3");
    FAIL() << "an unknown access was taken";
  } catch (const std::invalid_argument& error) {
    EXPECT_STREQ(error.what(), "rules:3: 'delete' is not read, write, call or param");
  }
  EXPECT_THROW(policy.add("laptop read arm.* extra", "--allow"), std::invalid_argument);
  EXPECT_TRUE(policy.empty()) << "a refused line adds nothing";
}

TEST(BridgePeerPolicy, AFileHoldsALineEachSkippingBlanksAndComments) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("horus_peer_policy_" + std::to_string(::getpid()));
  {
    std::ofstream file(path);
    file << "# who may do what\n\n  \nlaptop write cmd_vel\nlaptop oops\n";
  }
  horus::bridge::PeerPolicy policy;
  try {
    policy.load(path.string());
    FAIL() << "the bad fifth line was taken";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()).rfind(path.string() + ":5: ", 0), 0U) << error.what();
  }
  EXPECT_TRUE(policy.allows("laptop", horus::bridge::Access::Write, "cmd_vel"))
      << "the lines before the bad one count";
  std::filesystem::remove(path);
  EXPECT_THROW(policy.load(path.string()), std::invalid_argument) << "a missing file";
}

}  // namespace

// FrameSource: a topic's frames as every bridge takes them out (POD and serialized messages as
// they are, pool frames recorded with their block's data), with their sequence and what was lost.
namespace {

using horus::Image;
using horus::ImageEncoding;
using horus::RawTopic;
using horus::bridge::FrameSource;
using horus::msg::ImageDescriptor;

/// A POD type of 8 bytes, known only at run time (as a bridge knows a peer's).
horus::TypeIdentity counter_type() {
  horus::TypeIdentity type;
  type.name = "test.Counter";
  type.fingerprint = 0x1234;
  type.schema = "message Counter { u64 value }";
  type.is_pod = true;
  type.size = sizeof(std::uint64_t);
  type.alignment = alignof(std::uint64_t);
  return type;
}

std::unique_ptr<RawTopic> counter_topic(std::size_t capacity) {
  horus::TopicOptions options;
  options.capacity = capacity;
  return std::make_unique<RawTopic>("counter", counter_type(), options);
}

bool send_counter(RawTopic& topic, std::uint64_t value) {
  return topic.send(std::as_bytes(std::span(&value, 1)));
}

std::uint64_t counter_of(const horus::bridge::Frame& frame) {
  std::uint64_t value = 0;
  EXPECT_EQ(frame.bytes.size(), sizeof value);
  std::memcpy(&value, frame.bytes.data(), std::min(frame.bytes.size(), sizeof value));
  return value;
}

TEST(BridgeFrameSource, FramesComeInOrderWithTheirSequenceAndNothingMoreAfter) {
  const topic_test::PrivateNamespace ns;
  const std::unique_ptr<RawTopic> publisher = counter_topic(8);
  FrameSource source(counter_topic(8), "");
  EXPECT_FALSE(source.pool_backed());
  EXPECT_FALSE(source.try_next().has_value()) << "nothing sent yet";
  for (std::uint64_t value = 100; value < 103; ++value) {
    ASSERT_TRUE(send_counter(*publisher, value));
  }

  for (std::uint64_t i = 0; i < 3; ++i) {
    const auto frame = i == 0 ? source.next(std::chrono::milliseconds(100)) : source.try_next();
    ASSERT_TRUE(frame.has_value()) << "frame " << i;
    EXPECT_EQ(frame->sequence, i);
    EXPECT_EQ(frame->lost, 0U);
    EXPECT_EQ(counter_of(*frame), 100 + i);
  }
  EXPECT_FALSE(source.try_next().has_value()) << "every frame was taken";
  EXPECT_FALSE(source.next(std::chrono::milliseconds(20)).has_value());
  EXPECT_EQ(source.lost(), 0U);
}

TEST(BridgeFrameSource, WhatTheRingOverwroteIsCountedLostOnTheNextFrame) {
  const topic_test::PrivateNamespace ns;
  const std::unique_ptr<RawTopic> publisher = counter_topic(4);
  FrameSource source(counter_topic(4), "");
  for (std::uint64_t value = 0; value < 10; ++value) ASSERT_TRUE(send_counter(*publisher, value));

  std::uint64_t taken = 0;
  std::uint64_t lost = 0;
  std::uint64_t expected_sequence = 0;
  while (const auto frame = source.try_next()) {
    expected_sequence += frame->lost;
    EXPECT_EQ(frame->sequence, expected_sequence) << "a gap of exactly the lost messages";
    EXPECT_EQ(counter_of(*frame), frame->sequence) << "the message of that ticket";
    ++expected_sequence;
    ++taken;
    lost += frame->lost;
  }
  EXPECT_EQ(taken, source.topic().capacity()) << "the ring's last messages";
  EXPECT_EQ(lost, 10 - taken);
  EXPECT_EQ(source.lost(), lost);
  EXPECT_EQ(source.stale(), 0U);
}

TEST(BridgeFrameSource, LatestIsTheNewestMessageTakenOrSentBeforeOpeningNotOneWaiting) {
  const topic_test::PrivateNamespace ns;
  const std::unique_ptr<RawTopic> publisher = counter_topic(8);
  ASSERT_TRUE(send_counter(*publisher, 7));
  ASSERT_TRUE(send_counter(*publisher, 8));
  // Opened after the messages went: a latched topic's late joiner.
  FrameSource source(counter_topic(8), "");
  EXPECT_FALSE(source.try_next().has_value()) << "a new reader starts after what was sent";
  const auto latest = source.latest();
  ASSERT_TRUE(latest.has_value());
  EXPECT_EQ(counter_of(*latest), 8U);
  EXPECT_EQ(latest->sequence, 1U);
  EXPECT_EQ(latest->lost, 0U);

  ASSERT_TRUE(send_counter(*publisher, 9));
  const auto next = source.next(std::chrono::milliseconds(100));
  ASSERT_TRUE(next.has_value()) << "latest() moved no read position";
  EXPECT_EQ(counter_of(*next), 9U);
  EXPECT_EQ(next->sequence, 2U);
  ASSERT_TRUE(source.latest().has_value());
  EXPECT_EQ(counter_of(*source.latest()), 9U) << "the newest again, though taken";

  ASSERT_TRUE(send_counter(*publisher, 10));
  EXPECT_FALSE(source.latest().has_value())
      << "10 is waiting: next() gives it, and a joiner welcomed with it would get it twice";
  const auto waiting = source.try_next();
  ASSERT_TRUE(waiting.has_value());
  EXPECT_EQ(counter_of(*waiting), 10U);
  ASSERT_TRUE(source.latest().has_value());
  EXPECT_EQ(counter_of(*source.latest()), 10U);
  EXPECT_EQ(source.lost(), 0U);
}

/// A private namespace with its pools, removed afterwards.
class BridgePoolFrameSource : public ::testing::Test {
 protected:
  ~BridgePoolFrameSource() override { horus::remove_pools(ns_.name()); }

  static std::unique_ptr<RawTopic> camera_reader() {
    return std::make_unique<RawTopic>("camera", horus::type_identity<ImageDescriptor>(),
                                      horus::pool_topic_options());
  }

  topic_test::PrivateNamespace ns_;
};

TEST_F(BridgePoolFrameSource, AnImageIsItsDescriptorThenTheDataOfItsBlock) {
  horus::Topic<Image> camera("camera");
  FrameSource source(camera_reader(), ns_.name());
  ASSERT_TRUE(source.pool_backed());
  Image image = Image::make(6, 4, ImageEncoding::Rgb8);
  const std::span<std::uint8_t> pixels = image.data_mut();
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<std::uint8_t>(i * 3);
  ASSERT_TRUE(camera.send(image));

  const auto frame = source.next(std::chrono::milliseconds(100));
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->sequence, 0U);
  EXPECT_EQ(frame->lost, 0U);
  ASSERT_EQ(frame->bytes.size(), sizeof(ImageDescriptor) + pixels.size());
  ImageDescriptor descriptor;
  std::memcpy(&descriptor, frame->bytes.data(), sizeof descriptor);
  EXPECT_EQ(descriptor.width, 4U);
  EXPECT_EQ(descriptor.height, 6U);
  EXPECT_EQ(descriptor.encoding, ImageEncoding::Rgb8);
  EXPECT_EQ(std::memcmp(frame->bytes.data() + sizeof descriptor, pixels.data(), pixels.size()), 0)
      << "the block's data follows the descriptor";

  const auto latest = source.latest();
  ASSERT_TRUE(latest.has_value());
  EXPECT_TRUE(std::equal(latest->bytes.begin(), latest->bytes.end(), frame->bytes.begin(),
                         frame->bytes.end()))
      << "latest() records the frame the same way";
  EXPECT_FALSE(source.try_next().has_value());
}

TEST_F(BridgePoolFrameSource, AFrameWhoseBlockWasReusedIsSkippedAndCountedLost) {
  horus::TensorPoolOptions small;
  small.block_size = 4096;
  small.block_count = 2;
  const horus::TensorPool pool = horus::TensorPool::open("small", small);
  horus::Topic<Image> camera("camera");
  horus::Topic<ImageDescriptor> forger("camera", horus::pool_topic_options());
  FrameSource source(camera_reader(), ns_.name());

  ImageDescriptor stale;
  {
    const Image gone = Image::make(8, 8, ImageEncoding::Mono8, pool);
    stale = gone.descriptor();
  }
  // Both blocks taken: the allocation that finds none free frees and reuses the one above.
  const Image first = Image::make(8, 8, ImageEncoding::Mono8, pool);
  Image second = Image::make(8, 8, ImageEncoding::Mono8, pool);
  ASSERT_EQ(second.block().index, stale.block.index);
  second.fill(42);
  ASSERT_TRUE(forger.send(stale));
  ASSERT_TRUE(camera.send(second));

  const auto frame = source.try_next();
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->sequence, 1U) << "the stale frame was skipped";
  EXPECT_EQ(frame->lost, 1U);
  EXPECT_EQ(source.lost(), 1U);
  EXPECT_EQ(source.stale(), 1U);
  ASSERT_EQ(frame->bytes.size(), sizeof(ImageDescriptor) + 64);
  EXPECT_TRUE(std::all_of(frame->bytes.begin() + sizeof(ImageDescriptor), frame->bytes.end(),
                          [](std::byte b) { return b == std::byte{42}; }));

  ASSERT_TRUE(forger.send(stale));
  EXPECT_FALSE(source.next(std::chrono::milliseconds(20)).has_value())
      << "a stale frame alone gives nothing";
  EXPECT_EQ(source.stale(), 2U) << "counted as it was met";
}

}  // namespace

// LocalServiceCaller: a local service called on a worker of its own, each outcome handed to a
// callback there; with payloads (the service's types known) or a far client's frames.
namespace {

using horus::ServiceErrorKind;
using horus::bridge::LocalServiceCaller;
using service_test::Echo;
using service_test::EchoRequest;
using service_test::EchoResponse;

template <class T>
std::vector<std::byte> bytes_of(const T& message) {
  const std::vector<std::uint8_t> encoded = horus::encode(message);
  const auto* first = reinterpret_cast<const std::byte*>(encoded.data());
  return {first, first + encoded.size()};
}

std::string echoed(std::span<const std::byte> payload) {
  return horus::decode<EchoResponse>(
             std::span(reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()))
      .text;
}

/// An Echo server in `space` that answers each text with itself and "!", until destroyed.
class EchoServer {
 public:
  explicit EchoServer(const std::string& space)
      : server_(horus::raw_service_type<Echo>(), in_namespace(space)), serving_([this] {
          while (!server_.stopped()) {
            if (auto request = server_.next(std::chrono::milliseconds(100))) {
              const auto text = horus::decode<EchoRequest>(
                  std::span(reinterpret_cast<const std::uint8_t*>(request->payload.data()),
                            request->payload.size()));
              server_.answer(request->caller, bytes_of(EchoResponse{text.text + "!"}));
            }
          }
        }) {}
  ~EchoServer() {
    server_.stop();
    serving_.join();
  }

  static horus::TopicOptions in_namespace(const std::string& space) {
    horus::TopicOptions options;
    options.namespace_name = space;
    return options;
  }

 private:
  horus::RawServiceServer server_;
  std::thread serving_;
};

LocalServiceCaller::Outcome call_and_wait(LocalServiceCaller& caller,
                                          std::vector<std::byte> request,
                                          std::chrono::milliseconds timeout) {
  std::promise<LocalServiceCaller::Outcome> outcome;
  const std::thread::id asking = std::this_thread::get_id();
  caller.call(std::move(request), timeout, [&](LocalServiceCaller::Outcome called) {
    EXPECT_NE(std::this_thread::get_id(), asking) << "the outcome comes on the worker";
    outcome.set_value(std::move(called));
  });
  return outcome.get_future().get();
}

/// Frame mode's topics, opened with the types of Echo's frames.
LocalServiceCaller frame_caller(const std::string& space) {
  const horus::RawServiceType type = horus::raw_service_type<Echo>();
  std::optional<horus::TopicInfo> requests;
  for (horus::TopicInfo& info : horus::list_topics(space)) {
    if (info.name == type.request_topic) requests = std::move(info);
  }
  EXPECT_TRUE(requests.has_value()) << "the server made " << type.request_topic;
  return LocalServiceCaller(
      type.name, requests.value_or(horus::TopicInfo{}), std::nullopt, space, " on the robot",
      [space, type](const horus::TopicInfo& info) {
        const bool reply = info.name != type.request_topic;
        return std::make_unique<horus::RawTopic>(
            info.name, horus::service_frame_type(reply ? type.response : type.request, reply),
            EchoServer::in_namespace(space));
      });
}

TEST(BridgeLocalServiceCaller, PayloadsGoToTheLocalServerAndTheOutcomeComesOnTheWorker) {
  const topic_test::PrivateNamespace ns;
  LocalServiceCaller caller(horus::raw_service_type<Echo>(), ns.name());
  {
    const EchoServer server(ns.name());
    const LocalServiceCaller::Outcome answered =
        call_and_wait(caller, bytes_of(EchoRequest{"hi", 1}), std::chrono::seconds(5));
    ASSERT_TRUE(answered.answer) << answered.answer.error().to_string();
    EXPECT_EQ(echoed(*answered.answer), "hi!");
    EXPECT_FALSE(answered.response_type.has_value()) << "payloads carry no frame type";
  }
  const LocalServiceCaller::Outcome alone =
      call_and_wait(caller, bytes_of(EchoRequest{"hi", 1}), std::chrono::seconds(5));
  ASSERT_FALSE(alone.answer);
  EXPECT_EQ(alone.answer.error().kind(), ServiceErrorKind::NoServer);
}

TEST(BridgeLocalServiceCaller, FramesComeBackAsTheServersWithTheirTypeLearned) {
  const topic_test::PrivateNamespace ns;
  const horus::RawServiceType type = horus::raw_service_type<Echo>();
  const horus::ServiceFrameCodec requests(type.request, false);
  const horus::ServiceFrameCodec responses(type.response, true);
  std::optional<EchoServer> server(std::in_place, ns.name());
  LocalServiceCaller caller = frame_caller(ns.name());
  // The far client's ids: the caller sends under its own.
  const std::vector<std::byte> frame =
      requests.request(horus::ServiceCaller{77, 5, 9}, bytes_of(EchoRequest{"hi", 1}));

  const LocalServiceCaller::Outcome answered =
      call_and_wait(caller, frame, std::chrono::seconds(5));
  ASSERT_TRUE(answered.answer) << answered.answer.error().to_string();
  ASSERT_TRUE(answered.response_type.has_value()) << "learned from the reply topic the server made";
  EXPECT_EQ(answered.response_type->type_name, responses.frame_type().name);
  const auto response = responses.read_response(*answered.answer);
  ASSERT_TRUE(response.has_value());
  EXPECT_FALSE(response->failure.has_value());
  EXPECT_EQ(echoed(response->payload), "hi!");

  server.reset();
  const LocalServiceCaller::Outcome alone = call_and_wait(caller, frame, std::chrono::seconds(5));
  ASSERT_FALSE(alone.answer);
  EXPECT_EQ(alone.answer.error(), horus::ServiceError::no_server("no server for Echo on the robot"))
      << alone.answer.error().to_string();
}

TEST(BridgeLocalServiceCaller, DestroyedMidCallItEndsTheWaitAsATimeout) {
  const topic_test::PrivateNamespace ns;
  // Registered, never answering.
  horus::RawServiceServer silent(horus::raw_service_type<Echo>(),
                                 EchoServer::in_namespace(ns.name()));
  std::promise<LocalServiceCaller::Outcome> outcome;
  const auto started = std::chrono::steady_clock::now();
  {
    LocalServiceCaller caller = frame_caller(ns.name());
    const horus::ServiceFrameCodec requests(horus::raw_service_type<Echo>().request, false);
    caller.call(requests.request(horus::ServiceCaller{1, 1, 0}, bytes_of(EchoRequest{"hi", 1})),
                std::chrono::seconds(30),
                [&](LocalServiceCaller::Outcome called) { outcome.set_value(std::move(called)); });
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const LocalServiceCaller::Outcome ended = outcome.get_future().get();
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(5));
  ASSERT_FALSE(ended.answer);
  EXPECT_EQ(ended.answer.error(),
            horus::ServiceError::timeout("no answer from Echo on the robot within 30000 ms"));
}

}  // namespace
