// TypeDescription::decode: the MessagePack tree of docs/type-description.md to the structs of
// horus/type_description.hpp, checked whole before anyone walks a message with it.
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <cstring>
#include <limits>
#include <map>
#include <utility>

#include "horus/type_description.hpp"
#include "msgpack_input.hpp"

namespace horus {

namespace {

constexpr std::array<std::string_view, 11> kPrimitiveNames{"bool", "u8",  "u16", "u32", "u64", "i8",
                                                           "i16",  "i32", "i64", "f32", "f64"};

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw TypeDescriptionError("type description: " + path + ": " + what);
}

/// The value of `key` in the map `object`, or nullptr when it has none.
const msgpack::object* find_key(const msgpack::object& object, std::string_view key) {
  for (std::uint32_t i = 0; i < object.via.map.size; ++i) {
    const msgpack::object& k = object.via.map.ptr[i].key;
    if (k.type == msgpack::type::STR && std::string_view(k.via.str.ptr, k.via.str.size) == key) {
      return &object.via.map.ptr[i].val;
    }
  }
  return nullptr;
}

/// A map of the tree with the path that names it in errors ("types[2].fields[0]").
class Node {
 public:
  Node(const msgpack::object& object, std::string path) : object_(object), path_(std::move(path)) {
    if (object_.type != msgpack::type::MAP) fail(path_, "expected a map");
  }

  const std::string& path() const { return path_; }

  /// The value of `key`; nullptr when it is absent or nil (and `required` is false).
  const msgpack::object* get(std::string_view key, bool required) const {
    const msgpack::object* value = find_key(object_, key);
    if (value == nullptr || value->type == msgpack::type::NIL) {
      if (required) fail(path_, "has no \"" + std::string(key) + "\"");
      return nullptr;
    }
    return value;
  }

  std::string text(std::string_view key) const { return text_of(*get(key, true), at(key)); }

  std::optional<std::string> optional_text(std::string_view key) const {
    const msgpack::object* value = get(key, false);
    if (value == nullptr) return std::nullopt;
    return text_of(*value, at(key));
  }

  /// A count, size or offset: a non-negative integer at most `limit`.
  std::optional<std::size_t> optional_count(std::string_view key, std::size_t limit) const {
    const msgpack::object* value = get(key, false);
    if (value == nullptr) return std::nullopt;
    if (value->type != msgpack::type::POSITIVE_INTEGER) {
      fail(at(key), "expected a non-negative integer");
    }
    if (value->via.u64 > limit) {
      fail(at(key), std::to_string(value->via.u64) + " is more than the " + std::to_string(limit) +
                        " this reader accepts");
    }
    return static_cast<std::size_t>(value->via.u64);
  }

  std::size_t count(std::string_view key, std::size_t limit) const {
    get(key, true);
    return *optional_count(key, limit);
  }

  std::int64_t integer(std::string_view key) const {
    const msgpack::object& value = *get(key, true);
    if (value.type == msgpack::type::NEGATIVE_INTEGER) return value.via.i64;
    // An enumerator of a u64 enum above INT64_MAX keeps its bits (read back as the same u64).
    if (value.type == msgpack::type::POSITIVE_INTEGER)
      return static_cast<std::int64_t>(value.via.u64);
    fail(at(key), "expected an integer");
  }

  /// The elements of the array `key` (an absent or nil array is empty).
  std::span<const msgpack::object> list(std::string_view key) const {
    const msgpack::object* value = get(key, false);
    if (value == nullptr) return {};
    if (value->type != msgpack::type::ARRAY) fail(at(key), "expected an array");
    return {value->via.array.ptr, value->via.array.size};
  }

  std::string at(std::string_view key) const { return path_ + "." + std::string(key); }

 private:
  static std::string text_of(const msgpack::object& value, const std::string& path) {
    if (value.type != msgpack::type::STR) fail(path, "expected a string");
    return std::string(value.via.str.ptr, value.via.str.size);
  }

