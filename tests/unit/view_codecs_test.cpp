// The live view's codecs (bridges/view/codecs.hpp) on generated types: the channel each type gets,
// payloads as exact JSON text and back to the generated code's bytes, Foxglove's frame-name
// defaults, an image encoded as one copy with no allocation, and the errors a bad type or payload
// gets. tests/view/test_view_codecs.py checks every type against readers that are not ours.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <horus/msg/cmd_vel.hpp>
#include <horus/msg/image_descriptor.hpp>
#include <horus/msg/path.hpp>
#include <horus/msg/point_cloud_descriptor.hpp>
#include <horus/msg/pose_stamped.hpp>
#include <horus/msg/transform_stamped.hpp>
#include <topic_test/blob.hpp>

#include "../support/allocation_counter.hpp"
#include "horus/codec.hpp"
#include "horus/msgpack.hpp"
#include "horus/raw_topic.hpp"
#include "horus/view/codecs.hpp"

namespace {

using horus::view::codec_for;
using horus::view::CodecError;

template <class T>
std::vector<std::byte> frame_of(const T& message) {
  const std::vector<std::uint8_t> bytes = horus::encode(message);
  const auto* data = reinterpret_cast<const std::byte*>(bytes.data());
  return {data, data + bytes.size()};
}

std::vector<std::byte> bytes_of(std::string_view text) {
  const auto* data = reinterpret_cast<const std::byte*>(text.data());
  return {data, data + text.size()};
}

std::string text_of(const std::vector<std::byte>& bytes) {
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

TEST(ViewCodecs, PlainTypesAreJsonWithU64AsDigitsAndReadBackToTheSameBytes) {
  const auto codec = codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  EXPECT_EQ(codec->schema().encoding, "json");
  EXPECT_EQ(codec->schema().schema_name, "horus.msg.CmdVel");
  EXPECT_EQ(codec->schema().schema_encoding, "jsonschema");
  EXPECT_FALSE(codec->schema().schema_is_binary);
  EXPECT_NE(codec->schema().schema.find(
                R"("stamp_nanos":{"type":"string","pattern":"^[0-9]+$","description":"[ns]"})"),
            std::string::npos)
      << codec->schema().schema;

  horus::msg::CmdVel command;
  command.stamp_nanos = (std::uint64_t{1} << 60) + 1;  // past 2^53: a double would round it
  command.linear = 0.1F;
  command.angular = -1.25F;
  std::vector<std::byte> payload;
  codec->encode(frame_of(command), payload);
  EXPECT_EQ(text_of(payload),
            R"({"stamp_nanos":"1152921504606846977","linear":0.1,"angular":-1.25})");

  std::vector<std::byte> frame;
  codec->decode(payload, frame);
  EXPECT_EQ(frame, frame_of(command));
}

TEST(ViewCodecs, SerializedMessagesCrossAsJsonBothWays) {
  const auto codec = codec_for(horus::type_identity<topic_test::Blob>(), "blobs");
  topic_test::Blob blob;
  blob.seq = 7;
  blob.text = "say \"hi\"\n";
  blob.data = {1, 2, 255};
  std::vector<std::byte> payload;
  codec->encode(frame_of(blob), payload);
  EXPECT_EQ(text_of(payload), R"({"seq":"7","text":"say \"hi\"\n","data":"AQL/","note":null})");

  blob.note = "n";
  std::vector<std::byte> frame;
  codec->decode(bytes_of(R"({"seq":"7","text":"say \"hi\"\n","data":"AQL/","note":"n"})"), frame);
  EXPECT_EQ(frame, frame_of(blob));
}

TEST(ViewCodecs, NonFiniteFloatsAreNullAndNullIsNaN) {
  const auto codec = codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  horus::msg::CmdVel command;
  command.linear = std::numeric_limits<float>::infinity();
  std::vector<std::byte> payload;
  codec->encode(frame_of(command), payload);
  EXPECT_EQ(text_of(payload), R"({"stamp_nanos":"0","linear":null,"angular":0})");
  std::vector<std::byte> frame;
  codec->decode(payload, frame);
  ASSERT_EQ(frame.size(), sizeof(horus::msg::CmdVel));
  horus::msg::CmdVel back;
  std::memcpy(&back, frame.data(), sizeof(back));
  EXPECT_TRUE(std::isnan(back.linear));
}

TEST(ViewCodecs, AViewersBadPayloadIsRefusedNamingTheField) {
  const auto codec = codec_for(horus::type_identity<horus::msg::PoseStamped>(), "goal");
  std::vector<std::byte> frame;
  // foxglove.PoseInFrame comes back as a PoseStamped; a frame name too long for string<32>.
  const std::string long_name(40, 'f');
  try {
    codec->decode(bytes_of(R"({"timestamp":{"sec":1,"nsec":2},"frame_id":")" + long_name +
                           R"(","pose":{"position":{"x":1,"y":2,"z":3},)"
                           R"("orientation":{"x":0,"y":0,"z":0,"w":1}}})"),
                  frame);
    FAIL() << "a 40-byte frame name was taken";
  } catch (const CodecError& error) {
    EXPECT_STREQ(error.what(),
                 "horus.msg.PoseStamped.frame_id: a string of 40 bytes, longer than 32");
  }
  EXPECT_THROW(codec->decode(bytes_of(R"({"pose": 3})"), frame), CodecError);
  EXPECT_THROW(codec->decode(bytes_of("[1, 2"), frame), CodecError);
}

