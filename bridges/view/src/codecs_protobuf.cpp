// Images, depth images and point clouds as Foxglove's protobuf well-known schemas
// (foxglove.RawImage, foxglove.CompressedImage, foxglove.PointCloud): binary, so the pixels cross
// as they are (JSON would base64 them). The protobuf wire format and the FileDescriptorSet the
// channel advertises are written here by hand from a small table of Foxglove's .proto files
// (field names and numbers as github.com/foxglove/schemas publishes them): the product carries
// no protobuf library. Which type gets which schema, and each field's value, follow the
// recording export (runtime/python/horus/foxglove.py: _raw_image, _depth_image, _point_cloud,
// _compressed_image, IMAGE_ENCODINGS, POINT_TYPES, POINT_FIELDS, DEPTH_ENCODINGS).
//
// An image's encode is a few header bytes and one copy of the pixels into the payload, whose
// capacity is reused: no per-pixel work, no allocation once the payload has grown.
#include <array>
#include <cctype>
#include <cstring>
#include <optional>
#include <string>

#include "codecs_internal.hpp"

namespace horus::view::detail {

namespace {

// -- the wire format ------------------------------------------------------------------------------

enum class WireType : std::uint8_t { Varint = 0, Fixed64 = 1, LengthDelimited = 2, Fixed32 = 5 };

/// Appends protobuf fields to a string (whose capacity it reuses).
class ProtoWriter {
 public:
  explicit ProtoWriter(std::string& out) : out_(out) {}

  void varint(std::uint64_t value) {
    while (value >= 0x80) {
      out_ += static_cast<char>((value & 0x7F) | 0x80);
      value >>= 7;
    }
    out_ += static_cast<char>(value);
  }

  void tag(std::uint32_t field, WireType type) {
    varint((std::uint64_t{field} << 3) | static_cast<std::uint8_t>(type));
  }

  void unsigned_field(std::uint32_t field, std::uint64_t value) {
    tag(field, WireType::Varint);
    varint(value);
  }

  /// int32 / int64 / enum: negative values as their 64-bit two's complement.
  void signed_field(std::uint32_t field, std::int64_t value) {
    unsigned_field(field, static_cast<std::uint64_t>(value));
  }

  void fixed32_field(std::uint32_t field, std::uint32_t value) {
    tag(field, WireType::Fixed32);
    little_endian(value);
  }

  void double_field(std::uint32_t field, double value) {
    tag(field, WireType::Fixed64);
    std::uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof(bits));
    little_endian(bits);
  }

  void bytes_field(std::uint32_t field, std::string_view bytes) {
    tag(field, WireType::LengthDelimited);
    varint(bytes.size());
    out_.append(bytes);
  }

  /// Starts an embedded message; its fields follow, then end_message(the returned mark).
  std::size_t begin_message(std::uint32_t field) {
    tag(field, WireType::LengthDelimited);
    out_ += '\0';  // the length, rewritten by end_message
    return out_.size();
  }

  void end_message(std::size_t mark) {
    const std::size_t length = out_.size() - mark;
    std::array<char, 10> prefix{};
    std::size_t size = 0;
    for (std::uint64_t value = length; size == 0 || value != 0; value >>= 7) {
      prefix[size++] = static_cast<char>((value & 0x7F) | (value >= 0x80 ? 0x80 : 0));
    }
    out_.replace(mark - 1, 1, prefix.data(), size);
  }

 private:
  template <class T>
  void little_endian(T value) {
    for (std::size_t i = 0; i < sizeof(T); ++i) {
      out_ += static_cast<char>((value >> (8 * i)) & 0xFF);
    }
  }

