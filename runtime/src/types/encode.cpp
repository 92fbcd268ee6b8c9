// TypeDescription::encode: the structs of horus/type_description.hpp back to the MessagePack tree
// of docs/type-description.md, keys in the order generator/horus_gen/description.py writes them,
// so a description horus-gen carried comes back byte for byte.
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <cinttypes>
#include <cstdio>
#include <set>
#include <variant>

#include "horus/type_description.hpp"

namespace horus {

namespace {

using Packer = msgpack::packer<msgpack::sbuffer>;

void text(Packer& packer, std::string_view value) {
  packer.pack_str(static_cast<std::uint32_t>(value.size()));
  packer.pack_str_body(value.data(), static_cast<std::uint32_t>(value.size()));
}

/// A key of a map, then its value is packed by the caller.
void key(Packer& packer, std::string_view name) { text(packer, name); }

void optional_count(Packer& packer, const std::optional<std::size_t>& value) {
  if (value) {
    packer.pack_uint64(*value);
  } else {
    packer.pack_nil();
  }
}

/// MessagePack bytes kept as they came (a VALUE, the summary's PARTs); nil when there are none.
void raw(msgpack::sbuffer& buffer, Packer& packer, const std::string& bytes) {
  if (bytes.empty()) {
    packer.pack_nil();
  } else {
    buffer.write(bytes.data(), bytes.size());
  }
}

void fingerprint(Packer& packer, std::uint64_t value) {
  char hex[19];
  std::snprintf(hex, sizeof hex, "0x%016" PRIx64, value);
  text(packer, std::string_view(hex, 18));
}

void type(Packer& packer, const TypeRef& ref) {
  const auto element = [&] {
    key(packer, "element");
    type(packer, *ref.element);
  };
  switch (ref.kind) {
    case TypeRef::Kind::Primitive:
      packer.pack_map(2);
      key(packer, "kind");
      text(packer, "primitive");
      key(packer, "name");
      text(packer, primitive_name(ref.primitive));
      return;
    case TypeRef::Kind::FixedString:
      packer.pack_map(2);
      key(packer, "kind");
      text(packer, "string");
      key(packer, "capacity");
      packer.pack_uint64(ref.length);
      return;
    case TypeRef::Kind::String:
      packer.pack_map(1);
      key(packer, "kind");
      text(packer, "string");
      return;
    case TypeRef::Kind::Bytes:
      packer.pack_map(1);
      key(packer, "kind");
      text(packer, "bytes");
      return;
    case TypeRef::Kind::Array:
      packer.pack_map(3);
      key(packer, "kind");
      text(packer, "array");
      element();
      key(packer, "length");
      packer.pack_uint64(ref.length);
      return;
    case TypeRef::Kind::Vec:
    case TypeRef::Kind::Optional:
      packer.pack_map(2);
      key(packer, "kind");
      text(packer, ref.kind == TypeRef::Kind::Vec ? "vec" : "optional");
      element();
      return;
    case TypeRef::Kind::Message:
    case TypeRef::Kind::Enum:
      packer.pack_map(2);
      key(packer, "kind");
      text(packer, ref.kind == TypeRef::Kind::Message ? "message" : "enum");
      key(packer, "name");
      text(packer, ref.name);
      return;
  }
}

/// A parameter's declaration keys, those present, after the field's own.
void declaration_keys(msgpack::sbuffer& buffer, Packer& packer, const MessageField& field) {
  if (field.doc) {
    key(packer, "doc");
    text(packer, *field.doc);
  }
  if (field.range) {
    key(packer, "range");
    packer.pack_array(2);
    for (const std::optional<double>& bound : {field.range->min, field.range->max}) {
      if (bound) {
        // float64 always, as horus-gen writes it (msgpack-cxx would write 2.0 as an integer).
        std::uint64_t bits = 0;
        std::memcpy(&bits, &*bound, sizeof bits);
        char out[9] = {static_cast<char>(0xcb)};
        for (std::size_t i = 0; i < 8; ++i) out[1 + i] = static_cast<char>(bits >> (56 - 8 * i));
        buffer.write(out, sizeof out);
      } else {
        packer.pack_nil();
      }
    }
  }
  if (field.choices) {
    key(packer, "choices");
    packer.pack_array(static_cast<std::uint32_t>(field.choices->size()));
    for (const std::string& choice : *field.choices) raw(buffer, packer, choice);
  }
  if (field.read_only) {
    key(packer, "read_only");
    if (*field.read_only) {
      packer.pack_true();
    } else {
      packer.pack_false();
    }
  }
}

void message_entry(msgpack::sbuffer& buffer, Packer& packer, const MessageType& message) {
  packer.pack_map(13);
  key(packer, "kind");
  text(packer, "message");
  key(packer, "name");
  text(packer, message.name);
  key(packer, "package");
  text(packer, message.package);
  key(packer, "fingerprint");
  fingerprint(packer, message.fingerprint);
  key(packer, "tier");
  text(packer, message.is_pod ? "pod" : "serialized");
  key(packer, "size");
  optional_count(packer, message.is_pod ? std::optional(message.size) : std::nullopt);
  key(packer, "alignment");
  optional_count(packer, message.is_pod ? std::optional(message.alignment) : std::nullopt);
  key(packer, "fields");
  packer.pack_array(static_cast<std::uint32_t>(message.fields.size()));
  for (const MessageField& field : message.fields) {
    packer.pack_map(7 + (field.doc ? 1 : 0) + (field.range ? 1 : 0) + (field.choices ? 1 : 0) +
                    (field.read_only ? 1 : 0));
    key(packer, "name");
    text(packer, field.name);
    key(packer, "type");
    type(packer, field.type);
    key(packer, "offset");
    optional_count(packer, field.offset);
    key(packer, "size");
    optional_count(packer, field.size);
    key(packer, "default");
    raw(buffer, packer, field.default_value);
    key(packer, "unit");
    text(packer, field.unit);
    key(packer, "spelling");
    text(packer, field.spelling);
    declaration_keys(buffer, packer, field);
  }
  key(packer, "constants");
  packer.pack_array(static_cast<std::uint32_t>(message.constants.size()));
  for (const MessageConstant& constant : message.constants) {
    packer.pack_map(4);
    key(packer, "name");
    text(packer, constant.name);
    key(packer, "type");
    type(packer, constant.type);
    key(packer, "value");
    raw(buffer, packer, constant.value);
    key(packer, "spelling");
    text(packer, constant.spelling);
  }
  key(packer, "padding");
  packer.pack_array(static_cast<std::uint32_t>(message.padding.size()));
  for (const PaddingRange& range : message.padding) {
    packer.pack_map(2);
    key(packer, "offset");
    packer.pack_uint64(range.offset);
    key(packer, "size");
    packer.pack_uint64(range.size);
  }
  key(packer, "summary");
  if (message.summary.empty()) {
    packer.pack_array(0);
  } else {
    buffer.write(message.summary.data(), message.summary.size());
  }
  key(packer, "topic");
  if (message.topic) {
    text(packer, *message.topic);
  } else {
    packer.pack_nil();
  }
  key(packer, "schema");
  text(packer, message.schema);
}

void enum_entry(Packer& packer, const EnumType& enumeration) {
  packer.pack_map(7);
  key(packer, "kind");
  text(packer, "enum");
  key(packer, "name");
  text(packer, enumeration.name);
  key(packer, "package");
  text(packer, enumeration.package);
  key(packer, "fingerprint");
  fingerprint(packer, enumeration.fingerprint);
  key(packer, "underlying");
  text(packer, primitive_name(enumeration.underlying));
  key(packer, "values");
  packer.pack_array(static_cast<std::uint32_t>(enumeration.values.size()));
  for (const Enumerator& enumerator : enumeration.values) {
    packer.pack_map(2);
    key(packer, "name");
    text(packer, enumerator.name);
    key(packer, "value");
    // A u64 enumerator above INT64_MAX is kept as its bits (decode's Node::integer).
    if (enumeration.underlying == Primitive::U64) {
      packer.pack_uint64(static_cast<std::uint64_t>(enumerator.value));
    } else {
      packer.pack_int64(enumerator.value);
    }
  }
  key(packer, "schema");
  text(packer, enumeration.schema);
}

void service_entry(Packer& packer, const ServiceType& service) {
  packer.pack_map(8);
  key(packer, "kind");
  text(packer, "service");
  key(packer, "name");
  text(packer, service.name);
  key(packer, "package");
  text(packer, service.package);
  key(packer, "fingerprint");
  fingerprint(packer, service.fingerprint);
  key(packer, "request");
  text(packer, service.request);
  key(packer, "response");
  text(packer, service.response);
  key(packer, "request_topic");
  text(packer, service.request_topic);
  key(packer, "response_topic");
  text(packer, service.response_topic);
}

using Entry = std::variant<const MessageType*, const EnumType*, const ServiceType*>;

/// The order the types are written in: entries of the description's tables, each once.
class EntryOrder {
 public:
  explicit EntryOrder(const TypeDescription& description) : description_(description) {}

