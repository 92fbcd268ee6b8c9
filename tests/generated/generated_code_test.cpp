// Generated C++ for tests/schemas: values, defaults, identity, summaries and wire bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <horus/codec.hpp>
#include <horus/msgpack.hpp>
#include <limits>
#include <other_pkg/stamp.hpp>
#include <summary_names/type.hpp>
#include <test_msgs.hpp>

namespace {

using namespace test_msgs;

TEST(GeneratedCode, DefaultsComeFromTheSchema) {
  const Defaults d{};
  EXPECT_FLOAT_EQ(d.speed, 0.1f);
  EXPECT_EQ(d.count, 4000000000U);
  EXPECT_EQ(d.offset, -3);
  EXPECT_EQ(d.mode, Mode::Run);
  EXPECT_TRUE(d.enabled);
  EXPECT_EQ(d.label.view(), "abcd");
  EXPECT_EQ(d.gains, (std::array<double, 3>{1.0, 0.5, -0.25}));
  EXPECT_EQ(d.stamp.source, other_pkg::Source::Clock);
  const Primitives zeros{};
  EXPECT_EQ(zeros.u64_value, 0U);
  EXPECT_FALSE(zeros.flag);
}

TEST(GeneratedCode, ConstantsAreStaticMembers) {
  static_assert(Defaults::MAX_SPEED == 2.5f);
  static_assert(Defaults::LIMIT == std::numeric_limits<std::int64_t>::min());
  static_assert(Defaults::NAME == "defaults");
  static_assert(Defaults::START == Mode::Run);
  SUCCEED();
}

TEST(GeneratedCode, TypeInfoCarriesIdentity) {
  using Info = horus::TypeInfo<Pose2>;
  static_assert(Info::name == "test_msgs.Pose2");
  static_assert(Info::package == "test_msgs");
  static_assert(Info::is_pod);
  static_assert(Info::field_count == 2);
  static_assert(horus::PodMessage<Pose2>);
  static_assert(horus::SerializedMessage<Serialized>);
  static_assert(!horus::PodMessage<Serialized>);
  static_assert(horus::SchemaEnum<Mode>);
  EXPECT_NE(Info::fingerprint, horus::TypeInfo<Point2>::fingerprint);
  EXPECT_EQ(Info::schema,
            "message test_msgs.Pose2 {\n  position: test_msgs.Point2,\n  theta: f32,\n}\n"
            "message test_msgs.Point2 {\n  x: f64,\n  y: f64,\n}\n");
  EXPECT_EQ(horus::TypeInfo<Defaults>::default_topic, "test.defaults");
}

TEST(GeneratedCode, EnumsHaveNames) {
  EXPECT_EQ(to_string(Mode::Fault), "Fault");
  EXPECT_EQ(to_string(static_cast<Mode>(7)), "");
  EXPECT_EQ(static_cast<std::uint8_t>(Mode::Fault), 200);
  EXPECT_EQ(other_pkg::to_string(other_pkg::Source::Ptp), "Ptp");
}

TEST(GeneratedCode, ServicesNameTheirTopicsAndTypes) {
  static_assert(std::is_same_v<GetRobotPose::Request, GetRobotPoseRequest>);
  static_assert(std::is_same_v<GetRobotPose::Response, GetRobotPoseResponse>);
  EXPECT_EQ(GetRobotPose::name(), "GetRobotPose");
  EXPECT_EQ(GetRobotPose::request_topic(), "GetRobotPose.request");
  EXPECT_EQ(GetRobotPose::response_topic(), "GetRobotPose.response");
  EXPECT_EQ(GetRobotPose::request_type_name(), "test_msgs.GetRobotPoseRequest");
  EXPECT_EQ(GetRobotPose::response_type_name(), "test_msgs.GetRobotPoseResponse");
  EXPECT_FALSE(horus::TypeInfo<GetRobotPoseRequest>::is_pod);
  EXPECT_TRUE(horus::TypeInfo<AddIntsRequest>::is_pod);
  EXPECT_NE(GetRobotPose::fingerprint(), AddInts::fingerprint());
}

TEST(GeneratedCode, LogSummaryIsOneReadableLine) {
  Pose2 pose{};
  pose.position.x = 1.5;
  pose.theta = 0.25f;
  EXPECT_EQ(pose.log_summary(), "Pose2{position: Point2{x: 1.5 m, y: 0 m}, theta: 0.25 rad}");

  Arrays arrays{};
  arrays.ranges[10] = 0.42f;
  arrays.ranges[11] = 30.0f;
  arrays.small = {1, 2, 3};
  arrays.name.assign("lidar");
  EXPECT_EQ(
      arrays.log_summary(),
      "Arrays{small: [1, 2, 3], ranges: [360 x f32, min 0, max 30], grid: [<4 bytes>, <4 bytes>, "
      "<4 bytes>], name: \"lidar\", names: [\"\", \"\"], poses: [Pose2{position: Point2{x: 0 m, y: "
      "0 m}, theta: 0 rad}, Pose2{position: Point2{x: 0 m, y: 0 m}, theta: 0 rad}], flags: "
      "[5 x bool]}");

  EXPECT_EQ(Defaults{}.log_summary(),
            "Defaults(Run) at 0.1 m/s with Stamp{sec: 0, nanosec: 0, source: Clock}");

  Serialized s{};
  s.values = {1.0, 2.5};
  s.maybe_text = "hi";
  s.data.resize(1024);
  EXPECT_EQ(
      s.log_summary(),
      "Serialized{text: \"\", data: <1024 bytes>, values: [1, 2.5], counts: [], small: <0 bytes>, "
      "maybe: none, maybe_text: \"hi\", poses: [], tags: [], fixed: [0, 0, 0], mode: Idle, label: "
      "\"\", nested: none}");
}

TEST(GeneratedCode, LogSummaryTellsMembersAndTypesFromItsOwnNames) {
  summary_names::Type t{};
  t.fields = 7;
  t.text = summary_names::Kind::Text;
  t.field = {0.5f, -2.0f};
  t.horus_log_summary.emplace().assign("abc");
  t.kParts = {summary_names::Kind::Text, static_cast<summary_names::Kind>(9)};
  EXPECT_EQ(t.log_summary(),
            "Type{fields: 7, text: Text, field: [0.5, -2], horus_log_summary: \"abc\", kParts: "
            "[Text, 9]}");
}

TEST(GeneratedCode, FixedStringsNeverTruncateSilently) {
  Arrays a{};
  EXPECT_THROW(a.name.assign("a name longer than twelve"), horus::Error);
  EXPECT_TRUE(a.name.empty());
  EXPECT_TRUE(a.name.try_assign("exactly12byt"));
  EXPECT_EQ(a.name.view(), "exactly12byt");
  EXPECT_EQ(a.name.size(), 12U);
  EXPECT_FALSE(a.name.try_assign("thirteen byte"));
  EXPECT_EQ(a.name.view(), "exactly12byt");
}

TEST(GeneratedCode, PodEncodeIsTheStructWithPaddingZeroed) {
  Primitives value{};
  value.flag = true;
  value.u64_value = 0x0102030405060708ULL;
  value.f64_value = -2.5;
  // What a struct's padding holds is unspecified: make it garbage on purpose.
  auto* raw = reinterpret_cast<unsigned char*>(&value);
  ASSERT_FALSE(horus::TypeInfo<Primitives>::padding.empty());
  for (const horus::PaddingRange& hole : horus::TypeInfo<Primitives>::padding) {
    std::memset(raw + hole.offset, 0xAB, hole.size);
  }
  const Primitives* p = &value;
  const std::vector<std::uint8_t> bytes = horus::encode(*p);
  ASSERT_EQ(bytes.size(), sizeof(Primitives));
  for (const horus::PaddingRange& hole : horus::TypeInfo<Primitives>::padding) {
    for (std::size_t i = hole.offset; i < hole.offset + hole.size; ++i) {
      EXPECT_EQ(bytes[i], 0) << "padding byte " << i;
    }
  }
  EXPECT_EQ(bytes[0], 1);
  EXPECT_EQ(bytes[8], 0x08);
  EXPECT_EQ(horus::decode<Primitives>(bytes), *p);
}

TEST(GeneratedCode, PodDecodeRejectsTheWrongLength) {
  std::vector<std::uint8_t> bytes = horus::encode(Pose2{});
  bytes.pop_back();
  EXPECT_THROW(horus::decode<Pose2>(bytes), horus::DecodeError);
  EXPECT_FALSE(horus::try_decode<Pose2>(bytes).has_value());
}

Serialized sample_serialized() {
  Serialized s{};
  s.text = "héllo";
  s.data = {0, 1, 2, 255};
  s.values = {1.0, -0.5, 1e300};
  s.counts = {0, 70000, 4000000000U};
  s.small = {9, 8};
  s.maybe = -42;
  s.poses.resize(2);
  s.poses[1].position.y = 3.25;
  s.poses[1].theta = -1.5f;
  s.tags = {"a", "bb"};
  s.fixed = {0.5f, -0.0f, 3.0f};
  s.mode = Mode::Fault;
  s.label.assign("sixteen-chars-ok");
  s.nested = std::vector<Point2>{{1, 2}, {3, 4}};
  return s;
}

TEST(GeneratedCode, SerializedMessagesRoundTrip) {
  const Serialized s = sample_serialized();
  const std::vector<std::uint8_t> bytes = horus::encode(s);
  EXPECT_EQ(bytes[0], 0x9d) << "a message is a MessagePack array of its 13 fields";
  EXPECT_EQ(horus::decode<Serialized>(bytes), s);
  Blob blob{};
  blob.seq = 7;
  blob.payload.assign(1 << 20, 0x5A);
  EXPECT_EQ(horus::decode<Blob>(horus::encode(blob)), blob);
  GetRobotPoseRequest request{};
  request.robot_name = "agv-3";
  EXPECT_EQ(horus::decode<GetRobotPoseRequest>(horus::encode(request)), request);
}

TEST(GeneratedCode, SerializedDecodeRejectsBadBytes) {
  std::vector<std::uint8_t> bytes = horus::encode(sample_serialized());
  std::vector<std::uint8_t> truncated(bytes.begin(), bytes.end() - 3);
  EXPECT_THROW(horus::decode<Serialized>(truncated), horus::DecodeError);
  std::vector<std::uint8_t> trailing = bytes;
  trailing.push_back(0xc0);
  EXPECT_THROW(horus::decode<Serialized>(trailing), horus::DecodeError);
  const std::vector<std::uint8_t> wrong_count{0x92, 0x01, 0x02};
  EXPECT_THROW(horus::decode<Serialized>(wrong_count), horus::DecodeError);
  const std::vector<std::uint8_t> not_an_array{0x01};
  EXPECT_THROW(horus::decode<Blob>(not_an_array), horus::DecodeError);
  Blob blob{};
  std::vector<std::uint8_t> wrong_type = horus::encode(blob);
  wrong_type[1] = 0xa1;  // seq becomes a one-byte string
  wrong_type.insert(wrong_type.begin() + 2, 'x');
  EXPECT_FALSE(horus::try_decode<Blob>(wrong_type).has_value());
  Arrays arrays{};
  arrays.name.assign("twelve bytes");
  EXPECT_EQ(horus::decode<Arrays>(horus::encode(arrays)).name.view(), "twelve bytes");
}

TEST(GeneratedCode, FixedStringTooLongOnTheWireIsAnError) {
  // A peer that sends 17 bytes for a string<16> field gets a decode error, not a cut string.
  Serialized s{};
  std::vector<std::uint8_t> bytes = horus::encode(s);
  // label is field 12 (index 11): an empty str (0xa0). Replace it with a 17-byte str.
  const auto label = std::find(bytes.rbegin(), bytes.rend(), 0xa0);
  ASSERT_NE(label, bytes.rend());
  auto at = std::prev(label.base());
  *at = 0xa0 | 17;
  bytes.insert(at + 1, 17, 'x');
  EXPECT_THROW(horus::decode<Serialized>(bytes), horus::DecodeError);
}

}  // namespace
