// zero_message / default_message: a message written from its description alone, byte for byte
// what the generated C++ writes for the same values (horus::encode: the struct bytes of a POD
// message, the msgpack-cxx adaptors' MessagePack of a serialized one: each integer through the
// packer of its width, f32 as float 32, byte blocks as bin).
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <algorithm>
#include <cstring>
#include <functional>
#include <optional>

#include "horus/type_description.hpp"
#include "msgpack_input.hpp"

namespace horus {

namespace {

[[noreturn]] void bad_default(const std::string& what) {
  throw TypeDescriptionError("type description: default " + what);
}

/// The MessagePack tree of a field's stored default.
msgpack::object_handle default_tree(const MessageField& field) {
  return types::unpack_whole<TypeDescriptionError>(field.default_value.data(),
                                                   field.default_value.size(), field.name);
}

double number_of(const msgpack::object& value, std::string_view field) {
  switch (value.type) {
    case msgpack::type::FLOAT32:
    case msgpack::type::FLOAT64:
      return value.via.f64;
    case msgpack::type::POSITIVE_INTEGER:
      return static_cast<double>(value.via.u64);
    case msgpack::type::NEGATIVE_INTEGER:
      return static_cast<double>(value.via.i64);
    default:
      bad_default("of " + std::string(field) + " is not a number");
  }
}

/// An integer default as its 64 bits (what a cast to the field's width keeps).
std::uint64_t integer_of(const msgpack::object& value, std::string_view field) {
  if (value.type == msgpack::type::POSITIVE_INTEGER) return value.via.u64;
  if (value.type == msgpack::type::NEGATIVE_INTEGER)
    return static_cast<std::uint64_t>(value.via.i64);
  bad_default("of " + std::string(field) + " is not an integer");
}

/// An enum default: the enumerator's name, its value, or a map holding either.
std::int64_t enumerator_of(const EnumType& enumeration, const msgpack::object& value,
                           std::string_view field) {
  if (value.type == msgpack::type::MAP) {
    for (std::uint32_t i = 0; i < value.via.map.size; ++i) {
      const msgpack::object& key = value.via.map.ptr[i].key;
      const std::string_view name =
          key.type == msgpack::type::STR ? std::string_view(key.via.str.ptr, key.via.str.size) : "";
      if (name == "value") return enumerator_of(enumeration, value.via.map.ptr[i].val, field);
    }
    bad_default("of " + std::string(field) + " is a map without a \"value\"");
  }
  if (value.type == msgpack::type::STR) {
    std::string_view name(value.via.str.ptr, value.via.str.size);
    name = name.substr(name.rfind(':') == std::string_view::npos ? 0 : name.rfind(':') + 1);
    for (const Enumerator& enumerator : enumeration.values) {
      if (enumerator.name == name) return enumerator.value;
    }
    bad_default("of " + std::string(field) + ": " + std::string(name) +
                " is not an enumerator of " + enumeration.name);
  }
  return static_cast<std::int64_t>(integer_of(value, field));
}

std::string_view text_of(const msgpack::object& value, std::string_view field) {
  if (value.type != msgpack::type::STR)
    bad_default("of " + std::string(field) + " is not a string");
  return {value.via.str.ptr, value.via.str.size};
}

std::span<const msgpack::object> elements_of(const msgpack::object& value, std::size_t length,
                                             std::string_view field) {
  if (value.type != msgpack::type::ARRAY || value.via.array.size != length) {
    bad_default("of " + std::string(field) + " is not a list of " + std::to_string(length));
  }
  return {value.via.array.ptr, value.via.array.size};
}

/// The MessagePack of a serialized message.
class SerializedWriter {
 public:
  SerializedWriter(const TypeDescription& description, bool with_defaults)
      : description_(description), with_defaults_(with_defaults), packer_(buffer_) {}

  std::vector<std::uint8_t> message(const MessageType& type) {
    std::vector<std::optional<std::size_t>> smallest(description_.messages.size());
    if (smallest_message(type, smallest) > kMaxMessageBytes) {
      throw TypeDescriptionError("type description: a " + type.name + " takes more than " +
                                 std::to_string(kMaxMessageBytes) + " bytes");
    }
    write_message(type);
    const auto* data = reinterpret_cast<const std::uint8_t*>(buffer_.data());
    return std::vector<std::uint8_t>(data, data + buffer_.size());
  }

