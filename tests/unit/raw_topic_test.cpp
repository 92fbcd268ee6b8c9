// horus::RawTopic and horus::TypeIdentity: a topic opened by name as bytes shares its segment with
// typed handles, and the segment keeps the type description beside the schema for tools.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>

#include <horus/raw_topic.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using topic_test::PrivateNamespace;
using topic_test::Sample;
using topic_test::sealed;

horus::TopicInfo listed(const std::string& name) {
  for (horus::TopicInfo& info : horus::list_topics()) {
    if (info.name == name) return info;
  }
  throw std::runtime_error("topic " + name + " is not listed");
}

TEST(TypeIdentity, OfAGeneratedTypeIsItsTypeInfo) {
  const horus::TypeIdentity identity = horus::type_identity<Sample>();
  EXPECT_EQ(identity.name, horus::TypeInfo<Sample>::name);
  EXPECT_EQ(identity.fingerprint, horus::TypeInfo<Sample>::fingerprint);
  EXPECT_EQ(identity.schema, horus::TypeInfo<Sample>::schema);
  EXPECT_TRUE(identity.is_pod);
  EXPECT_EQ(identity.size, sizeof(Sample));
  EXPECT_EQ(identity.alignment, alignof(Sample));
  EXPECT_EQ(identity.description, std::string_view(horus::TypeInfo<Sample>::description));
  if constexpr (requires { horus::TypeInfo<Sample>::description; }) {
    EXPECT_FALSE(identity.description.empty()) << "generated code carries its description";
  }
}

TEST(RawTopic, SharesItsSegmentWithATypedTopicInBothDirections) {
  PrivateNamespace ns;
  horus::Topic<Sample> typed("shared");
  horus::RawTopic raw("shared", horus::type_identity<Sample>(), horus::TopicOptions{});

  const Sample sent = sealed<Sample>(7);
  ASSERT_TRUE(raw.send(std::as_bytes(std::span(&sent, 1))));
  const auto got = typed.try_recv();
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(*got, sent);

  ASSERT_TRUE(typed.send(sealed<Sample>(8)));
  const std::ptrdiff_t size = raw.try_recv();  // its own message first
  ASSERT_EQ(size, static_cast<std::ptrdiff_t>(sizeof(Sample)));
  ASSERT_EQ(raw.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  Sample received{};
  std::memcpy(&received, raw.received(sizeof(Sample)).data(), sizeof received);
  EXPECT_EQ(received, sealed<Sample>(8));
}

TEST(RawTopic, AnotherFingerprintIsRefused) {
  PrivateNamespace ns;
  horus::Topic<Sample> typed("typed");
  horus::TypeIdentity other = horus::type_identity<Sample>();
  other.fingerprint ^= 1;
  EXPECT_THROW(horus::RawTopic("typed", other, horus::TopicOptions{}), horus::Error);
}

TEST(RawTopic, TheTypeDescriptionIsStoredBesideTheSchemaAndListed) {
  PrivateNamespace ns;
  horus::TypeIdentity identity = horus::type_identity<Sample>();
  // Any bytes, a NUL among them: the segment stores them as given.
  identity.description = std::string{'\x81', '\xa1', 'k', '\xc4', '\x02', '\0', '\x01'};
  const horus::RawTopic raw("described", identity, horus::TopicOptions{});
  const horus::TopicInfo info = listed("described");
  EXPECT_EQ(info.schema, identity.schema);
  EXPECT_EQ(info.description, identity.description);
}

TEST(RawTopic, ATypeWithoutDescriptionListsAnEmptyOne) {
  PrivateNamespace ns;
  horus::TypeIdentity identity = horus::type_identity<Sample>();
  identity.description.clear();
  const horus::RawTopic raw("plain", identity, horus::TopicOptions{});
  const horus::TopicInfo info = listed("plain");
  EXPECT_TRUE(info.description.empty());
  EXPECT_EQ(info.schema, identity.schema);
}

TEST(RawTopic, ATypedTopicStoresItsGeneratedDescription) {
  PrivateNamespace ns;
  const horus::Topic<Sample> typed("typed");
  EXPECT_EQ(listed("typed").description, std::string_view(horus::TypeInfo<Sample>::description));
}

}  // namespace