  std::string& out_;
};

// -- Foxglove's .proto files, as a table ---------------------------------------------------------

// FieldDescriptorProto.Type.
enum class FieldType : std::uint8_t {
  Double = 1,
  Int64 = 3,
  Int32 = 5,
  Fixed32 = 7,
  String = 9,
  Message = 11,
  Bytes = 12,
  Enum = 14
};

struct ProtoField {
  std::string_view name;
  std::uint32_t number;
  FieldType type;
  std::string_view type_name = {};
  bool repeated = false;
};

struct ProtoEnumValue {
  std::string_view name;
  std::int32_t number;
};

struct ProtoFile {
  std::string_view path;
  std::string_view package;
  std::string_view message;
  std::vector<std::string_view> dependencies;
  std::vector<ProtoField> fields;
  /// A nested enum (PackedElementField.NumericType): its name and values.
  std::string_view enum_name = {};
  std::vector<ProtoEnumValue> enum_values = {};
};

// PackedElementField.NumericType numbers (foxglove.py's POINT_TYPES uses them too).
enum class NumericType : std::uint8_t {
  Unknown = 0,
  Uint8 = 1,
  Int8 = 2,
  Uint16 = 3,
  Int16 = 4,
  Uint32 = 5,
  Int32 = 6,
  Float32 = 7,
  Float64 = 8
};

const std::vector<ProtoFile>& proto_files() {
  static const std::vector<ProtoFile> files = {
      {"google/protobuf/timestamp.proto",
       "google.protobuf",
       "Timestamp",
       {},
       {{"seconds", 1, FieldType::Int64}, {"nanos", 2, FieldType::Int32}}},
      {"foxglove/Vector3.proto",
       "foxglove",
       "Vector3",
       {},
       {{"x", 1, FieldType::Double}, {"y", 2, FieldType::Double}, {"z", 3, FieldType::Double}}},
      {"foxglove/Quaternion.proto",
       "foxglove",
       "Quaternion",
       {},
       {{"x", 1, FieldType::Double},
        {"y", 2, FieldType::Double},
        {"z", 3, FieldType::Double},
        {"w", 4, FieldType::Double}}},
      {"foxglove/Pose.proto",
       "foxglove",
       "Pose",
       {"foxglove/Quaternion.proto", "foxglove/Vector3.proto"},
       {{"position", 1, FieldType::Message, ".foxglove.Vector3"},
        {"orientation", 2, FieldType::Message, ".foxglove.Quaternion"}}},
      {"foxglove/PackedElementField.proto",
       "foxglove",
       "PackedElementField",
       {},
       {{"name", 1, FieldType::String},
        {"offset", 2, FieldType::Fixed32},
        {"type", 3, FieldType::Enum, ".foxglove.PackedElementField.NumericType"}},
       "NumericType",
       {{"UNKNOWN", 0},
        {"UINT8", 1},
        {"INT8", 2},
        {"UINT16", 3},
        {"INT16", 4},
        {"UINT32", 5},
        {"INT32", 6},
        {"FLOAT32", 7},
        {"FLOAT64", 8}}},
      {"foxglove/RawImage.proto",
       "foxglove",
       "RawImage",
       {"google/protobuf/timestamp.proto"},
       {{"timestamp", 1, FieldType::Message, ".google.protobuf.Timestamp"},
        {"frame_id", 7, FieldType::String},
        {"width", 2, FieldType::Fixed32},
        {"height", 3, FieldType::Fixed32},
        {"encoding", 4, FieldType::String},
        {"step", 5, FieldType::Fixed32},
        {"data", 6, FieldType::Bytes}}},
      {"foxglove/CompressedImage.proto",
       "foxglove",
       "CompressedImage",
       {"google/protobuf/timestamp.proto"},
       {{"timestamp", 1, FieldType::Message, ".google.protobuf.Timestamp"},
        {"frame_id", 4, FieldType::String},
        {"data", 2, FieldType::Bytes},
        {"format", 3, FieldType::String}}},
      {"foxglove/PointCloud.proto",
       "foxglove",
       "PointCloud",
       {"foxglove/PackedElementField.proto", "foxglove/Pose.proto",
        "google/protobuf/timestamp.proto"},
       {{"timestamp", 1, FieldType::Message, ".google.protobuf.Timestamp"},
        {"frame_id", 2, FieldType::String},
        {"pose", 3, FieldType::Message, ".foxglove.Pose"},
        {"point_stride", 4, FieldType::Fixed32},
        {"fields", 5, FieldType::Message, ".foxglove.PackedElementField", true},
        {"data", 6, FieldType::Bytes}}},
  };
  return files;
}

const ProtoFile* proto_file(std::string_view path) {
  for (const ProtoFile& file : proto_files()) {
    if (file.path == path) return &file;
  }
  return nullptr;
}

/// google.protobuf.FileDescriptorProto of `file` (fields: name 1, package 2, dependency 3,
/// message_type 4, syntax 12; DescriptorProto: name 1, field 2, enum_type 4;
/// FieldDescriptorProto: name 1, number 3, label 4, type 5, type_name 6).
std::string file_descriptor(const ProtoFile& file) {
  constexpr std::uint64_t kLabelOptional = 1;
  constexpr std::uint64_t kLabelRepeated = 3;
  std::string out;
  ProtoWriter writer(out);
  writer.bytes_field(1, file.path);
  writer.bytes_field(2, file.package);
  for (const std::string_view dependency : file.dependencies) writer.bytes_field(3, dependency);
  const std::size_t message = writer.begin_message(4);
  writer.bytes_field(1, file.message);
  for (const ProtoField& field : file.fields) {
    const std::size_t mark = writer.begin_message(2);
    writer.bytes_field(1, field.name);
    writer.unsigned_field(3, field.number);
    writer.unsigned_field(4, field.repeated ? kLabelRepeated : kLabelOptional);
    writer.unsigned_field(5, static_cast<std::uint64_t>(field.type));
    if (!field.type_name.empty()) writer.bytes_field(6, field.type_name);
    writer.end_message(mark);
  }
  if (!file.enum_name.empty()) {
    // EnumDescriptorProto: name 1, value 2 (EnumValueDescriptorProto: name 1, number 2).
    const std::size_t enumeration = writer.begin_message(4);
    writer.bytes_field(1, file.enum_name);
    for (const ProtoEnumValue& value : file.enum_values) {
      const std::size_t mark = writer.begin_message(2);
      writer.bytes_field(1, value.name);
      writer.signed_field(2, value.number);
      writer.end_message(mark);
    }
    writer.end_message(enumeration);
  }
  writer.end_message(message);
  writer.bytes_field(12, "proto3");
  return out;
}

/// `path` after every file it depends on, each once (the order a descriptor pool adds them in).
void add_with_dependencies(std::string_view path, std::vector<std::string_view>& ordered) {
  for (const std::string_view done : ordered) {
    if (done == path) return;
  }
  const ProtoFile* file = proto_file(path);
  for (const std::string_view dependency : file->dependencies) {
    add_with_dependencies(dependency, ordered);
  }
  ordered.push_back(path);
}

// -- a message's top-level fields, as the protobuf codecs read them -------------------------------

/// One top-level field's value as the walk gave it.
struct FieldSlot {
  enum class Kind : std::uint8_t { Missing, Bool, Unsigned, Signed, Float, Enum, Text, Bytes };
  Kind kind = Kind::Missing;
  std::uint64_t unsigned_value = 0;
  std::int64_t signed_value = 0;
  double float_value = 0.0;
  /// Text: the string; Enum: the enumerator's name (empty for a value outside the enum).
  std::string text;
  /// Bytes: a span into the walked POD bytes, or into `owned` for a serialized message (whose
  /// MessagePack tree lives only while it is walked).
  std::span<const std::uint8_t> bytes;
  std::vector<std::uint8_t> owned;