 private:
  /// The fewest bytes a `type` value takes, at most kMaxMessageBytes + 1: checked before writing
  /// anything, so a description whose arrays multiply up to terabytes is refused at once.
  /// `smallest`: each message's, once computed (types may share a message many times over).
  std::size_t smallest_value(const TypeRef& type,
                             std::vector<std::optional<std::size_t>>& smallest) const {
    constexpr std::size_t kTooLarge = kMaxMessageBytes + 1;
    switch (type.kind) {
      case TypeRef::Kind::Array: {
        const std::size_t element =
            type.is_byte_block() ? 1 : smallest_value(*type.element, smallest);
        if (element != 0 && type.length > kTooLarge / element) return kTooLarge;
        return std::min(kTooLarge, 5 + type.length * element);
      }
      case TypeRef::Kind::Message:
        return smallest_message(description_.message(type), smallest);
      default:
        return 1;
    }
  }

  std::size_t smallest_message(const MessageType& type,
                               std::vector<std::optional<std::size_t>>& smallest) const {
    std::optional<std::size_t>& known =
        smallest[static_cast<std::size_t>(&type - description_.messages.data())];
    if (!known) {
      std::size_t total = 1;
      for (const MessageField& field : type.fields) {
        total = std::min(kMaxMessageBytes + 1, total + smallest_value(field.type, smallest));
      }
      known = total;
    }
    return *known;
  }

  /// Refuses a message of more than kMaxMessageBytes before writing `count` more values (each
  /// takes a byte at least): a hostile description's array lengths cannot exhaust memory.
  void reserve(std::size_t count) {
    if (count > kMaxMessageBytes - std::min(buffer_.size(), kMaxMessageBytes)) {
      throw TypeDescriptionError("type description: a message of more than " +
                                 std::to_string(kMaxMessageBytes) + " bytes");
    }
  }

  void write_message(const MessageType& type) {
    reserve(type.fields.size());
    packer_.pack_array(static_cast<std::uint32_t>(type.fields.size()));
    for (const MessageField& field : type.fields) {
      if (with_defaults_ && !field.default_value.empty()) {
        const msgpack::object_handle tree = default_tree(field);
        given(field.type, tree.get(), field.name);
      } else {
        zero(field.type);
      }
    }
  }

  void integer(Primitive primitive, std::uint64_t bits) {
    switch (primitive) {
      case Primitive::U8:
        packer_.pack_uint8(static_cast<std::uint8_t>(bits));
        return;
      case Primitive::U16:
        packer_.pack_uint16(static_cast<std::uint16_t>(bits));
        return;
      case Primitive::U32:
        packer_.pack_uint32(static_cast<std::uint32_t>(bits));
        return;
      case Primitive::U64:
        packer_.pack_uint64(bits);
        return;
      case Primitive::I8:
        packer_.pack_int8(static_cast<std::int8_t>(bits));
        return;
      case Primitive::I16:
        packer_.pack_int16(static_cast<std::int16_t>(bits));
        return;
      case Primitive::I32:
        packer_.pack_int32(static_cast<std::int32_t>(bits));
        return;
      default:
        packer_.pack_int64(static_cast<std::int64_t>(bits));
    }
  }

  void number(Primitive primitive, double value) {
    if (primitive == Primitive::F32) {
      packer_.pack_float(static_cast<float>(value));
    } else {
      packer_.pack_double(value);
    }
  }

  void text(std::string_view value) {
    packer_.pack_str(static_cast<std::uint32_t>(value.size()));
    // An empty str of a parsed default has no data pointer, which memcpy must not be given.
    if (!value.empty())
      packer_.pack_str_body(value.data(), static_cast<std::uint32_t>(value.size()));
  }

