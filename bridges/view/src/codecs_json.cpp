// Every type Foxglove has no schema of its own for: its plain values as JSON, under the JSON
// Schema `horus-gen --lang jsonschema` writes for it, made here from the type description as the
// recording export makes it (runtime/python/horus/foxglove.py, generated_json_schema and
// wide_integers_as_strings: the other home of these rules).
#include <cstdint>
#include <string>

#include "codecs_internal.hpp"

namespace horus::view::detail {

namespace {

/// The dialect `horus-gen --lang jsonschema` writes (lang/jsonschema.py, DIALECT).
constexpr std::string_view kJsonSchemaDialect = "https://json-schema.org/draft/2020-12/schema";

JsonValue type_schema(const TypeDescription& description, const TypeRef& type);

JsonValue message_schema(const TypeDescription& description, const MessageType& type) {
  JsonValue properties = JsonValue::object();
  JsonValue required = JsonValue::array();
  for (const MessageField& field : type.fields) {
    JsonValue schema = type_schema(description, field.type);
    // The description keeps no doc comments: a field is described by its unit alone.
    if (!field.unit.empty())
      schema.set("description", JsonValue::of_string("[" + field.unit + "]"));
    properties.set(field.name, std::move(schema));
    required.push(JsonValue::of_string(field.name));
  }
  JsonValue schema = JsonValue::object();
  schema.set("title", JsonValue::of_string(type.name))
      .set("type", JsonValue::of_string("object"))
      .set("properties", std::move(properties))
      .set("required", std::move(required))
      .set("additionalProperties", JsonValue::of_bool(false));
  return schema;
}

JsonValue integer_schema(Primitive primitive) {
  const std::size_t bits = primitive_size(primitive) * 8;
  JsonValue schema = JsonValue::object();
  switch (primitive) {
    case Primitive::U64:
    case Primitive::I64:
      // Past 2^53 a JavaScript number (Foxglove reads JSON numbers as doubles) rounds them:
      // their digits as a string.
      schema.set("type", JsonValue::of_string("string"))
          .set("pattern",
               JsonValue::of_string(primitive == Primitive::I64 ? "^-?[0-9]+$" : "^[0-9]+$"));
      return schema;
    case Primitive::I8:
    case Primitive::I16:
    case Primitive::I32:
      schema.set("type", JsonValue::of_string("integer"))
          .set("minimum", JsonValue::of_signed(-(std::int64_t{1} << (bits - 1))))
          .set("maximum", JsonValue::of_signed((std::int64_t{1} << (bits - 1)) - 1));
      return schema;
    default:
      schema.set("type", JsonValue::of_string("integer"))
          .set("minimum", JsonValue::of_unsigned(0))
          .set("maximum", JsonValue::of_unsigned((std::uint64_t{1} << bits) - 1));
      return schema;
  }
}

JsonValue type_schema(const TypeDescription& description, const TypeRef& type) {
  JsonValue schema = JsonValue::object();
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      if (type.primitive == Primitive::Bool) {
        schema.set("type", JsonValue::of_string("boolean"));
        return schema;
      }
      if (type.primitive == Primitive::F32 || type.primitive == Primitive::F64) {
        // null: NaN or an infinity, which JSON cannot spell.
        JsonValue kinds = JsonValue::array();
        kinds.push(JsonValue::of_string("number")).push(JsonValue::of_string("null"));
        schema.set("type", std::move(kinds));
        return schema;
      }
      return integer_schema(type.primitive);
    case TypeRef::Kind::FixedString:
    case TypeRef::Kind::String:
      schema.set("type", JsonValue::of_string("string"));
      return schema;
    case TypeRef::Kind::Bytes:
    case TypeRef::Kind::Vec:
      if (type.is_byte_block()) {
        schema.set("type", JsonValue::of_string("string"))
            .set("contentEncoding", JsonValue::of_string("base64"));
        return schema;
      }
      schema.set("type", JsonValue::of_string("array"))
          .set("items", type_schema(description, *type.element));
      return schema;
    case TypeRef::Kind::Array:
      schema.set("type", JsonValue::of_string("array"))
          .set("items", type_schema(description, *type.element))
          .set("minItems", JsonValue::of_unsigned(type.length))
          .set("maxItems", JsonValue::of_unsigned(type.length));
      return schema;
    case TypeRef::Kind::Optional: {
      JsonValue none = JsonValue::object();
      none.set("type", JsonValue::of_string("null"));
      JsonValue any = JsonValue::array();
      any.push(type_schema(description, *type.element)).push(std::move(none));
      schema.set("anyOf", std::move(any));
      return schema;
    }
    case TypeRef::Kind::Message:
      return message_schema(description, description.message(type));
    case TypeRef::Kind::Enum: {
      const EnumType& enumeration = description.enumeration(type);
      JsonValue names = JsonValue::array();
      for (const Enumerator& value : enumeration.values)
        names.push(JsonValue::of_string(value.name));
      schema.set("title", JsonValue::of_string(enumeration.name))
          .set("type", JsonValue::of_string("string"))
          .set("enum", std::move(names));
      return schema;
    }
  }
  return schema;
}

class JsonCodec final : public MessageCodec {
 public:
  explicit JsonCodec(std::shared_ptr<const DescribedType> type) : type_(std::move(type)) {
    const MessageType& message = *type_->message;
    std::string text;
    write_json(json_schema(type_->description, message), text);
    schema_ = ChannelSchema{"json", message.name, "jsonschema", std::move(text), false};
  }

  const ChannelSchema& schema() const override { return schema_; }

  void encode(std::span<const std::byte> frame, std::vector<std::byte>& payload) override {
    // A pool frame (a tensor's) shows its descriptor: Foxglove has no schema for the data.
    const FrameParts parts = split_frame(*type_, frame);
    text_.clear();
    write_json(message_value(type_->description, *type_->message, parts.message, true), text_);
    const auto* data = reinterpret_cast<const std::byte*>(text_.data());
    payload.assign(data, data + text_.size());
  }

  void decode(std::span<const std::byte> payload, std::vector<std::byte>& frame) override {
    if (type_->pool_backed) {
      throw CodecError("publishing " + type_->message->name +
                       " frames from a viewer is not supported (their data lives in a pool)");
    }
    const JsonValue value =
        parse_json(std::string_view(reinterpret_cast<const char*>(payload.data()), payload.size()));
    encode_message(type_->description, *type_->message, value, frame);
  }

 private:
  std::shared_ptr<const DescribedType> type_;
  ChannelSchema schema_;
  std::string text_;
};

}  // namespace

JsonValue json_schema(const TypeDescription& description, const MessageType& type) {
  JsonValue schema = JsonValue::object();
  schema.set("$schema", JsonValue::of_string(std::string(kJsonSchemaDialect)));
  for (auto& member : message_schema(description, type).members) {
    schema.set(std::move(member.key), std::move(member.value));
  }
  return schema;
}

std::unique_ptr<MessageCodec> make_json_codec(std::shared_ptr<const DescribedType> type) {
  return std::make_unique<JsonCodec>(std::move(type));
}

}  // namespace horus::view::detail