  std::uint64_t as_unsigned() const noexcept {
    switch (kind) {
      case Kind::Unsigned:
        return unsigned_value;
      case Kind::Signed:
      case Kind::Enum:
        return signed_value < 0 ? 0 : static_cast<std::uint64_t>(signed_value);
      case Kind::Float:
        return float_value > 0 ? static_cast<std::uint64_t>(float_value) : 0;
      case Kind::Bool:
        return unsigned_value;
      default:
        return 0;
    }
  }

  /// The value as foxglove.py's str() of the plain value reads it: an enumerator's name, a text,
  /// an integer's digits.
  std::string_view name(std::string& digits) const {
    if (kind == Kind::Text || (kind == Kind::Enum && !text.empty())) return text;
    digits = kind == Kind::Signed || kind == Kind::Enum ? std::to_string(signed_value)
                                                        : std::to_string(as_unsigned());
    return digits;
  }
};

/// Walks a message and keeps the values of its own fields (not those of nested messages or
/// sequences), reusing its buffers from one message to the next.
class TopFields final : public MessageVisitor {
 public:
  TopFields(const TypeDescription& description, const MessageType& type)
      : description_(description), type_(type), slots_(type.fields.size()) {}

  void walk(std::span<const std::uint8_t> message) {
    for (FieldSlot& slot : slots_) slot.kind = FieldSlot::Kind::Missing;
    depth_ = 0;
    try {
      walk_message(description_, type_, message, *this);
    } catch (const DecodeError& error) {
      throw CodecError(std::string("a frame that is not a ") + type_.name + ": " + error.what());
    }
  }