  void zero(const TypeRef& type) {
    reserve(1);
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        if (type.primitive == Primitive::Bool) {
          packer_.pack_false();
        } else if (type.primitive == Primitive::F32 || type.primitive == Primitive::F64) {
          number(type.primitive, 0.0);
        } else {
          integer(type.primitive, 0);
        }
        return;
      case TypeRef::Kind::FixedString:
      case TypeRef::Kind::String:
        text({});
        return;
      case TypeRef::Kind::Bytes:
      case TypeRef::Kind::Vec:
        if (type.is_byte_block()) {
          packer_.pack_bin(0);
        } else {
          packer_.pack_array(0);
        }
        return;
      case TypeRef::Kind::Array:
        reserve(type.length);
        if (type.is_byte_block()) {
          const std::string zeros(type.length, '\0');
          packer_.pack_bin(static_cast<std::uint32_t>(type.length));
          packer_.pack_bin_body(zeros.data(), static_cast<std::uint32_t>(type.length));
          return;
        }
        packer_.pack_array(static_cast<std::uint32_t>(type.length));
        for (std::size_t i = 0; i < type.length; ++i) zero(*type.element);
        return;
      case TypeRef::Kind::Optional:
        packer_.pack_nil();
        return;
      case TypeRef::Kind::Message:
        write_message(description_.message(type));
        return;
      case TypeRef::Kind::Enum:
        integer(description_.enumeration(type).underlying, 0);
        return;
    }
  }

  /// `value`, a default of the description, as a `type`.
  void given(const TypeRef& type, const msgpack::object& value, std::string_view field) {
    reserve(1);
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        if (type.primitive == Primitive::Bool) {
          if (value.type != msgpack::type::BOOLEAN)
            bad_default("of " + std::string(field) + " is not a bool");
          value.via.boolean ? packer_.pack_true() : packer_.pack_false();
        } else if (type.primitive == Primitive::F32 || type.primitive == Primitive::F64) {
          number(type.primitive, number_of(value, field));
        } else {
          integer(type.primitive, integer_of(value, field));
        }
        return;
      case TypeRef::Kind::FixedString:
      case TypeRef::Kind::String:
        text(text_of(value, field));
        return;
      case TypeRef::Kind::Array: {
        const std::span<const msgpack::object> elements = elements_of(value, type.length, field);
        reserve(type.length);
        if (type.is_byte_block()) {
          std::string block;
          for (const msgpack::object& element : elements) {
            block.push_back(static_cast<char>(integer_of(element, field)));
          }
          packer_.pack_bin(static_cast<std::uint32_t>(block.size()));
          packer_.pack_bin_body(block.data(), static_cast<std::uint32_t>(block.size()));
          return;
        }
        packer_.pack_array(static_cast<std::uint32_t>(type.length));
        for (const msgpack::object& element : elements) given(*type.element, element, field);
        return;
      }
      case TypeRef::Kind::Enum: {
        const EnumType& enumeration = description_.enumeration(type);
        integer(enumeration.underlying,
                static_cast<std::uint64_t>(enumerator_of(enumeration, value, field)));
        return;
      }
      default:
        bad_default("of " + std::string(field) + ": its type takes no default");
    }
  }

  const TypeDescription& description_;
  bool with_defaults_;
  msgpack::sbuffer buffer_;
  msgpack::packer<msgpack::sbuffer> packer_;
};

/// The schema defaults written into zeroed POD bytes (decode() proved every field fits).
class PodDefaults {
 public:
  PodDefaults(const TypeDescription& description, std::vector<std::uint8_t>& bytes)
      : description_(description), bytes_(bytes) {}

  void message(const MessageType& type, std::size_t at) {
    for (const MessageField& field : type.fields) {
      if (!field.default_value.empty()) {
        const msgpack::object_handle tree = default_tree(field);
        given(field.type, tree.get(), at + *field.offset, field.name);
      } else {
        nested(field.type, at + *field.offset);
      }
    }
  }

 private:
  std::size_t size_of(const TypeRef& type) const {
    switch (type.kind) {
      case TypeRef::Kind::Array:
        return type.length * size_of(*type.element);
      case TypeRef::Kind::FixedString:
        return type.length;
      case TypeRef::Kind::Message:
        return description_.message(type).size;
      case TypeRef::Kind::Enum:
        return primitive_size(description_.enumeration(type).underlying);
      default:
        return primitive_size(type.primitive);
    }
  }

