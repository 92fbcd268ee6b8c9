// Topics of plain values (seed 002's Topic<f32>, Topic<u64>): numbers and arrays of them,
// carried byte for byte, with an identity spelled as the schema language spells the type.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include <horus/error.hpp>
#include <horus/plain_value.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using topic_test::PrivateNamespace;

static_assert(horus::PlainValue<float> && horus::PlainValue<std::uint64_t> &&
              horus::PlainValue<bool> && horus::PlainValue<std::array<double, 3>> &&
              horus::PlainValue<std::array<std::array<std::uint8_t, 4>, 2>>);
static_assert(!horus::PlainValue<topic_test::Sample> && !horus::Message<float>,
              "a plain value is not a message, and a message is not a plain value");
static_assert(!horus::PlainValue<std::array<float, 0>> && !horus::PlainValue<char> &&
              !horus::PlainValue<std::array<topic_test::Sample, 2>>);

TEST(TopicPlainValue, NamesAreTheSchemaLanguagesSpelling) {
  EXPECT_EQ(horus::TypeInfo<float>::name, "f32");
  EXPECT_EQ(horus::TypeInfo<double>::name, "f64");
  EXPECT_EQ(horus::TypeInfo<std::uint64_t>::name, "u64");
  EXPECT_EQ(horus::TypeInfo<std::int8_t>::name, "i8");
  EXPECT_EQ(horus::TypeInfo<bool>::name, "bool");
  EXPECT_EQ((horus::TypeInfo<std::array<float, 360>>::name), "[f32; 360]");
  EXPECT_EQ((horus::TypeInfo<std::array<std::array<std::uint8_t, 4>, 12>>::name), "[[u8; 4]; 12]");
  EXPECT_EQ(horus::TypeInfo<float>::schema, "value f32\n");
  EXPECT_EQ((horus::TypeInfo<std::array<double, 3>>::schema), "value [f64; 3]\n");
}

TEST(TopicPlainValue, FingerprintIsFnv1aOfTheSchemaText) {
  // Pinned values: Python computes the same from the same rule, so they must never drift.
  EXPECT_EQ(horus::TypeInfo<float>::fingerprint, horus::detail::fnv1a("value f32\n"));
  EXPECT_EQ(horus::detail::fnv1a(""), 0xcbf29ce484222325ULL);
  EXPECT_EQ(horus::detail::fnv1a("a"), 0xaf63dc4c8601ec8cULL);
  EXPECT_NE(horus::TypeInfo<float>::fingerprint, horus::TypeInfo<std::uint32_t>::fingerprint);
  EXPECT_NE((horus::TypeInfo<std::array<float, 3>>::fingerprint),
            (horus::TypeInfo<std::array<float, 4>>::fingerprint));
}

TEST(TopicPlainValue, FloatsArriveInOrder) {
  PrivateNamespace ns;
  horus::Topic<float> pub("motor.velocity");
  horus::Topic<float> sub("motor.velocity");
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(pub.send(0.5F * static_cast<float>(i)));
  }
  for (int i = 0; i < 5; ++i) {
    const std::optional<float> got = sub.try_recv();
    ASSERT_TRUE(got.has_value()) << i;
    EXPECT_EQ(*got, 0.5F * static_cast<float>(i));
  }
  EXPECT_FALSE(sub.try_recv().has_value());
  EXPECT_EQ(*pub.read_latest(), 2.0F);
}

TEST(TopicPlainValue, CountersOfU64KeepEveryBit) {
  PrivateNamespace ns;
  horus::Topic<std::uint64_t> pub("ticks");
  horus::Topic<std::uint64_t> sub("ticks");
  const std::uint64_t values[] = {0, 1, 0xfedcba9876543210ULL, UINT64_MAX};
  for (const std::uint64_t value : values) {
    ASSERT_TRUE(pub.send(value));
  }
  for (const std::uint64_t value : values) {
    EXPECT_EQ(sub.try_recv(), value);
  }
}

TEST(TopicPlainValue, ArraysTravelWholeAndCanBeLoaned) {
  PrivateNamespace ns;
  using Ranges = std::array<float, 360>;
  horus::Topic<Ranges> pub("scan.ranges");
  horus::Topic<Ranges> sub("scan.ranges");
  Ranges ranges{};
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    ranges[i] = static_cast<float>(i) / 4;
  }
  ASSERT_TRUE(pub.send(ranges));
  EXPECT_EQ(sub.try_recv(), ranges);

  horus::Loan<Ranges> loan = pub.loan();
  loan->fill(7.25F);
  ASSERT_TRUE(pub.publish(std::move(loan)));
  const std::optional<Ranges> loaned = sub.try_recv();
  ASSERT_TRUE(loaned.has_value());
  EXPECT_EQ((*loaned)[0], 7.25F);
  EXPECT_EQ((*loaned)[359], 7.25F);
}

TEST(TopicPlainValue, ToolsSeeTheNameAndSchema) {
  PrivateNamespace ns;
  horus::Topic<std::array<double, 3>> position("arm.position");
  ASSERT_TRUE(position.send({1.0, 2.0, 3.0}));
  const std::vector<horus::TopicInfo> topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].type_name, "[f64; 3]");
  EXPECT_EQ(topics[0].schema, "value [f64; 3]\n");
  EXPECT_EQ(topics[0].fingerprint, (horus::TypeInfo<std::array<double, 3>>::fingerprint));
  EXPECT_TRUE(topics[0].is_pod);
  EXPECT_EQ(topics[0].max_message_size, sizeof(double) * 3);
}

TEST(TopicPlainValue, AnotherValueTypeIsRefusedNamingBoth) {
  PrivateNamespace ns;
  horus::Topic<float> incumbent("level");
  try {
    horus::Topic<std::uint32_t> other("level");
    FAIL() << "a u32 handle opened an f32 topic";
  } catch (const horus::Error& error) {
    const std::string text = error.what();
    EXPECT_NE(text.find("carries f32"), std::string::npos) << text;
    EXPECT_NE(text.find("as u32"), std::string::npos) << text;
  }
  EXPECT_THROW(horus::Topic<topic_test::Sample>("level"), horus::Error);
  EXPECT_THROW((horus::Topic<std::array<float, 1>>("level")), horus::Error)
      << "a one-element array is another type than its element";
}

}  // namespace