  const msgpack::object& object_;
  std::string path_;
};

std::string indexed(const std::string& path, std::size_t index) {
  return path + "[" + std::to_string(index) + "]";
}

/// `value` packed again as it came: msgpack-cxx packs a whole-numbered double as an integer, so
/// floats are written here, as float64 (encode() gives back horus-gen's bytes).
void repack(const msgpack::object& value, msgpack::sbuffer& buffer) {
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  switch (value.type) {
    case msgpack::type::FLOAT32:
    case msgpack::type::FLOAT64: {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &value.via.f64, sizeof bits);
      std::array<char, 9> out{static_cast<char>(0xcb)};
      for (std::size_t i = 0; i < 8; ++i) out[1 + i] = static_cast<char>(bits >> (56 - 8 * i));
      buffer.write(out.data(), out.size());
      return;
    }
    case msgpack::type::ARRAY:
      packer.pack_array(value.via.array.size);
      for (std::uint32_t i = 0; i < value.via.array.size; ++i) {
        repack(value.via.array.ptr[i], buffer);
      }
      return;
    case msgpack::type::MAP:
      packer.pack_map(value.via.map.size);
      for (std::uint32_t i = 0; i < value.via.map.size; ++i) {
        repack(value.via.map.ptr[i].key, buffer);
        repack(value.via.map.ptr[i].val, buffer);
      }
      return;
    default:
      packer.pack(value);
  }
}

/// A VALUE kept as its own MessagePack bytes (what default_message() and consumers read).
std::string packed(const msgpack::object* value) {
  if (value == nullptr) return {};
  msgpack::sbuffer buffer;
  repack(*value, buffer);
  return std::string(buffer.data(), buffer.size());
}

Primitive primitive_named(std::string_view name, const std::string& path) {
  const std::optional<Primitive> primitive = horus::primitive_named(name);
  if (!primitive) fail(path, "\"" + std::string(name) + "\" is not a primitive");
  return *primitive;
}

std::uint64_t fingerprint_of(const Node& entry) {
  const msgpack::object& value = *entry.get("fingerprint", true);
  if (value.type == msgpack::type::POSITIVE_INTEGER) return value.via.u64;
  const std::string text = entry.text("fingerprint");
  std::uint64_t fingerprint = 0;
  const char* end = text.data() + text.size();
  const std::from_chars_result parsed =
      std::from_chars(text.data() + std::min<std::size_t>(2, text.size()), end, fingerprint, 16);
  if (!text.starts_with("0x") || text.size() == 2 || parsed.ec != std::errc() ||
      parsed.ptr != end) {
    fail(entry.at("fingerprint"), "\"" + text + "\" is not a hexadecimal 0x... number");
  }
  return fingerprint;
}

/// Where each message and enum of "types" will be, by name: what TYPE names resolve to.
struct Names {
  std::map<std::string, std::size_t, std::less<>> messages;
  std::map<std::string, std::size_t, std::less<>> enums;
};

TypeRef read_type(const msgpack::object& object, const std::string& path, const Names& names,
                  std::size_t depth) {
  if (depth > kMaxTypeNesting) {
    fail(path, "types nest deeper than " + std::to_string(kMaxTypeNesting) + " levels");
  }
  const Node node(object, path);
  const std::string kind = node.text("kind");
  TypeRef type;
  const auto element = [&] {
    type.element = std::make_shared<const TypeRef>(
        read_type(*node.get("element", true), node.at("element"), names, depth + 1));
  };
  const auto named = [&](const auto& table, TypeRef::Kind named_kind) {
    type.kind = named_kind;
    type.name = node.text("name");
    const auto it = table.find(type.name);
    if (it == table.end()) {
      const bool other_kind =
          names.messages.count(type.name) != 0 || names.enums.count(type.name) != 0;
      fail(path, "names " + kind + " " + type.name +
                     (other_kind ? ", which is not a " + kind : ", which is not in types"));
    }
    type.index = it->second;
  };
  if (kind == "primitive") {
    type.kind = TypeRef::Kind::Primitive;
    type.primitive = primitive_named(node.text("name"), node.at("name"));
  } else if (kind == "string") {
    const std::optional<std::size_t> capacity = node.optional_count("capacity", kMaxMessageBytes);
    type.kind = capacity ? TypeRef::Kind::FixedString : TypeRef::Kind::String;
    if (capacity) {
      if (*capacity == 0) fail(node.at("capacity"), "string<0> holds nothing");
      type.length = *capacity;
    }
  } else if (kind == "bytes") {
    type.kind = TypeRef::Kind::Bytes;
  } else if (kind == "array") {
    type.kind = TypeRef::Kind::Array;
    type.length = node.count("length", kMaxMessageBytes);
    element();
  } else if (kind == "vec") {
    type.kind = TypeRef::Kind::Vec;
    element();
  } else if (kind == "optional") {
    type.kind = TypeRef::Kind::Optional;
    element();
  } else if (kind == "message") {
    named(names.messages, TypeRef::Kind::Message);
  } else if (kind == "enum") {
    named(names.enums, TypeRef::Kind::Enum);
  } else {
    fail(node.at("kind"), "\"" + kind + "\" is not a kind of type");
  }
  return type;
}