TEST(ViewCodecs, APoseIsFoxglovePoseInFrameNamedAfterItsTopicWhenItNamesNoFrame) {
  const auto codec = codec_for(horus::type_identity<horus::msg::PoseStamped>(), "robot/pose");
  EXPECT_EQ(codec->schema().schema_name, "foxglove.PoseInFrame");
  horus::msg::PoseStamped pose;
  pose.pose.position.x = 1.5;
  pose.pose.orientation.w = 1.0;
  pose.timestamp_ns = 3'000'000'004;
  std::vector<std::byte> payload;
  codec->encode(frame_of(pose), payload);
  EXPECT_EQ(text_of(payload),
            R"({"timestamp":{"sec":3,"nsec":4},"frame_id":"robot/pose","pose":)"
            R"({"position":{"x":1.5,"y":0,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}}})");

  // Published back by a viewer (a goal pose): the topic's name is no frame name of its own.
  std::vector<std::byte> frame;
  codec->decode(payload, frame);
  horus::msg::PoseStamped back;
  std::memcpy(&back, frame.data(), sizeof(back));
  EXPECT_EQ(back.pose.position.x, 1.5);
  EXPECT_EQ(back.pose.orientation.w, 1.0);
  EXPECT_EQ(back.timestamp_ns, pose.timestamp_ns);
  EXPECT_EQ(std::string_view(back.frame_id), "");
}

TEST(ViewCodecs, APathIsFoxglovePosesInFrameOfItsValidWaypointsHeadingsAsTurnsAboutZ) {
  const auto codec = codec_for(horus::type_identity<horus::msg::Path>(), "planner/path");
  EXPECT_EQ(codec->schema().schema_name, "foxglove.PosesInFrame");
  horus::msg::Path path;
  path.waypoint_count = 2;
  path.waypoints[0].pose.x = 1.5;
  path.waypoints[1].pose.y = -2.0;
  path.waypoints[1].pose.theta = std::numeric_limits<double>::quiet_NaN();  // no heading: no turn
  path.waypoints[2].pose.x = 99.0;  // past waypoint_count: not part of the path
  path.timestamp_ns = 3'000'000'004;
  std::vector<std::byte> payload;
  codec->encode(frame_of(path), payload);
  EXPECT_EQ(text_of(payload),
            R"({"timestamp":{"sec":3,"nsec":4},"frame_id":"planner/path","poses":[)"
            R"({"position":{"x":1.5,"y":0,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}},)"
            R"({"position":{"x":0,"y":-2,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}}]})");

  // Published by a viewer: a quarter turn about +Z is a heading of pi/2.
  std::vector<std::byte> frame;
  codec->decode(bytes_of(R"({"timestamp":{"sec":0,"nsec":7},"frame_id":"map","poses":[)"
                         R"({"position":{"x":1,"y":2,"z":5},)"
                         R"("orientation":{"x":0,"y":0,"z":0.7071067811865476,)"
                         R"("w":0.7071067811865476}}]})"),
                frame);
  ASSERT_EQ(frame.size(), sizeof(horus::msg::Path));
  horus::msg::Path back;
  std::memcpy(&back, frame.data(), sizeof(back));
  EXPECT_EQ(back.waypoint_count, 1);
  EXPECT_EQ(back.waypoints[0].pose.x, 1.0);
  EXPECT_EQ(back.waypoints[0].pose.y, 2.0);
  EXPECT_NEAR(back.waypoints[0].pose.theta, std::acos(-1.0) / 2, 1e-12);
  EXPECT_EQ(back.timestamp_ns, 7U);
  EXPECT_EQ(std::string_view(back.frame_id), "map");

  try {
    codec->decode(bytes_of(R"({"poses":[{"position":{"x":1,"y":2,"z":0},)"
                           R"("orientation":{"x":0,"y":0,"z":"up","w":1}}]})"),
                  frame);
    FAIL() << "an orientation that is not numbers was taken";
  } catch (const CodecError& error) {
    EXPECT_STREQ(error.what(), "poses[0].orientation.z: expected a number");
  }
}

