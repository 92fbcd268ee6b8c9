// bridges/dds without DDS traffic: HORUS names on DDS and back, the identity an exporting writer
// carries in its user data (what the Python bridge writes too), and the DDS type name spelled
// from a type description (as horus-gen's IDL names it), and frames as tf2_msgs/msg/TFMessage.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "horus/dds/names.hpp"
#include "horus/dds/ros2_twins.hpp"
#include "horus/dds/user_data.hpp"
#include "horus/dds/xtypes.hpp"
#include "horus/msg/cmd_vel.hpp"
#include "horus/topic.hpp"
#include "horus/type_description.hpp"

namespace {

using namespace horus::dds_bridge;

TEST(DdsBridgeNames, DotsAreSlashesUnderRos2sPrefix) {
  EXPECT_EQ(dds_topic_name("cmd_vel"), "rt/cmd_vel");
  EXPECT_EQ(dds_topic_name("arm.state"), "rt/arm/state");
  EXPECT_EQ(horus_topic_name("rt/arm/state"), "arm.state");
  EXPECT_EQ(dotted("rt/fleet/telemetry"), "fleet.telemetry");
}

TEST(DdsBridgeNames, ANameWithNoCounterpartIsRefusedSayingWhy) {
  try {
    dds_topic_name("arm-1");
    FAIL() << "arm-1 has no DDS name";
  } catch (const std::invalid_argument& error) {
    EXPECT_TRUE(std::string(error.what()).starts_with("DDS topic names cannot hold its '-'"));
  }
  try {
    horus_topic_name("rt/arm.state");
    FAIL() << "rt/arm.state is ambiguous";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()),
              "its '.' makes it ambiguous: rt/arm.state and rt/arm/state would both be the "
              "local topic 'arm.state'");
  }
  EXPECT_THROW(horus_topic_name("rt/arm:state"), std::invalid_argument);
  EXPECT_THROW(horus_topic_name("rt/"), std::invalid_argument);
}

TEST(DdsBridgeUserData, TheIdentityRoundTripsAsPythonsJsonWritesIt) {
  const WriterIdentity identity{
      {"horus.msg.CmdVel", 0x0123456789abcdefULL, "CmdVel {\n  é: \"q\"\n}"},
      std::string("\x00\x01\xff", 3)};
  const std::string data = identity_user_data(identity);
  EXPECT_EQ(data,
            "{\"type\": \"horus.msg.CmdVel\", \"fingerprint\": \"0123456789abcdef\", \"schema\": "
            "\"CmdVel {\\n  \\u00e9: \\\"q\\\"\\n}\", \"description\": \"0001ff\"}");
  const auto back = parse_identity_user_data(data);
  ASSERT_TRUE(back.has_value());
  EXPECT_TRUE(back->topic.same_type(identity.topic));
  EXPECT_EQ(back->topic.schema, identity.topic.schema);
  EXPECT_EQ(back->description, identity.description);
}

TEST(DdsBridgeUserData, APlainWriterHasNoneAndAnotherShapeIsRefused) {
  EXPECT_FALSE(parse_identity_user_data("").has_value());
  EXPECT_THROW(parse_identity_user_data("not json"), std::invalid_argument);
  EXPECT_THROW(parse_identity_user_data("{\"type\": \"a.B\"}"), std::invalid_argument);
  EXPECT_THROW(
      parse_identity_user_data("{\"type\": \"a.B\", \"fingerprint\": \"xyz\", \"schema\": \"\"}"),
      std::invalid_argument);
  // Without a description (a bridge from before descriptions): the identity alone.
  const auto old = parse_identity_user_data(
      "{\"type\": \"a.B\", \"fingerprint\": \"00000000000000ff\", \"schema\": \"B {}\"}");
  ASSERT_TRUE(old.has_value());
  EXPECT_EQ(old->topic.fingerprint, 0xffU);
  EXPECT_TRUE(old->description.empty());
}

TEST(DdsBridgeTypes, TheDdsTypeNameIsRos2sAsTheGeneratedIdlSpellsIt) {
  const auto description = horus::TypeDescription::decode(
      std::string_view(horus::TypeInfo<horus::msg::CmdVel>::description));
  EXPECT_EQ(dds_type_name(description, description.root_message()), "horus::msg::dds_::CmdVel_");
  const std::string idl = idl_of(description);
  EXPECT_NE(idl.find("@final\nstruct CmdVel_ {\n  uint64 stamp_nanos;\n  float linear;\n  "
                     "float angular;\n};"),
            std::string::npos)
      << idl;
}

// -- frames as tf2_msgs/msg/TFMessage ----------------------------------------------------------