/// A parameter's declaration keys (doc, range, choices, read_only), those present.
void read_declaration_keys(const Node& node, MessageField& field) {
  field.doc = node.optional_text("doc");
  if (const msgpack::object* range = node.get("range", false)) {
    if (range->type != msgpack::type::ARRAY || range->via.array.size != 2) {
      fail(node.at("range"), "expected [min or null, max or null]");
    }
    std::array<std::optional<double>, 2> bounds;
    for (std::size_t i = 0; i < 2; ++i) {
      const msgpack::object& bound = range->via.array.ptr[i];
      switch (bound.type) {
        case msgpack::type::NIL:
          break;
        case msgpack::type::FLOAT32:
        case msgpack::type::FLOAT64:
          bounds[i] = bound.via.f64;
          break;
        case msgpack::type::POSITIVE_INTEGER:
          bounds[i] = static_cast<double>(bound.via.u64);
          break;
        case msgpack::type::NEGATIVE_INTEGER:
          bounds[i] = static_cast<double>(bound.via.i64);
          break;
        default:
          fail(indexed(node.at("range"), i), "expected a number or null");
      }
    }
    field.range = MessageField::Range{bounds[0], bounds[1]};
  }
  if (node.get("choices", false) != nullptr) {
    std::vector<std::string> choices;
    for (const msgpack::object& choice : node.list("choices")) choices.push_back(packed(&choice));
    field.choices = std::move(choices);
  }
  if (const msgpack::object* read_only = node.get("read_only", false)) {
    if (read_only->type != msgpack::type::BOOLEAN) fail(node.at("read_only"), "expected a bool");
    field.read_only = read_only->via.boolean;
  }
}

MessageType read_message(const Node& entry, const Names& names) {
  MessageType message;
  message.name = entry.text("name");
  message.package = entry.text("package");
  message.fingerprint = fingerprint_of(entry);
  const std::string tier = entry.text("tier");
  if (tier != "pod" && tier != "serialized") {
    fail(entry.at("tier"), "\"" + tier + "\" is neither pod nor serialized");
  }
  message.is_pod = tier == "pod";
  if (message.is_pod) {
    message.size = entry.count("size", kMaxMessageBytes);
    message.alignment = entry.count("alignment", kMaxMessageBytes);
    if (message.size == 0) fail(entry.at("size"), "a POD message takes one byte at least");
  }
  const std::span<const msgpack::object> fields = entry.list("fields");
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const Node node(fields[i], indexed(entry.at("fields"), i));
    MessageField field;
    field.name = node.text("name");
    field.type = read_type(*node.get("type", true), node.at("type"), names, 0);
    field.offset = node.optional_count("offset", kMaxMessageBytes);
    field.size = node.optional_count("size", kMaxMessageBytes);
    field.default_value = packed(node.get("default", false));
    field.unit = node.optional_text("unit").value_or("");
    field.spelling = node.optional_text("spelling").value_or("");
    read_declaration_keys(node, field);
    message.fields.push_back(std::move(field));
  }
  const std::span<const msgpack::object> constants = entry.list("constants");
  for (std::size_t i = 0; i < constants.size(); ++i) {
    const Node node(constants[i], indexed(entry.at("constants"), i));
    message.constants.push_back(MessageConstant{
        node.text("name"), read_type(*node.get("type", true), node.at("type"), names, 0),
        packed(node.get("value", true)), node.optional_text("spelling").value_or("")});
  }
  const std::span<const msgpack::object> padding = entry.list("padding");
  for (std::size_t i = 0; i < padding.size(); ++i) {
    const Node node(padding[i], indexed(entry.at("padding"), i));
    const PaddingRange range{node.count("offset", kMaxMessageBytes),
                             node.count("size", kMaxMessageBytes)};
    if (range.offset + range.size > message.size) {
      fail(node.path(), "padding ends at " + std::to_string(range.offset + range.size) +
                            ", past the message's " + std::to_string(message.size) + " bytes");
    }
    message.padding.push_back(range);
  }
  if (const msgpack::object* summary = entry.get("summary", false)) {
    if (summary->type != msgpack::type::ARRAY) fail(entry.at("summary"), "expected an array");
    message.summary = packed(summary);
  }
  message.topic = entry.optional_text("topic");
  message.schema = entry.optional_text("schema").value_or("");
  return message;
}

