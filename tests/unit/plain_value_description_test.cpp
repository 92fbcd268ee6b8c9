// The type description every plain value carries (horus/plain_value.hpp): the message
// `PlainValue { value: <name> }` its wire bytes are, with the plain value's own identity, so
// consumers that know only a description (the DDS bridge, horus-remote, `horus topic echo`) read
// plain-value topics as they read message topics.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <horus/codec.hpp>
#include <horus/plain_value.hpp>
#include <horus/raw_topic.hpp>
#include <horus/type_description.hpp>

namespace {

using horus::MessageType;
using horus::TypeDescription;
using horus::TypeInfo;
using horus::TypeRef;

template <class T>
class PlainValueDescription : public ::testing::Test {};

using PlainValues =
    ::testing::Types<bool, std::int8_t, std::int16_t, std::int32_t, std::int64_t, std::uint8_t,
                     std::uint16_t, std::uint32_t, std::uint64_t, float, double,
                     std::array<float, 3>, std::array<std::array<std::uint8_t, 4>, 2>,
                     std::array<bool, 5>, std::array<std::array<double, 2>, 3>, std::string,
                     std::vector<std::uint8_t>, std::vector<float>, std::vector<bool>,
                     std::vector<std::string>, std::vector<std::array<float, 3>>,
                     std::vector<std::vector<std::int16_t>>>;
TYPED_TEST_SUITE(PlainValueDescription, PlainValues);

TYPED_TEST(PlainValueDescription, DescribesTheOneFieldMessageWithTheValuesIdentity) {
  using T = TypeParam;
  const std::string_view bytes = TypeInfo<T>::description;
  ASSERT_FALSE(bytes.empty());
  const TypeDescription description = TypeDescription::decode(bytes);
  EXPECT_EQ(description.encode(), bytes) << "the bytes are the encoder's own";
  EXPECT_EQ(description.root, TypeInfo<T>::name);
  ASSERT_EQ(description.messages.size(), 1U);
  EXPECT_TRUE(description.enums.empty());
  const MessageType& message = description.root_message();
  EXPECT_EQ(message.name, TypeInfo<T>::name);
  EXPECT_EQ(message.package, "");
  EXPECT_EQ(message.fingerprint, TypeInfo<T>::fingerprint);
  EXPECT_EQ(message.schema, TypeInfo<T>::schema);
  EXPECT_EQ(message.is_pod, TypeInfo<T>::is_pod);
  ASSERT_EQ(message.fields.size(), 1U);
  EXPECT_EQ(message.fields[0].name, "value");
  EXPECT_EQ(message.fields[0].spelling, TypeInfo<T>::name);
  EXPECT_TRUE(message.constants.empty());
  EXPECT_TRUE(message.padding.empty());
  if constexpr (TypeInfo<T>::is_pod) {
    EXPECT_EQ(message.size, sizeof(T));
    EXPECT_EQ(message.alignment, alignof(T));
    EXPECT_EQ(message.fields[0].offset, 0U);
    EXPECT_EQ(message.fields[0].size, sizeof(T));
  } else {
    EXPECT_EQ(message.size, 0U);
    EXPECT_FALSE(message.fields[0].offset.has_value());
  }
}

TYPED_TEST(PlainValueDescription, WritesTheBytesOfAValueInitialisedValue) {
  using T = TypeParam;
  const TypeDescription description = TypeDescription::decode(TypeInfo<T>::description);
  const MessageType& message = description.root_message();
  const std::vector<std::uint8_t> initialised = horus::encode(T{});
  EXPECT_EQ(horus::zero_message(description, message), initialised);
  EXPECT_EQ(horus::default_message(description, message), initialised);
}

TYPED_TEST(PlainValueDescription, IsWhatATopicSegmentStores) {
  using T = TypeParam;
  const horus::TypeIdentity identity = horus::type_identity<T>();
  EXPECT_EQ(identity.description, std::string(std::string_view(TypeInfo<T>::description)));
}

TEST(PlainValueDescription, SpellsEachValueTypeAsTheSchemaLanguageDoes) {
  const auto value_type = [](std::string_view bytes) {
    return TypeDescription::decode(bytes).root_message().fields[0].type;
  };
  const TypeRef number = value_type(TypeInfo<float>::description);
  EXPECT_EQ(number.kind, TypeRef::Kind::Primitive);
  EXPECT_EQ(number.primitive, horus::Primitive::F32);
  EXPECT_EQ(value_type(TypeInfo<std::string>::description).kind, TypeRef::Kind::String);
  const TypeRef nested =
      value_type(TypeInfo<std::array<std::array<std::uint8_t, 4>, 2>>::description);
  ASSERT_EQ(nested.kind, TypeRef::Kind::Array);
  EXPECT_EQ(nested.length, 2U);
  ASSERT_EQ(nested.element->kind, TypeRef::Kind::Array);
  EXPECT_EQ(nested.element->length, 4U);
  EXPECT_TRUE(nested.element->is_byte_block());
  const TypeRef bytes = value_type(TypeInfo<std::vector<std::uint8_t>>::description);
  ASSERT_EQ(bytes.kind, TypeRef::Kind::Vec);
  EXPECT_TRUE(bytes.is_byte_block());
  const TypeRef arrays = value_type(TypeInfo<std::vector<std::array<float, 3>>>::description);
  ASSERT_EQ(arrays.kind, TypeRef::Kind::Vec);
  EXPECT_EQ(arrays.element->kind, TypeRef::Kind::Array);
  EXPECT_EQ(arrays.element->element->primitive, horus::Primitive::F32);
}

TEST(PlainValueDescription, PrintsTheValueAsJsonThroughTheDescription) {
  using Triple = std::array<float, 3>;
  const TypeDescription triple = TypeDescription::decode(TypeInfo<Triple>::description);
  const std::vector<std::uint8_t> bytes = horus::encode(Triple{1.5F, -2.0F, 0.25F});
  EXPECT_EQ(horus::to_json(triple, triple.root_message(), bytes), R"({"value": [1.5, -2, 0.25]})");
  const TypeDescription text = TypeDescription::decode(TypeInfo<std::string>::description);
  EXPECT_EQ(horus::to_json(text, text.root_message(), horus::encode(std::string("hi"))),
            R"({"value": "hi"})");
}

}  // namespace
