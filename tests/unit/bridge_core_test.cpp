// bridges/core: what every bridge decides the same way. Globs as Python's fnmatchcase reads them
// (the Python bridge and horus.Network give the same patterns), the first matching rule, each
// name decided once and a name both directions match refused, identities compared by name and
// fingerprint.
#include <gtest/gtest.h>

#include <chrono>

#include "horus/bridge/identity.hpp"
#include "horus/bridge/topic_policy.hpp"

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

}  // namespace