// XCDR1 by hand, in either byte order: what a ROS 2 node's rmw writes.
class HandCdr {
 public:
  explicit HandCdr(bool little) : little_(little) {
    bytes_ = {std::byte{0}, std::byte{little ? std::uint8_t{1} : std::uint8_t{0}}, std::byte{0},
              std::byte{0}};
  }
  template <typename T>
  HandCdr& number(T value) {
    while ((bytes_.size() - 4) % sizeof(T) != 0) bytes_.push_back(std::byte{0});
    std::byte raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    if (little_ != (std::endian::native == std::endian::little)) std::reverse(raw, raw + sizeof(T));
    bytes_.insert(bytes_.end(), raw, raw + sizeof(T));
    return *this;
  }
  HandCdr& string(const std::string& text) {
    number(static_cast<std::uint32_t>(text.size() + 1));
    for (const char c : text) bytes_.push_back(static_cast<std::byte>(c));
    bytes_.push_back(std::byte{0});
    return *this;
  }
  // One TransformStamped.
  HandCdr& transform(std::int32_t sec, std::uint32_t nanosec, const std::string& parent,
                     const std::string& child, std::initializer_list<double> values) {
    number(sec).number(nanosec).string(parent).string(child);
    for (const double value : values) number(value);
    return *this;
  }
  std::vector<std::byte> bytes() const { return bytes_; }

 private:
  bool little_;
  std::vector<std::byte> bytes_;
};

horus::StampedTransform stamped(std::string parent, std::string child, std::int64_t stamp,
                                horus::Transform transform) {
  return {std::move(parent), std::move(child), std::chrono::nanoseconds(stamp), transform};
}

void expect_same(const horus::StampedTransform& a, const horus::StampedTransform& b) {
  EXPECT_EQ(a.parent, b.parent);
  EXPECT_EQ(a.child, b.child);
  EXPECT_EQ(a.stamp, b.stamp);
  const horus::Vector3& p = a.transform.translation;
  const horus::Vector3& q = b.transform.translation;
  EXPECT_EQ(std::vector({p.x, p.y, p.z}), std::vector({q.x, q.y, q.z}));
  const horus::Quaternion& r = a.transform.rotation;
  const horus::Quaternion& s = b.transform.rotation;
  EXPECT_EQ(std::vector({r.x, r.y, r.z, r.w}), std::vector({s.x, s.y, s.z, s.w}));
}

TEST(DdsBridgeFrames, ATfMessageIsByteForByteWhatRos2Writes) {
  const std::vector<horus::StampedTransform> transforms{
      stamped("map", "odom", 1'500'000'000, {{1, 2, 3}, {0, 0, 0, 1}}),
      stamped("odom", "base_link", 2'000'000'007, {{-1, 0.5, 0}, {0, 0, 0.6, 0.8}})};
  std::vector<std::byte> sample;
  tf_message_to_cdr(transforms, sample);
  HandCdr hand(true);
  hand.number(std::uint32_t{2})
      .transform(1, 500'000'000, "map", "odom", {1, 2, 3, 0, 0, 0, 1})
      .transform(2, 7, "odom", "base_link", {-1, 0.5, 0, 0, 0, 0.6, 0.8});
  EXPECT_EQ(sample, hand.bytes());

  std::vector<horus::StampedTransform> back;
  ASSERT_EQ(tf_message_from_cdr(sample, back), "");
  ASSERT_EQ(back.size(), 2U);
  expect_same(back[0], transforms[0]);
  expect_same(back[1], transforms[1]);
}

TEST(DdsBridgeFrames, BigEndianSamplesDecodeAndOneLeadingSlashIsDropped) {
  HandCdr hand(false);
  hand.number(std::uint32_t{1}).transform(3, 4, "/map", "/odom", {1, 2, 3, 0, 0, 0, 1});
  std::vector<horus::StampedTransform> back;
  ASSERT_EQ(tf_message_from_cdr(hand.bytes(), back), "");
  ASSERT_EQ(back.size(), 1U);
  expect_same(back[0], stamped("map", "odom", 3'000'000'004, {{1, 2, 3}, {0, 0, 0, 1}}));
}

TEST(DdsBridgeFrames, ABadSampleSaysWhyAndGivesNoTransforms) {
  std::vector<horus::StampedTransform> back;
  // A count past the body: refused before anything is read.
  HandCdr forged(true);
  forged.number(std::uint32_t{1'000'000}).transform(1, 0, "map", "odom", {0, 0, 0, 0, 0, 0, 1});
  std::string why = tf_message_from_cdr(forged.bytes(), back);
  EXPECT_NE(why.find("does not decode as tf2_msgs/msg/TFMessage: a count of 1000000"),
            std::string::npos)
      << why;
  EXPECT_TRUE(back.empty());
  // Cut short in its second transform: nothing of the first is kept.
  HandCdr cut(true);
  cut.number(std::uint32_t{2}).transform(1, 0, "map", "odom", {0, 0, 0, 0, 0, 0, 1});
  cut.number(std::int32_t{1});
  why = tf_message_from_cdr(cut.bytes(), back);
  EXPECT_NE(why.find("does not decode as tf2_msgs/msg/TFMessage"), std::string::npos) << why;
  EXPECT_TRUE(back.empty());
  // XCDR2's encapsulation.
  std::vector<std::byte> xcdr2 = forged.bytes();
  xcdr2[1] = std::byte{7};
  why = tf_message_from_cdr(xcdr2, back);
  EXPECT_NE(why.find("is XCDR2"), std::string::npos) << why;
  EXPECT_NE(tf_message_from_cdr(std::vector<std::byte>(2), back), "");
}

}  // namespace