EnumType read_enum(const Node& entry) {
  EnumType enumeration;
  enumeration.name = entry.text("name");
  enumeration.package = entry.text("package");
  enumeration.fingerprint = fingerprint_of(entry);
  enumeration.underlying = primitive_named(entry.text("underlying"), entry.at("underlying"));
  if (enumeration.underlying == Primitive::Bool || enumeration.underlying == Primitive::F32 ||
      enumeration.underlying == Primitive::F64) {
    fail(entry.at("underlying"), "an enum's underlying type is an integer type");
  }
  const std::span<const msgpack::object> values = entry.list("values");
  for (std::size_t i = 0; i < values.size(); ++i) {
    const Node node(values[i], indexed(entry.at("values"), i));
    enumeration.values.push_back(Enumerator{node.text("name"), node.integer("value")});
  }
  enumeration.schema = entry.optional_text("schema").value_or("");
  return enumeration;
}

ServiceType read_service(const Node& entry) {
  return ServiceType{entry.text("name"),          entry.text("package"),
                     fingerprint_of(entry),       entry.text("request"),
                     entry.text("response"),      entry.text("request_topic"),
                     entry.text("response_topic")};
}

/// Bytes of `type` inside a POD message; nullopt for the serialized kinds.
std::optional<std::size_t> pod_size(const TypeDescription& description, const TypeRef& type) {
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      return primitive_size(type.primitive);
    case TypeRef::Kind::FixedString:
      return type.length;
    case TypeRef::Kind::Array: {
      const std::optional<std::size_t> element = pod_size(description, *type.element);
      if (!element || (*element != 0 && type.length > kMaxMessageBytes / *element)) {
        return std::nullopt;
      }
      return *element * type.length;
    }
    case TypeRef::Kind::Message: {
      const MessageType& message = description.message(type);
      return message.is_pod ? std::optional(message.size) : std::nullopt;
    }
    case TypeRef::Kind::Enum:
      return primitive_size(description.enumeration(type).underlying);
    default:
      return std::nullopt;
  }
}