  std::optional<std::size_t> index_of(std::string_view name) const {
    const MessageField* field = type_.find_field(name);
    if (field == nullptr) return std::nullopt;
    return static_cast<std::size_t>(field - type_.fields.data());
  }

  /// The slot of field `index`, or an empty one for a field the type lacks.
  const FieldSlot& operator[](std::optional<std::size_t> index) const {
    static const FieldSlot kMissing;
    return index ? slots_[*index] : kMissing;
  }

  void begin_message(const MessageType&) override { ++depth_; }
  void end_message(const MessageType&) override { --depth_; }
  void field(const MessageField& field) override {
    if (depth_ == 1) current_ = static_cast<std::size_t>(&field - type_.fields.data());
  }
  void boolean(bool value) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Bool)) slot->unsigned_value = value ? 1 : 0;
  }
  void unsigned_integer(const TypeRef&, std::uint64_t value) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Unsigned)) slot->unsigned_value = value;
  }
  void signed_integer(const TypeRef&, std::int64_t value) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Signed)) slot->signed_value = value;
  }
  void floating(const TypeRef&, double value) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Float)) slot->float_value = value;
  }
  void enumerator(const EnumType& type, std::int64_t value) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Enum)) {
      slot->signed_value = value;
      const Enumerator* named = type.find_value(value);
      slot->text.assign(named != nullptr ? std::string_view(named->name) : std::string_view());
    }
  }
  void string(const TypeRef&, std::string_view text) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Text)) slot->text.assign(text);
  }
  void bytes(const TypeRef&, std::span<const std::uint8_t> data) override {
    if (FieldSlot* slot = top(FieldSlot::Kind::Bytes)) {
      if (type_.is_pod) {
        slot->bytes = data;
      } else {
        slot->owned.assign(data.begin(), data.end());
        slot->bytes = slot->owned;
      }
    }
  }
  void begin_sequence(const TypeRef&, std::size_t) override { ++depth_; }
  void end_sequence(const TypeRef&) override { --depth_; }
  void begin_optional(const TypeRef&, bool) override {}
  void end_optional(const TypeRef&) override {}

 private:
  /// The slot a value at the message's own level goes in, marked `kind`; nullptr deeper down.
  FieldSlot* top(FieldSlot::Kind kind) {
    if (depth_ != 1) return nullptr;
    slots_[current_].kind = kind;
    return &slots_[current_];
  }

  const TypeDescription& description_;
  const MessageType& type_;
  std::vector<FieldSlot> slots_;
  int depth_ = 0;
  std::size_t current_ = 0;
};

