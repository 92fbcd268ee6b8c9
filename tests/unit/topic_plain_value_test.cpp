// Topics of plain values (seed 002's Topic<f32>, Topic<u64>, Topic<String>): numbers and arrays
// of them, carried byte for byte, strings and vectors, carried as a message of one field would
// be, each with an identity spelled as the schema language spells the type.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <horus/codec.hpp>

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
static_assert(horus::SerializedPlainValue<std::string> &&
              horus::SerializedPlainValue<std::vector<std::uint8_t>> &&
              horus::SerializedPlainValue<std::vector<std::array<float, 3>>> &&
              horus::SerializedPlainValue<std::vector<std::string>>);
static_assert(!horus::PodTopicValue<std::string> && !horus::PodTopicValue<std::vector<float>> &&
                  horus::PodTopicValue<std::array<float, 3>>,
              "strings and vectors are serialized: no loans");
static_assert(!horus::PlainValue<std::vector<topic_test::Sample>> &&
              !horus::PlainValue<std::array<std::string, 2>> &&
              !horus::PlainValue<std::vector<char>>);

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

TEST(TopicPlainValue, StringsAndVectorsAreSpelledAsTheSchemaLanguageSpellsThem) {
  EXPECT_EQ(horus::TypeInfo<std::string>::name, "String");
  EXPECT_EQ(horus::TypeInfo<std::vector<std::uint8_t>>::name, "Vec<u8>");
  EXPECT_EQ(horus::TypeInfo<std::vector<float>>::name, "Vec<f32>");
  EXPECT_EQ((horus::TypeInfo<std::vector<std::array<float, 3>>>::name), "Vec<[f32; 3]>");
  EXPECT_EQ(horus::TypeInfo<std::vector<std::string>>::name, "Vec<String>");
  EXPECT_EQ(horus::TypeInfo<std::string>::schema, "value String\n");
  EXPECT_EQ(horus::TypeInfo<std::string>::fingerprint, horus::detail::fnv1a("value String\n"));
  EXPECT_FALSE(horus::TypeInfo<std::string>::is_pod);
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

TEST(TopicPlainValue, StringsAndVectorsArriveWhole) {
  PrivateNamespace ns;
  horus::Topic<std::string> pub("status");
  horus::Topic<std::string> sub("status");
  horus::Topic<std::vector<float>> ranges_pub("ranges");
  horus::Topic<std::vector<float>> ranges_sub("ranges");
  ASSERT_TRUE(pub.send("ready"));
  ASSERT_TRUE(pub.send(std::string(1000, 'x')));
  ASSERT_TRUE(ranges_pub.send({0.5F, 1.5F, -2.0F}));
  EXPECT_EQ(sub.try_recv(), "ready");
  EXPECT_EQ(sub.try_recv(), std::string(1000, 'x'));
  EXPECT_EQ(ranges_sub.try_recv(), (std::vector<float>{0.5F, 1.5F, -2.0F}));
  EXPECT_EQ(pub.read_latest(), std::string(1000, 'x'));
}

TEST(TopicPlainValue, AStringOrVectorTravelsAsAMessageOfOneField) {
  // A MessagePack array of one element, then the value: what Python writes, and what tools that
  // decode `value String` as the message `PlainValue { value: String }` read.
  EXPECT_EQ(horus::encode(std::string("hi")), (std::vector<std::uint8_t>{0x91, 0xa2, 'h', 'i'}));
  EXPECT_EQ(horus::encode(std::vector<std::uint8_t>{1, 2}),
            (std::vector<std::uint8_t>{0x91, 0xc4, 0x02, 1, 2}));
  EXPECT_EQ(horus::encode(std::vector<float>{1.0F, 0.5F}),
            (std::vector<std::uint8_t>{0x91, 0x92, 0x01, 0xca, 0x3f, 0x00, 0x00, 0x00}));
  EXPECT_EQ(horus::decode<std::string>(std::vector<std::uint8_t>{0x91, 0xa2, 'h', 'i'}), "hi");
  EXPECT_THROW(horus::decode<std::string>(std::vector<std::uint8_t>{0xa2, 'h', 'i'}),
               horus::DecodeError)
      << "a bare string is not the one field of a message";
  EXPECT_EQ(horus::encode(2.5), (std::vector<std::uint8_t>{0, 0, 0, 0, 0, 0, 0x04, 0x40}));
}

TEST(TopicPlainValue, LogSummaryFollowsTheSummaryRules) {
  EXPECT_EQ(horus::log_summary(1.5), "1.5");
  EXPECT_EQ(horus::log_summary(std::int64_t{-3}), "-3");
  EXPECT_EQ(horus::log_summary(true), "true");
  EXPECT_EQ(horus::log_summary(std::string("front")), "\"front\"");
  EXPECT_EQ(horus::log_summary(std::vector<std::uint8_t>(3)), "<3 bytes>");
  EXPECT_EQ(horus::log_summary(std::array<float, 3>{1.0F, 2.5F, -3.0F}), "[1, 2.5, -3]");
  std::array<float, 10> many{};
  many[4] = 9.0F;
  EXPECT_EQ(horus::log_summary(many), "[10 x f32, min 0, max 9]");
  EXPECT_EQ(horus::log_summary(std::vector<std::string>(5)), "[5 x String]");
}

TEST(TopicPlainValue, AStringTopicRefusesBytesNamingBoth) {
  PrivateNamespace ns;
  horus::Topic<std::string> incumbent("label");
  try {
    horus::Topic<std::vector<std::uint8_t>> other("label");
    FAIL() << "a Vec<u8> handle opened a String topic";
  } catch (const horus::Error& error) {
    const std::string text = error.what();
    EXPECT_NE(text.find("carries String"), std::string::npos) << text;
    EXPECT_NE(text.find("as Vec<u8>"), std::string::npos) << text;
  }
}

}  // namespace
