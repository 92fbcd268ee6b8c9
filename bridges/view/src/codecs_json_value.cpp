// The JSON value the JSON codecs work on: built and printed here; read from a viewer's text by
// Cap'n Proto's JSON parser (the one the view's protocol reads its messages with); bytes as
// base64 through kj's codec.
#include <capnp/compat/json.h>
#include <capnp/message.h>
#include <kj/encoding.h>

#include <array>
#include <charconv>
#include <cmath>

#include "codecs_internal.hpp"

namespace horus::view::detail {

JsonValue JsonValue::null() { return {}; }

JsonValue JsonValue::of_bool(bool value) {
  JsonValue out;
  out.kind = Kind::Bool;
  out.boolean = value;
  return out;
}

JsonValue JsonValue::of_unsigned(std::uint64_t value) {
  JsonValue out;
  out.kind = Kind::Unsigned;
  out.unsigned_value = value;
  return out;
}

JsonValue JsonValue::of_signed(std::int64_t value) {
  JsonValue out;
  out.kind = Kind::Signed;
  out.signed_value = value;
  return out;
}

JsonValue JsonValue::of_float(double value, bool single_precision) {
  JsonValue out;
  out.kind = Kind::Float;
  out.float_value = value;
  out.single_precision = single_precision;
  return out;
}

JsonValue JsonValue::of_string(std::string value) {
  JsonValue out;
  out.kind = Kind::String;
  out.text = std::move(value);
  return out;
}

JsonValue JsonValue::of_bytes(std::span<const std::uint8_t> data) {
  JsonValue out;
  out.kind = Kind::Bytes;
  out.text.assign(reinterpret_cast<const char*>(data.data()), data.size());
  return out;
}

JsonValue JsonValue::array() {
  JsonValue out;
  out.kind = Kind::Array;
  return out;
}

JsonValue JsonValue::object() {
  JsonValue out;
  out.kind = Kind::Object;
  return out;
}

JsonValue& JsonValue::set(std::string key, JsonValue value) {
  members.push_back({std::move(key), std::move(value)});
  return *this;
}

JsonValue& JsonValue::push(JsonValue value) {
  items.push_back(std::move(value));
  return *this;
}

const JsonValue* JsonValue::find(std::string_view key) const noexcept {
  for (const JsonMember& member : members) {
    if (member.key == key) return &member.value;
  }
  return nullptr;
}

JsonValue* JsonValue::find(std::string_view key) noexcept {
  for (JsonMember& member : members) {
    if (member.key == key) return &member.value;
  }
  return nullptr;
}

bool JsonValue::is_number() const noexcept {
  return kind == Kind::Unsigned || kind == Kind::Signed || kind == Kind::Float;
}

double JsonValue::number() const noexcept {
  switch (kind) {
    case Kind::Unsigned:
      return static_cast<double>(unsigned_value);
    case Kind::Signed:
      return static_cast<double>(signed_value);
    case Kind::Float:
      return float_value;
    default:
      return 0.0;
  }
}

// -- printing -------------------------------------------------------------------------------------

namespace {

void write_string(std::string_view text, std::string& out) {
  out += '"';
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\r') {
      out += "\\r";
    } else if (byte < 0x20) {
      static constexpr std::string_view kHex = "0123456789abcdef";
      out += "\\u00";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xF];
    } else {
      out += c;
    }
  }
  out += '"';
}

template <class T>
void write_number(T value, std::string& out) {
  std::array<char, 32> text{};
  const std::to_chars_result result = std::to_chars(text.data(), text.data() + text.size(), value);
  out.append(text.data(), result.ptr);
}

}  // namespace

std::string decode_base64(std::string_view text, std::string_view where) {
  const kj::EncodingResult<kj::Array<kj::byte>> decoded =
      kj::decodeBase64(kj::arrayPtr(text.data(), text.size()));
  if (decoded.hadErrors) throw CodecError(std::string(where) + ": not base64");
  return std::string(decoded.asChars().begin(), decoded.asChars().end());
}