// -- the codecs -----------------------------------------------------------------------------------

enum class Shape { RawImage, DepthImage, CompressedImage, PointCloud };

// foxglove.py's IMAGE_ENCODINGS: ImageEncoding names as Foxglove's RawImage encodings.
struct NamePair {
  std::string_view horus;
  std::string_view foxglove;
};
constexpr std::array<NamePair, 10> kImageEncodings = {{{"Mono8", "mono8"},
                                                       {"Mono16", "mono16"},
                                                       {"Rgb8", "rgb8"},
                                                       {"Bgr8", "bgr8"},
                                                       {"Rgba8", "rgba8"},
                                                       {"Bgra8", "bgra8"},
                                                       {"Yuv422", "yuv422"},
                                                       {"Mono32F", "32FC1"},
                                                       {"BayerRggb8", "bayer_rggb8"},
                                                       {"Depth16", "16UC1"}}};

// foxglove.py's DEPTH_ENCODINGS: a depth image's dtype as (RawImage encoding, bytes per pixel).
struct DepthEncoding {
  std::string_view dtype;
  std::string_view encoding;
  std::uint32_t size;
};
constexpr std::array<DepthEncoding, 2> kDepthEncodings = {
    {{"F32", "32FC1", 4}, {"U16", "16UC1", 2}}};
constexpr DepthEncoding kDefaultDepthEncoding = {"", "32FC1", 4};

// foxglove.py's POINT_TYPES: a point cloud's dtype as (NumericType, bytes).
struct PointType {
  std::string_view dtype;
  NumericType numeric;
  std::uint32_t size;
};
constexpr std::array<PointType, 6> kPointTypes = {{{"F32", NumericType::Float32, 4},
                                                   {"F64", NumericType::Float64, 8},
                                                   {"U8", NumericType::Uint8, 1},
                                                   {"U16", NumericType::Uint16, 2},
                                                   {"I16", NumericType::Int16, 2},
                                                   {"I32", NumericType::Int32, 4}}};
constexpr PointType kDefaultPointType = {"", NumericType::Float32, 4};

// foxglove.py's POINT_FIELDS: component names by components per point (others: f0, f1, ...).
constexpr std::array<std::string_view, 3> kXyz = {"x", "y", "z"};
constexpr std::array<std::string_view, 4> kXyzi = {"x", "y", "z", "intensity"};
constexpr std::array<std::string_view, 6> kXyzRgb = {"x", "y", "z", "red", "green", "blue"};

constexpr std::uint64_t kNanosecondsPerSecond = 1'000'000'000;

/// Components per point a point cloud may name: far above any sensor's (XYZ, XYZI, XYZRGB).
constexpr std::uint64_t kMaxPointComponents = 256;

class ProtobufCodec final : public MessageCodec {
 public:
  ProtobufCodec(std::shared_ptr<const DescribedType> type, std::string_view schema_name,
                std::string topic)
      : type_(std::move(type)),
        topic_(std::move(topic)),
        fields_(type_->description, *type_->message) {
    if (schema_name == "foxglove.CompressedImage") {
      shape_ = Shape::CompressedImage;
    } else if (schema_name == "foxglove.PointCloud") {
      shape_ = Shape::PointCloud;
    } else if (type_->pool_backed && type_->message->name == "horus.msg.DepthImageDescriptor") {
      shape_ = Shape::DepthImage;
    } else {
      shape_ = Shape::RawImage;
    }
    for (const char* name : {"timestamp_ns", "frame_id", "width", "height", "step", "encoding",
                             "data", "format", "dtype", "fields_per_point"}) {
      indices_.emplace_back(name, fields_.index_of(name));
    }
    schema_ = ChannelSchema{"protobuf", std::string(schema_name), "protobuf",
                            foxglove_descriptor_set(schema_name), true};
  }