TEST(ViewCodecs, ATransformIsFoxgloveFrameTransformFromTheWorldToItsTopic) {
  const auto codec = codec_for(horus::type_identity<horus::msg::TransformStamped>(), "base_link");
  EXPECT_EQ(codec->schema().schema_name, "foxglove.FrameTransform");
  horus::msg::TransformStamped transform;
  transform.translation = {1.0, 2.0, std::numeric_limits<double>::quiet_NaN()};
  transform.rotation = {0.0, 0.0, 0.0, 1.0};
  transform.timestamp_ns = 1;
  std::vector<std::byte> payload;
  codec->encode(frame_of(transform), payload);
  EXPECT_EQ(text_of(payload), R"({"timestamp":{"sec":0,"nsec":1},"parent_frame_id":"world",)"
                              R"("child_frame_id":"base_link","translation":{"x":1,"y":2,"z":0},)"
                              R"("rotation":{"x":0,"y":0,"z":0,"w":1}})");
}

TEST(ViewCodecs, AnImageIsOneCopyOfItsPixelsAndAllocatesNothingOnceThePayloadHasGrown) {
  horus::msg::ImageDescriptor descriptor;
  descriptor.width = 640;
  descriptor.height = 480;
  descriptor.encoding = horus::msg::ImageEncoding::Rgb8;
  descriptor.channels = 3;
  descriptor.step = 640 * 3;
  descriptor.data_size = std::uint64_t{640} * 480 * 3;
  descriptor.frame_id = "camera";
  std::vector<std::byte> frame = frame_of(descriptor);
  const std::size_t descriptor_size = frame.size();
  for (std::size_t i = 0; i < descriptor.data_size; ++i) {
    frame.push_back(static_cast<std::byte>(i % 251));
  }

  const auto codec = codec_for(horus::type_identity<horus::msg::ImageDescriptor>(), "camera/image");
  EXPECT_EQ(codec->schema().encoding, "protobuf");
  EXPECT_EQ(codec->schema().schema_name, "foxglove.RawImage");
  EXPECT_TRUE(codec->schema().schema_is_binary);

  std::vector<std::byte> payload;
  codec->encode(frame, payload);
  const std::byte* grown = payload.data();
  const long before = horus_test::allocations.load();
  codec->encode(frame, payload);
  EXPECT_EQ(horus_test::allocations.load() - before, 0);
  EXPECT_EQ(payload.data(), grown);

  // A few header bytes, then the pixels as they were.
  ASSERT_GT(payload.size(), descriptor.data_size);
  const std::size_t header = payload.size() - descriptor.data_size;
  EXPECT_LT(header, 64U);
  EXPECT_EQ(
      std::memcmp(payload.data() + header, frame.data() + descriptor_size, descriptor.data_size),
      0);
  EXPECT_NE(text_of(payload).find("rgb8"), std::string::npos);

  std::vector<std::byte> published;
  try {
    codec->decode(payload, published);
    FAIL() << "an image was taken from a viewer";
  } catch (const CodecError& error) {
    EXPECT_STREQ(error.what(), "publishing images from a viewer is not supported");
  }
}

TEST(ViewCodecs, APointCloudNamingMillionsOfComponentsPerPointIsRefused) {
  horus::msg::PointCloudDescriptor descriptor;
  descriptor.point_count = 1;
  descriptor.fields_per_point = 1'000'000;
  const auto codec =
      codec_for(horus::type_identity<horus::msg::PointCloudDescriptor>(), "lidar/points");
  EXPECT_EQ(codec->schema().schema_name, "foxglove.PointCloud");
  std::vector<std::byte> payload;
  try {
    codec->encode(frame_of(descriptor), payload);
    FAIL() << "a header of a million fields was written";
  } catch (const CodecError& error) {
    EXPECT_STREQ(error.what(),
                 "horus.msg.PointCloudDescriptor: 1000000 components per point, more than 256");
  }
}

TEST(ViewCodecs, ATruncatedPoolFrameIsRefused) {
  const auto codec = codec_for(horus::type_identity<horus::msg::ImageDescriptor>(), "camera/image");
  std::vector<std::byte> payload;
  EXPECT_THROW(codec->encode(bytes_of("short"), payload), CodecError);
}

TEST(ViewCodecs, ATypeWithoutAReadableDescriptionIsRefusedNamingTheTopic) {
  horus::TypeIdentity type = horus::type_identity<horus::msg::CmdVel>();
  type.description.clear();
  try {
    codec_for(type, "cmd_vel");
    FAIL() << "a type without a description got a codec";
  } catch (const CodecError& error) {
    EXPECT_STREQ(error.what(),
                 "topic 'cmd_vel' (horus.msg.CmdVel) carries no type description: the live view "
                 "cannot decode it");
  }
  type.description = "not msgpack";
  EXPECT_THROW(codec_for(type, "cmd_vel"), CodecError);
}

TEST(ViewCodecs, AFrameThatIsNotAMessageOfTheTypeIsRefused) {
  const auto codec = codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  std::vector<std::byte> payload;
  EXPECT_THROW(codec->encode(bytes_of("three"), payload), CodecError);
}

}  // namespace
