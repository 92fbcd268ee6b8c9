// What horus-remote writes for types it was not compiled with (bridges/remote/zero_message.cpp,
// services.cpp: failure_frame), read back by the decoders of the types themselves: the
// standard serialized messages (bytes, Option, Vec<i8>, Vec<u8>, nested messages, fixed
// strings) and a serialized response frame, each from its type description.
#include <gtest/gtest.h>

#include <horus/msg/compressed_image.hpp>
#include <horus/msg/cost_map.hpp>
#include <horus/msg/generic_message.hpp>
#include <horus/msg/occupancy_grid.hpp>

#include <cstring>
#include <string>

#include "horus/codec.hpp"
#include "horus/detail/service_frame.hpp"
#include "horus/msgpack.hpp"
#include "horus/type_description.hpp"
#include "services.hpp"
#include "zero_message.hpp"

namespace {

template <class T>
T decoded_zero() {
  horus::TopicInfo type;
  type.type_name = horus::TypeInfo<T>::name;
  type.schema = horus::TypeInfo<T>::schema;
  type.description = horus::TypeInfo<T>::description;
  const std::vector<std::byte> bytes = horus::remote::zero_message(type);
  return horus::decode<T>(
      std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
}

TEST(ZeroMessage, DecodesAsTheStandardSerializedMessages) {
  EXPECT_TRUE(decoded_zero<horus::msg::GenericMessage>().data.empty());
  EXPECT_FALSE(decoded_zero<horus::msg::GenericMessage>().metadata.has_value());
  const auto grid = decoded_zero<horus::msg::OccupancyGrid>();
  EXPECT_TRUE(grid.data.empty());
  EXPECT_EQ(grid.width, 0U);
  EXPECT_EQ(grid.resolution, 0.0F);  // zero, not the schema's default
  EXPECT_TRUE(decoded_zero<horus::msg::CostMap>().costs.empty());
  EXPECT_TRUE(decoded_zero<horus::msg::CompressedImage>().data.empty());
}

TEST(ZeroMessage, NamesATypeTheDescriptionDoesNotHold) {
  horus::TopicInfo type;
  type.type_name = "horus.msg.Nothing";
  type.description = horus::TypeInfo<horus::msg::GenericMessage>::description;
  EXPECT_THROW(horus::remote::zero_message(type), horus::TypeDescriptionError);
}

TEST(ZeroMessage, ATypeWithoutADescriptionIsRefusedSayingSo) {
  horus::TopicInfo type;
  type.name = "old";
  type.type_name = horus::TypeInfo<horus::msg::GenericMessage>::name;
  type.schema = horus::TypeInfo<horus::msg::GenericMessage>::schema;
  try {
    horus::remote::zero_message(type);
    FAIL() << "a type without a description gave a message";
  } catch (const horus::TypeDescriptionError& e) {
    EXPECT_NE(std::string(e.what()).find("carries no type description"), std::string::npos)
        << e.what();
  }
}

TEST(FailureFrame, DecodesAsASerializedResponseFrame) {
  using Frame = horus::detail::ServiceResponseFrame<horus::msg::OccupancyGrid>;
  horus::TopicInfo type;
  type.type_name = horus::TypeInfo<Frame>::name;
  type.schema = horus::TypeInfo<Frame>::schema;
  type.description = horus::TypeInfo<Frame>::description;
  type.is_pod = false;
  const std::string text(300, 'x');  // longer than a POD frame holds: kept whole here
  const std::vector<std::byte> bytes =
      horus::remote::failure_frame(type, 7, 1ULL << 40, horus::ServiceError::timeout(text));
  const Frame frame = horus::decode<Frame>(
      std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
  EXPECT_EQ(frame.client_id, 7U);
  EXPECT_EQ(frame.request_id, 1ULL << 40);
  EXPECT_EQ(frame.status, horus::detail::kStatusTimeout);
  EXPECT_EQ(frame.error, text);
}

}  // namespace