/// Every POD field of `message` lies inside it, with the size its type has, and no two overlap
/// (so walking a message reads each byte once, however its types nest).
void check_pod_layout(const TypeDescription& description, const MessageType& message,
                      const std::string& path) {
  std::vector<std::pair<std::size_t, std::size_t>> taken;  // [offset, end) of each field
  for (std::size_t i = 0; i < message.fields.size(); ++i) {
    const MessageField& field = message.fields[i];
    const std::string field_path = indexed(path + ".fields", i);
    const std::optional<std::size_t> size = pod_size(description, field.type);
    if (!size) {
      fail(field_path, "a POD message's field " + field.name +
                           " has a type without a fixed layout (or too large)");
    }
    if (!field.offset) fail(field_path, "a POD message's field " + field.name + " has no offset");
    if (field.size && *field.size != *size) {
      fail(field_path, "size " + std::to_string(*field.size) + " of " + field.name +
                           " is not its type's " + std::to_string(*size));
    }
    if (*field.offset + *size > message.size) {
      fail(field_path, field.name + " at offset " + std::to_string(*field.offset) + " with " +
                           std::to_string(*size) + " bytes ends past the message's " +
                           std::to_string(message.size) + " bytes");
    }
    taken.emplace_back(*field.offset, *field.offset + *size);
  }
  std::sort(taken.begin(), taken.end());
  for (std::size_t i = 1; i < taken.size(); ++i) {
    if (taken[i].first < taken[i - 1].second) {
      fail(path, "two fields of " + message.name + " overlap at offset " +
                     std::to_string(taken[i].first));
    }
  }
}

/// The messages a TYPE uses, whatever wraps them (arrays, Vec, Option).
const TypeRef& innermost(const TypeRef& type) {
  const TypeRef* inner = &type;
  while (inner->element) inner = inner->element.get();
  return *inner;
}

/// How deep messages nest below the message at `index`, refusing a message that contains itself
/// (no encoding of it has an end) and nesting deeper than kMaxTypeNesting (what walking a message
/// recurses through). `height`: -1 on the path being followed, else the height once known.
std::size_t message_height(const TypeDescription& description, std::size_t index,
                           std::vector<std::optional<std::ptrdiff_t>>& height, std::size_t depth) {
  const MessageType& message = description.messages[index];
  if (height[index] == -1) fail("types", "message " + message.name + " contains itself");
  if (height[index]) return static_cast<std::size_t>(*height[index]);
  if (depth > kMaxTypeNesting) {
    fail("types", "messages nest deeper than " + std::to_string(kMaxTypeNesting) + " levels at " +
                      message.name);
  }
  height[index] = -1;
  std::size_t below = 0;
  for (const MessageField& field : message.fields) {
    const TypeRef& inner = innermost(field.type);
    if (inner.kind == TypeRef::Kind::Message) {
      below = std::max(below, 1 + message_height(description, inner.index, height, depth + 1));
    }
  }
  if (depth + below > kMaxTypeNesting) {
    fail("types", "messages nest deeper than " + std::to_string(kMaxTypeNesting) + " levels at " +
                      message.name);
  }
  height[index] = static_cast<std::ptrdiff_t>(below);
  return below;
}

}  // namespace

std::string_view primitive_name(Primitive primitive) noexcept {
  return kPrimitiveNames[static_cast<std::size_t>(primitive)];
}

std::optional<Primitive> primitive_named(std::string_view name) noexcept {
  const auto it = std::find(kPrimitiveNames.begin(), kPrimitiveNames.end(), name);
  if (it == kPrimitiveNames.end()) return std::nullopt;
  return static_cast<Primitive>(it - kPrimitiveNames.begin());
}

std::size_t primitive_size(Primitive primitive) noexcept {
  switch (primitive) {
    case Primitive::Bool:
    case Primitive::U8:
    case Primitive::I8:
      return 1;
    case Primitive::U16:
    case Primitive::I16:
      return 2;
    case Primitive::U32:
    case Primitive::I32:
    case Primitive::F32:
      return 4;
    default:
      return 8;
  }
}

bool TypeRef::is_byte_block() const noexcept {
  return kind == Kind::Bytes ||
         ((kind == Kind::Vec || kind == Kind::Array) && element->kind == Kind::Primitive &&
          element->primitive == Primitive::U8);
}

const MessageField* MessageType::find_field(std::string_view field_name) const noexcept {
  for (const MessageField& field : fields) {
    if (field.name == field_name) return &field;
  }
  return nullptr;
}

const Enumerator* EnumType::find_value(std::int64_t value) const noexcept {
  for (const Enumerator& enumerator : values) {
    if (enumerator.value == value) return &enumerator;
  }
  return nullptr;
}

