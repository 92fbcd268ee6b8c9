// What the codec sources share: a small JSON value (the JSON codecs build and print it, and read
// it from Cap'n Proto's parse of a viewer's text), messages as such values and back through the
// type description (walk_message, build_message), and one factory per kind of codec (codecs.cpp
// picks among them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "horus/type_description.hpp"
#include "horus/view/codecs.hpp"

namespace horus::view::detail {

struct JsonMember;

/// One JSON value, an object's members in the order they were set (the order they are printed).
struct JsonValue {
  enum class Kind : std::uint8_t {
    Null,
    Bool,
    Unsigned,
    Signed,
    Float,
    String,
    Bytes,
    Array,
    Object
  };
  Kind kind = Kind::Null;
  bool boolean = false;
  std::uint64_t unsigned_value = 0;
  std::int64_t signed_value = 0;
  double float_value = 0.0;
  /// Float: printed as the shortest text that reads back as the same f32.
  bool single_precision = false;
  /// String: the text; Bytes: the bytes (printed as base64, or as an array of numbers when
  /// `bytes_as_numbers`: the JSON Schema's [u8; N] is an array).
  std::string text;
  bool bytes_as_numbers = false;
  std::vector<JsonValue> items;
  std::vector<JsonMember> members;

  static JsonValue null();
  static JsonValue of_bool(bool value);
  static JsonValue of_unsigned(std::uint64_t value);
  static JsonValue of_signed(std::int64_t value);
  static JsonValue of_float(double value, bool single_precision = false);
  static JsonValue of_string(std::string value);
  static JsonValue of_bytes(std::span<const std::uint8_t> data);
  static JsonValue array();
  static JsonValue object();

  /// Appends a member (objects) and returns *this, so objects are written as one expression.
  JsonValue& set(std::string key, JsonValue value);
  /// Appends an element (arrays).
  JsonValue& push(JsonValue value);
  /// The member called `key`, or nullptr.
  const JsonValue* find(std::string_view key) const noexcept;
  JsonValue* find(std::string_view key) noexcept;
  bool is_number() const noexcept;
  /// Any number as a double (0 for other kinds).
  double number() const noexcept;
};

struct JsonMember {
  std::string key;
  JsonValue value;
};

/// `value` as compact JSON text appended to `out`; non-finite floats as null, bytes as base64.
void write_json(const JsonValue& value, std::string& out);
/// One whole JSON text, read by Cap'n Proto's JSON parser (every number a Float); CodecError
/// saying what is wrong.
JsonValue parse_json(std::string_view text);

/// Throws CodecError naming `where` when `text` is not base64.
std::string decode_base64(std::string_view text, std::string_view where);

/// A message's plain values, as Python's horus.typedesc.to_plain gives them: objects of fields,
/// enums as their enumerator's name (a value outside the enum as its number), byte blocks as
/// Bytes. With `wide_integers_as_strings`, u64 and i64 values become strings of their digits (what
/// the live view's JSON Schemas say of them: a JavaScript number cannot hold them).
JsonValue message_value(const TypeDescription& description, const MessageType& type,
                        std::span<const std::uint8_t> bytes, bool wide_integers_as_strings);

/// The frame of a `type` message holding `value` (an object as message_value gives it, wide
/// integers as strings or numbers): POD bytes or MessagePack as the generated code writes them.
/// Throws CodecError naming the field whose value does not fit the type.
void encode_message(const TypeDescription& description, const MessageType& type,
                    const JsonValue& value, std::vector<std::byte>& frame);

/// `type`'s JSON Schema as `horus-gen --lang jsonschema` writes it (generator/horus_gen/lang/
/// jsonschema.py) from the description (which has no doc comments: descriptions are the units'),
/// with u64 and i64 as strings of digits.
JsonValue json_schema(const TypeDescription& description, const MessageType& type);

/// The description of a topic's type and the message its frames hold.
struct DescribedType {
  TypeDescription description;
  const MessageType* message = nullptr;
  /// A pool-backed type's frames are the descriptor (message->size bytes) then the block's data.
  bool pool_backed = false;
};

/// The message bytes of a frame (a pool frame's descriptor), and the data after them.
struct FrameParts {
  std::span<const std::uint8_t> message;
  std::span<const std::uint8_t> data;
};
FrameParts split_frame(const DescribedType& type, std::span<const std::byte> frame);

/// Nanoseconds since the epoch now (CLOCK_REALTIME): a frame's stamp when it carries none, as
/// the export takes the message's log time.
std::uint64_t now_ns() noexcept;

std::unique_ptr<MessageCodec> make_json_codec(std::shared_ptr<const DescribedType> type);
/// Foxglove's JSON well-known schemas: `schema_name` one of foxglove.LaserScan,
/// foxglove.PoseInFrame, foxglove.PosesInFrame (a horus.msg.Path), foxglove.FrameTransform.
std::unique_ptr<MessageCodec> make_foxglove_json_codec(std::shared_ptr<const DescribedType> type,
                                                       std::string_view schema_name,
                                                       std::string topic);
/// Foxglove's protobuf well-known schemas: `schema_name` one of foxglove.RawImage (a message with
/// its pixels, or a depth image), foxglove.CompressedImage, foxglove.PointCloud.
std::unique_ptr<MessageCodec> make_protobuf_codec(std::shared_ptr<const DescribedType> type,
                                                  std::string_view schema_name, std::string topic);

/// The JSON Schema of a Foxglove JSON well-known schema, as foxglove.py's FOXGLOVE_SCHEMAS.
JsonValue foxglove_json_schema(std::string_view schema_name);
/// The serialized google.protobuf.FileDescriptorSet of a Foxglove protobuf well-known schema.
std::string foxglove_descriptor_set(std::string_view schema_name);

}  // namespace horus::view::detail