  template <class T>
  void put(std::size_t at, T value) {
    if (at > bytes_.size() || sizeof(T) > bytes_.size() - at) {
      bad_default("lies outside its message's bytes");
    }
    std::memcpy(bytes_.data() + at, &value, sizeof(T));
  }

  /// A field without a default: the defaults of the messages it holds.
  void nested(const TypeRef& type, std::size_t at) {
    if (type.kind == TypeRef::Kind::Message) {
      message(description_.message(type), at);
    } else if (type.kind == TypeRef::Kind::Array && innermost_is_message(type)) {
      const std::size_t stride = size_of(*type.element);
      for (std::size_t i = 0; i < type.length; ++i) nested(*type.element, at + i * stride);
    }
  }

  static bool innermost_is_message(const TypeRef& type) {
    const TypeRef* inner = &type;
    while (inner->element) inner = inner->element.get();
    return inner->kind == TypeRef::Kind::Message;
  }

  void integer(Primitive primitive, std::uint64_t bits, std::size_t at) {
    switch (primitive_size(primitive)) {
      case 1:
        put(at, static_cast<std::uint8_t>(bits));
        return;
      case 2:
        put(at, static_cast<std::uint16_t>(bits));
        return;
      case 4:
        put(at, static_cast<std::uint32_t>(bits));
        return;
      default:
        put(at, bits);
    }
  }

  void given(const TypeRef& type, const msgpack::object& value, std::size_t at,
             std::string_view field) {
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        if (type.primitive == Primitive::Bool) {
          if (value.type != msgpack::type::BOOLEAN)
            bad_default("of " + std::string(field) + " is not a bool");
          put(at, static_cast<std::uint8_t>(value.via.boolean ? 1 : 0));
        } else if (type.primitive == Primitive::F32) {
          put(at, static_cast<float>(number_of(value, field)));
        } else if (type.primitive == Primitive::F64) {
          put(at, number_of(value, field));
        } else {
          integer(type.primitive, integer_of(value, field), at);
        }
        return;
      case TypeRef::Kind::FixedString: {
        const std::string_view text = text_of(value, field);
        if (text.size() > type.length || at + type.length > bytes_.size()) {
          bad_default("of " + std::string(field) + " does not fit string<" +
                      std::to_string(type.length) + ">");
        }
        std::copy(text.begin(), text.end(), bytes_.begin() + static_cast<std::ptrdiff_t>(at));
        return;
      }
      case TypeRef::Kind::Array: {
        const std::size_t stride = size_of(*type.element);
        std::size_t element_at = at;
        for (const msgpack::object& element : elements_of(value, type.length, field)) {
          given(*type.element, element, element_at, field);
          element_at += stride;
        }
        return;
      }
      case TypeRef::Kind::Enum: {
        const EnumType& enumeration = description_.enumeration(type);
        integer(enumeration.underlying,
                static_cast<std::uint64_t>(enumerator_of(enumeration, value, field)), at);
        return;
      }
      default:
        bad_default("of " + std::string(field) + ": its type takes no default");
    }
  }

  const TypeDescription& description_;
  std::vector<std::uint8_t>& bytes_;
};

/// `type` is one of `description`'s (what the writers index their tables by).
void check_is_of(const TypeDescription& description, const MessageType& type) {
  const std::less<const MessageType*> before;
  if (description.messages.empty() || before(&type, description.messages.data()) ||
      before(&description.messages.back(), &type)) {
    throw Error(type.name + " is not a message of the description it was given with");
  }
}

}  // namespace

std::vector<std::uint8_t> zero_message(const TypeDescription& description,
                                       const MessageType& type) {
  check_is_of(description, type);
  if (type.is_pod) return std::vector<std::uint8_t>(type.size, 0);
  return SerializedWriter(description, false).message(type);
}

std::vector<std::uint8_t> default_message(const TypeDescription& description,
                                          const MessageType& type) {
  check_is_of(description, type);
  if (!type.is_pod) return SerializedWriter(description, true).message(type);
  std::vector<std::uint8_t> bytes(type.size, 0);
  PodDefaults(description, bytes).message(type, 0);
  return bytes;
}

}  // namespace horus