TypeDescription TypeDescription::decode(std::string_view bytes) {
  return decode(std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
}

TypeDescription TypeDescription::decode(std::span<const std::uint8_t> bytes) {
  if (bytes.size() > kMaxDescriptionBytes) {
    throw TypeDescriptionError("type description: " + std::to_string(bytes.size()) +
                               " bytes, more than the " + std::to_string(kMaxDescriptionBytes) +
                               " this reader accepts");
  }
  const msgpack::object_handle handle = types::unpack_whole<TypeDescriptionError>(
      reinterpret_cast<const char*>(bytes.data()), bytes.size(), "type description");
  const Node top(handle.get(), "description");
  if (const std::string format = top.text("format"); format != kTypeDescriptionFormat) {
    fail("format", "\"" + format + "\" is not " + std::string(kTypeDescriptionFormat));
  }
  TypeDescription description;
  description.version = top.integer("version");
  if (description.version < 1) {
    fail("version", std::to_string(description.version) + " is not a version");
  }
  if (description.version > kTypeDescriptionVersion) {
    throw TypeDescriptionError("type description version " + std::to_string(description.version) +
                               " is newer than this reader's " +
                               std::to_string(kTypeDescriptionVersion) +
                               ": update horus to read it");
  }
  description.root = top.optional_text("root").value_or("");

  // Names first, so that a field may name a type listed after it (the describe form's order).
  const std::span<const msgpack::object> entries = top.list("types");
  Names names;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const Node entry(entries[i], indexed("types", i));
    const std::string kind = entry.text("kind");
    auto* table = kind == "message" ? &names.messages : kind == "enum" ? &names.enums : nullptr;
    if (table == nullptr) continue;
    const std::string name = entry.text("name");
    if (names.messages.count(name) != 0 || names.enums.count(name) != 0) {
      fail(entry.path(), name + " is listed twice");
    }
    table->emplace(name, table->size());
  }
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const Node entry(entries[i], indexed("types", i));
    const std::string kind = entry.text("kind");
    if (kind == "message") {
      description.messages.push_back(read_message(entry, names));
    } else if (kind == "enum") {
      description.enums.push_back(read_enum(entry));
    } else if (kind == "service") {
      description.services.push_back(read_service(entry));
    }
    // Other kinds (the describe form's nodes) are no types: nothing names them in a TYPE.
  }

  std::vector<std::optional<std::ptrdiff_t>> height(description.messages.size());
  for (std::size_t i = 0; i < description.messages.size(); ++i) {
    message_height(description, i, height, 0);
  }
  std::size_t message_index = 0;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const Node entry(entries[i], indexed("types", i));
    if (entry.text("kind") != "message") continue;
    const MessageType& message = description.messages[message_index++];
    if (message.is_pod) check_pod_layout(description, message, entry.path());
  }
  if (!description.root.empty() && description.find_message(description.root) == nullptr &&
      description.find_enum(description.root) == nullptr &&
      description.find_service(description.root) == nullptr) {
    fail("root", description.root + " is not in types");
  }
  return description;
}

const MessageType* TypeDescription::find_message(std::string_view type_name) const noexcept {
  for (const MessageType& message : messages) {
    if (message.name == type_name) return &message;
  }
  return nullptr;
}

const EnumType* TypeDescription::find_enum(std::string_view type_name) const noexcept {
  for (const EnumType& enumeration : enums) {
    if (enumeration.name == type_name) return &enumeration;
  }
  return nullptr;
}

const ServiceType* TypeDescription::find_service(std::string_view type_name) const noexcept {
  for (const ServiceType& service : services) {
    if (service.name == type_name) return &service;
  }
  return nullptr;
}

const MessageType& TypeDescription::message(std::string_view type_name) const {
  if (const MessageType* found = find_message(type_name)) return *found;
  throw TypeDescriptionError("type description: no message " + std::string(type_name) +
                             " in its types");
}

const MessageType& TypeDescription::root_message() const {
  if (root.empty()) {
    throw TypeDescriptionError("type description: no root (the describe form): name the message");
  }
  return message(root);
}

}  // namespace horus
