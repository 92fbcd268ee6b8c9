// bridges/dds without DDS traffic: HORUS names on DDS and back, the identity an exporting writer
// carries in its user data (what the Python bridge writes too), and the DDS type name spelled
// from a type description (as horus-gen's IDL names it).
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "horus/dds/names.hpp"
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

}  // namespace