  const ChannelSchema& schema() const override { return schema_; }

  void encode(std::span<const std::byte> frame, std::vector<std::byte>& payload) override {
    const FrameParts parts = split_frame(*type_, frame);
    fields_.walk(parts.message);
    std::span<const std::uint8_t> data = parts.data;
    if (!type_->pool_backed) {
      const FieldSlot& field = slot("data");
      if (field.kind != FieldSlot::Kind::Bytes) {
        throw CodecError(type_->message->name + ": its field 'data' is not a byte block");
      }
      data = field.bytes;
    }
    header_.clear();
    ProtoWriter writer(header_);
    timestamp(writer);
    switch (shape_) {
      case Shape::RawImage:
      case Shape::DepthImage:
        raw_image(writer);
        break;
      case Shape::CompressedImage:
        writer.bytes_field(4, frame_name());
        writer.bytes_field(3, slot("format").text);
        break;
      case Shape::PointCloud:
        point_cloud(writer);
        break;
    }
    // The data field's tag and length end the header: CompressedImage's data is field 2,
    // RawImage's and PointCloud's field 6.
    writer.tag(shape_ == Shape::CompressedImage ? 2 : 6, WireType::LengthDelimited);
    writer.varint(data.size());
    // The data last, in one copy: the payload keeps its size (and bytes) when frames are alike.
    payload.resize(header_.size() + data.size());
    std::memcpy(payload.data(), header_.data(), header_.size());
    if (!data.empty()) std::memcpy(payload.data() + header_.size(), data.data(), data.size());
  }

  void decode(std::span<const std::byte>, std::vector<std::byte>&) override {
    throw CodecError(shape_ == Shape::PointCloud
                         ? "publishing point clouds from a viewer is not supported"
                         : "publishing images from a viewer is not supported");
  }

 private:
  const FieldSlot& slot(std::string_view name) const {
    for (const auto& [field, index] : indices_) {
      if (field == name) return fields_[index];
    }
    return fields_[std::nullopt];
  }

  std::string_view frame_name() const {
    const FieldSlot& frame_id = slot("frame_id");
    return frame_id.kind == FieldSlot::Kind::Text && !frame_id.text.empty()
               ? std::string_view(frame_id.text)
               : std::string_view(topic_);
  }

  /// google.protobuf.Timestamp (seconds 1, nanos 2) of the message's timestamp_ns, or now.
  void timestamp(ProtoWriter& writer) const {
    std::uint64_t ns = slot("timestamp_ns").as_unsigned();
    if (ns == 0) ns = now_ns();
    const std::size_t mark = writer.begin_message(1);
    writer.unsigned_field(1, ns / kNanosecondsPerSecond);
    writer.unsigned_field(2, ns % kNanosecondsPerSecond);
    writer.end_message(mark);
  }

  /// foxglove.RawImage's fields but the data.
  void raw_image(ProtoWriter& writer) {
    const std::uint64_t width = slot("width").as_unsigned();
    std::string_view encoding;
    std::uint64_t step = 0;
    if (shape_ == Shape::DepthImage) {
      std::string_view dtype = slot("dtype").name(digits_);
      DepthEncoding depth = kDefaultDepthEncoding;
      for (const DepthEncoding& known : kDepthEncodings) {
        if (known.dtype == dtype) depth = known;
      }
      encoding = depth.encoding;
      step = width * depth.size;
    } else {
      encoding = slot("encoding").name(digits_);
      bool mapped = false;
      for (const NamePair& known : kImageEncodings) {
        if (known.horus == encoding) {
          encoding = known.foxglove;
          mapped = true;
        }
      }
      if (!mapped) {
        // An encoding Foxglove names as HORUS does, but lower-case (foxglove.py: str().lower()).
        lower_.assign(encoding);
        for (char& c : lower_) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        encoding = lower_;
      }
      step = slot("step").as_unsigned();
    }
    writer.bytes_field(7, frame_name());
    writer.fixed32_field(2, static_cast<std::uint32_t>(width));
    writer.fixed32_field(3, static_cast<std::uint32_t>(slot("height").as_unsigned()));
    writer.bytes_field(4, encoding);
    writer.fixed32_field(5, static_cast<std::uint32_t>(step));
  }

