// codec_for: which Foxglove schema a topic's type becomes. The decisions are the recording
// export's (runtime/python/horus/foxglove.py: BY_TYPE, WITH_DATA_BY_TYPE, BY_SHAPE and
// foxglove_mapping), made here from the type description; tests/view/test_view_codecs.py checks
// that both give every standard type the same schema.
#include <algorithm>
#include <array>
#include <chrono>
#include <optional>
#include <span>
#include <string_view>

#include "codecs_internal.hpp"

namespace horus::view {

namespace detail {

FrameParts split_frame(const DescribedType& type, std::span<const std::byte> frame) {
  const std::span bytes(reinterpret_cast<const std::uint8_t*>(frame.data()), frame.size());
  if (!type.pool_backed) return {bytes, {}};
  const std::size_t size = type.message->size;
  if (bytes.size() < size) {
    throw CodecError("a " + type.message->name + " pool frame of " + std::to_string(bytes.size()) +
                     " bytes, shorter than its " + std::to_string(size) + "-byte descriptor");
  }
  return {bytes.first(size), bytes.subspan(size)};
}

std::uint64_t now_ns() noexcept {
  return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                        std::chrono::system_clock::now().time_since_epoch())
                                        .count());
}

}  // namespace detail

namespace {

// The descriptor types of the pool-backed types (horus::Image, DepthImage, PointCloud, Tensor:
// their TypeInfo says is_pool_backed), whose frames carry the block's data after the descriptor.
constexpr std::array<std::string_view, 4> kPoolDescriptors = {
    "horus.msg.ImageDescriptor", "horus.msg.DepthImageDescriptor", "horus.msg.PointCloudDescriptor",
    "horus.msg.TensorDescriptor"};

enum class Encoding { Json, Protobuf };

struct Mapping {
  std::string_view schema_name;
  Encoding encoding;
};

// foxglove.py's BY_TYPE.
struct TypeMapping {
  std::string_view type_name;
  Mapping mapping;
};
constexpr std::array<TypeMapping, 5> kByType = {{
    {"horus.msg.LaserScan", {"foxglove.LaserScan", Encoding::Json}},
    {"horus.msg.PoseStamped", {"foxglove.PoseInFrame", Encoding::Json}},
    {"horus.msg.Path", {"foxglove.PosesInFrame", Encoding::Json}},
    {"horus.msg.TransformStamped", {"foxglove.FrameTransform", Encoding::Json}},
    {"horus.msg.CompressedImage", {"foxglove.CompressedImage", Encoding::Protobuf}},
}};

// foxglove.py's WITH_DATA_BY_TYPE: drawn only with their data (a pool frame).
constexpr TypeMapping kDepthImage = {"horus.msg.DepthImageDescriptor",
                                     {"foxglove.RawImage", Encoding::Protobuf}};

// foxglove.py's BY_SHAPE: a message carrying its pixels, or its points.
constexpr std::array<std::string_view, 5> kPixelFields = {"width", "height", "step", "encoding",
                                                          "data"};
constexpr std::array<std::string_view, 4> kPointFields = {"point_count", "fields_per_point",
                                                          "dtype", "data"};
struct ShapeMapping {
  std::span<const std::string_view> fields;
  Mapping mapping;
};
constexpr std::array<ShapeMapping, 2> kByShape = {{
    {kPixelFields, {"foxglove.RawImage", Encoding::Protobuf}},
    {kPointFields, {"foxglove.PointCloud", Encoding::Protobuf}},
}};

/// The Foxglove schema `type` is drawn with, none for a type shown as its plain values.
std::optional<Mapping> foxglove_mapping(const detail::DescribedType& type) {
  const std::string& name = type.message->name;
  for (const TypeMapping& by_type : kByType) {
    if (by_type.type_name == name) return by_type.mapping;
  }
  // A pool frame's data is a field of its own, as the export adds "data" to the descriptor's.
  const auto has_field = [&](std::string_view field) {
    return type.message->find_field(field) != nullptr || (type.pool_backed && field == "data");
  };
  if (type.pool_backed && name == kDepthImage.type_name) return kDepthImage.mapping;
  for (const ShapeMapping& shape : kByShape) {
    if (std::all_of(shape.fields.begin(), shape.fields.end(), has_field)) return shape.mapping;
  }
  return std::nullopt;
}

}  // namespace

std::unique_ptr<MessageCodec> codec_for(const horus::TypeIdentity& type, const std::string& topic) {
  if (type.description.empty()) {
    throw CodecError("topic '" + topic + "' (" + type.name +
                     ") carries no type description: the live view cannot decode it");
  }
  auto described = std::make_shared<detail::DescribedType>();
  try {
    described->description = TypeDescription::decode(type.description);
    described->message = &described->description.root_message();
  } catch (const TypeDescriptionError& error) {
    throw CodecError("topic '" + topic + "' (" + type.name +
                     "): its type description cannot be read: " + error.what());
  }
  described->pool_backed =
      described->message->is_pod && std::find(kPoolDescriptors.begin(), kPoolDescriptors.end(),
                                              described->message->name) != kPoolDescriptors.end();
  const std::optional<Mapping> mapping = foxglove_mapping(*described);
  if (!mapping) return detail::make_json_codec(std::move(described));
  if (mapping->encoding == Encoding::Json) {
    return detail::make_foxglove_json_codec(std::move(described), mapping->schema_name, topic);
  }
  return detail::make_protobuf_codec(std::move(described), mapping->schema_name, topic);
}

}  // namespace horus::view