  /// `type_name` after every type it uses, as horus_gen.description.used_types orders them.
  void depth_first(std::string_view type_name) {
    if (const MessageType* message = description_.find_message(type_name)) {
      if (seen_.count(message) != 0) return;
      for (const MessageField& field : message->fields) {
        const TypeRef* inner = &field.type;
        while (inner->element) inner = inner->element.get();
        if (inner->kind == TypeRef::Kind::Message || inner->kind == TypeRef::Kind::Enum) {
          depth_first(inner->name);
        }
      }
      add(message);
    } else if (const EnumType* enumeration = description_.find_enum(type_name)) {
      add(enumeration);
    } else if (const ServiceType* service = description_.find_service(type_name)) {
      add(service);
    } else {
      throw TypeDescriptionError("type description: cannot encode it: " + std::string(type_name) +
                                 " is named but not in its types");
    }
  }

  template <class Type>
  void add(const Type* entry) {
    if (seen_.insert(entry).second) entries_.emplace_back(entry);
  }

  const std::vector<Entry>& entries() const noexcept { return entries_; }

 private:
  const TypeDescription& description_;
  std::set<const void*> seen_;
  std::vector<Entry> entries_;
};

}  // namespace

std::string TypeDescription::encode() const {
  EntryOrder order(*this);
  if (!root.empty()) order.depth_first(root);
  for (const MessageType& message : messages) order.add(&message);
  for (const EnumType& enumeration : enums) order.add(&enumeration);
  for (const ServiceType& service : services) order.add(&service);

  msgpack::sbuffer buffer;
  Packer packer(buffer);
  packer.pack_map(root.empty() ? 3 : 4);
  key(packer, "format");
  text(packer, kTypeDescriptionFormat);
  key(packer, "version");
  packer.pack_int64(kTypeDescriptionVersion);
  if (!root.empty()) {
    key(packer, "root");
    text(packer, root);
  }
  key(packer, "types");
  packer.pack_array(static_cast<std::uint32_t>(order.entries().size()));
  for (const Entry& entry : order.entries()) {
    if (const auto* message = std::get_if<const MessageType*>(&entry)) {
      message_entry(buffer, packer, **message);
    } else if (const auto* enumeration = std::get_if<const EnumType*>(&entry)) {
      enum_entry(packer, **enumeration);
    } else {
      service_entry(packer, *std::get<const ServiceType*>(entry));
    }
  }
  return std::string(buffer.data(), buffer.size());
}

}  // namespace horus