  /// foxglove.PointCloud's fields but the data.
  void point_cloud(ProtoWriter& writer) {
    const std::string_view dtype = slot("dtype").name(digits_);
    PointType point = kDefaultPointType;
    for (const PointType& known : kPointTypes) {
      if (known.dtype == dtype) point = known;
    }
    const std::uint64_t components = slot("fields_per_point").as_unsigned();
    if (components > kMaxPointComponents) {
      // A descriptor from another process: its count bounds the header written here.
      throw CodecError(type_->message->name + ": " + std::to_string(components) +
                       " components per point, more than " + std::to_string(kMaxPointComponents));
    }
    writer.bytes_field(2, frame_name());
    identity_pose(writer);
    writer.fixed32_field(4, static_cast<std::uint32_t>(point.size * components));
    for (std::uint64_t i = 0; i < components; ++i) {
      const std::size_t mark = writer.begin_message(5);
      writer.bytes_field(1, component_name(components, i));
      writer.fixed32_field(2, static_cast<std::uint32_t>(i * point.size));
      writer.unsigned_field(3, static_cast<std::uint64_t>(point.numeric));
      writer.end_message(mark);
    }
  }

  std::string_view component_name(std::uint64_t components, std::uint64_t i) {
    if (components == kXyz.size()) return kXyz[i];
    if (components == kXyzi.size()) return kXyzi[i];
    if (components == kXyzRgb.size()) return kXyzRgb[i];
    digits_ = "f" + std::to_string(i);
    return digits_;
  }

  /// foxglove.Pose at the frame's origin (the export's _identity_pose), field 3.
  static void identity_pose(ProtoWriter& writer) {
    const std::size_t pose = writer.begin_message(3);
    const std::size_t position = writer.begin_message(1);
    writer.double_field(1, 0.0);
    writer.double_field(2, 0.0);
    writer.double_field(3, 0.0);
    writer.end_message(position);
    const std::size_t orientation = writer.begin_message(2);
    writer.double_field(1, 0.0);
    writer.double_field(2, 0.0);
    writer.double_field(3, 0.0);
    writer.double_field(4, 1.0);
    writer.end_message(orientation);
    writer.end_message(pose);
  }

  std::shared_ptr<const DescribedType> type_;
  std::string topic_;
  Shape shape_ = Shape::RawImage;
  TopFields fields_;
  std::vector<std::pair<std::string_view, std::optional<std::size_t>>> indices_;
  ChannelSchema schema_;
  std::string header_;
  std::string digits_;
  std::string lower_;
};

}  // namespace

std::string foxglove_descriptor_set(std::string_view schema_name) {
  const std::string_view message = schema_name.substr(schema_name.find('.') + 1);
  const std::string path = "foxglove/" + std::string(message) + ".proto";
  if (proto_file(path) == nullptr) {
    throw CodecError("no Foxglove protobuf schema called " + std::string(schema_name));
  }
  std::vector<std::string_view> ordered;
  add_with_dependencies(path, ordered);
  // google.protobuf.FileDescriptorSet: file 1, repeated.
  std::string out;
  ProtoWriter writer(out);
  for (const std::string_view file : ordered)
    writer.bytes_field(1, file_descriptor(*proto_file(file)));
  return out;
}

std::unique_ptr<MessageCodec> make_protobuf_codec(std::shared_ptr<const DescribedType> type,
                                                  std::string_view schema_name, std::string topic) {
  return std::make_unique<ProtobufCodec>(std::move(type), schema_name, std::move(topic));
}

}  // namespace horus::view::detail