void write_json(const JsonValue& value, std::string& out) {
  using Kind = JsonValue::Kind;
  switch (value.kind) {
    case Kind::Null:
      out += "null";
      return;
    case Kind::Bool:
      out += value.boolean ? "true" : "false";
      return;
    case Kind::Unsigned:
      write_number(value.unsigned_value, out);
      return;
    case Kind::Signed:
      write_number(value.signed_value, out);
      return;
    case Kind::Float:
      if (!std::isfinite(value.float_value)) {
        out += "null";  // JSON has no NaN or infinity
      } else if (value.single_precision) {
        write_number(static_cast<float>(value.float_value), out);
      } else {
        write_number(value.float_value, out);
      }
      return;
    case Kind::String:
      write_string(value.text, out);
      return;
    case Kind::Bytes: {
      const std::span data(reinterpret_cast<const std::uint8_t*>(value.text.data()),
                           value.text.size());
      if (!value.bytes_as_numbers) {
        out += '"';
        out += kj::encodeBase64(kj::arrayPtr(data.data(), data.size())).cStr();
        out += '"';
        return;
      }
      out += '[';
      for (std::size_t i = 0; i < data.size(); ++i) {
        if (i != 0) out += ',';
        write_number(data[i], out);
      }
      out += ']';
      return;
    }
    case Kind::Array:
      out += '[';
      for (std::size_t i = 0; i < value.items.size(); ++i) {
        if (i != 0) out += ',';
        write_json(value.items[i], out);
      }
      out += ']';
      return;
    case Kind::Object:
      out += '{';
      for (std::size_t i = 0; i < value.members.size(); ++i) {
        if (i != 0) out += ',';
        write_string(value.members[i].key, out);
        out += ':';
        write_json(value.members[i].value, out);
      }
      out += '}';
      return;
  }
}

// -- reading
// ---------------------------------------------------------------------------------------

namespace {

/// Nesting accepted from a viewer: far deeper than any message, shallow enough for the stack.
constexpr std::size_t kMaxJsonDepth = 256;

/// Cap'n Proto's tree of a JSON text as the codecs' value. Every number comes as a double
/// (JSON's own reading): integers past 2^53 cross as strings of digits, as the schemas ask.
JsonValue value_of(capnp::json::Value::Reader value) {
  switch (value.which()) {
    case capnp::json::Value::BOOLEAN:
      return JsonValue::of_bool(value.getBoolean());
    case capnp::json::Value::NUMBER:
      return JsonValue::of_float(value.getNumber());
    case capnp::json::Value::STRING: {
      const capnp::Text::Reader text = value.getString();
      return JsonValue::of_string(std::string(text.begin(), text.end()));
    }
    case capnp::json::Value::ARRAY: {
      JsonValue out = JsonValue::array();
      out.items.reserve(value.getArray().size());
      for (const capnp::json::Value::Reader item : value.getArray()) out.push(value_of(item));
      return out;
    }
    case capnp::json::Value::OBJECT: {
      JsonValue out = JsonValue::object();
      for (const capnp::json::Value::Field::Reader member : value.getObject()) {
        const capnp::Text::Reader key = member.getName();
        out.set(std::string(key.begin(), key.end()), value_of(member.getValue()));
      }
      return out;
    }
    case capnp::json::Value::CALL:
      throw CodecError("JSON payload: a function call, which is not JSON");
    default:
      return JsonValue::null();
  }
}

}  // namespace

JsonValue parse_json(std::string_view text) {
  capnp::JsonCodec codec;
  codec.setMaxNestingDepth(kMaxJsonDepth);
  capnp::MallocMessageBuilder arena;
  auto root = arena.initRoot<capnp::json::Value>();
  // Cap'n Proto reports malformed JSON as a kj::Exception: the viewer is told its text.
  KJ_IF_MAYBE (error, kj::runCatchingExceptions(
                          [&] { codec.decodeRaw(kj::arrayPtr(text.data(), text.size()), root); })) {
    throw CodecError("JSON payload: " + std::string(error->getDescription().cStr()));
  }
  return value_of(root.asReader());
}

}  // namespace horus::view::detail
