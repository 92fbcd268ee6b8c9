// walk_message: one encoded message through a MessageVisitor. POD bytes are read at the
// description's offsets (decode() proved every field lies inside its message); serialized bytes
// are the MessagePack that horus/msgpack.hpp's adaptors write, checked value by value.
#include <cstring>
#include <limits>

#include "horus/type_description.hpp"
#include "msgpack_input.hpp"

namespace horus {

namespace {

/// Reads a POD message: `bytes` is exactly the walked message's size.
class PodWalker {
 public:
  PodWalker(const TypeDescription& description, std::span<const std::uint8_t> bytes,
            MessageVisitor& visitor)
      : description_(description), bytes_(bytes), visitor_(visitor) {}

  void message(const MessageType& type, std::size_t at) {
    visitor_.begin_message(type);
    for (const MessageField& field : type.fields) {
      visitor_.field(field);
      value(field.type, at + *field.offset);
    }
    visitor_.end_message(type);
  }

 private:
  /// The `size` bytes at `at`; decode()'s layout checks make the bound hold, this keeps a
  /// description built by hand (not decoded) from reading past the message.
  const std::uint8_t* span_at(std::size_t at, std::size_t size) const {
    if (at > bytes_.size() || size > bytes_.size() - at) {
      throw DecodeError("POD message: a field at " + std::to_string(at) + " ends past its " +
                        std::to_string(bytes_.size()) + " bytes");
    }
    return bytes_.data() + at;
  }

  template <class T>
  T read(std::size_t at) const {
    T value;
    std::memcpy(&value, span_at(at, sizeof(T)), sizeof(T));
    return value;
  }

  std::int64_t integer(Primitive primitive, std::size_t at) const {
    switch (primitive) {
      case Primitive::U8:
        return read<std::uint8_t>(at);
      case Primitive::U16:
        return read<std::uint16_t>(at);
      case Primitive::U32:
        return read<std::uint32_t>(at);
      case Primitive::U64:
        return static_cast<std::int64_t>(read<std::uint64_t>(at));
      case Primitive::I8:
        return read<std::int8_t>(at);
      case Primitive::I16:
        return read<std::int16_t>(at);
      case Primitive::I32:
        return read<std::int32_t>(at);
      default:
        return read<std::int64_t>(at);
    }
  }

  void primitive(const TypeRef& type, std::size_t at) {
    switch (type.primitive) {
      case Primitive::Bool:
        visitor_.boolean(read<std::uint8_t>(at) != 0);
        return;
      case Primitive::F32:
        visitor_.floating(type, read<float>(at));
        return;
      case Primitive::F64:
        visitor_.floating(type, read<double>(at));
        return;
      case Primitive::U8:
      case Primitive::U16:
      case Primitive::U32:
      case Primitive::U64:
        visitor_.unsigned_integer(type, static_cast<std::uint64_t>(integer(type.primitive, at)));
        return;
      default:
        visitor_.signed_integer(type, integer(type.primitive, at));
    }
  }

  std::size_t size_of(const TypeRef& type) const {
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        return primitive_size(type.primitive);
      case TypeRef::Kind::FixedString:
        return type.length;
      case TypeRef::Kind::Array:
        return type.length * size_of(*type.element);
      case TypeRef::Kind::Message:
        return description_.message(type).size;
      case TypeRef::Kind::Enum:
        return primitive_size(description_.enumeration(type).underlying);
      default:
        throw DecodeError("POD message: a field of a serialized type (" + type.name + ")");
    }
  }

  void value(const TypeRef& type, std::size_t at) {
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        primitive(type, at);
        return;
      case TypeRef::Kind::FixedString: {
        const auto* text = reinterpret_cast<const char*>(span_at(at, type.length));
        visitor_.string(type, std::string_view(text, strnlen(text, type.length)));
        return;
      }
      case TypeRef::Kind::Array: {
        if (type.is_byte_block()) {
          visitor_.bytes(type, std::span(span_at(at, type.length), type.length));
          return;
        }
        const std::size_t stride = size_of(*type.element);
        span_at(at, stride * type.length);
        visitor_.begin_sequence(type, type.length);
        for (std::size_t i = 0; i < type.length; ++i) value(*type.element, at + i * stride);
        visitor_.end_sequence(type);
        return;
      }
      case TypeRef::Kind::Message:
        message(description_.message(type), at);
        return;
      case TypeRef::Kind::Enum: {
        const EnumType& enumeration = description_.enumeration(type);
        visitor_.enumerator(enumeration, integer(enumeration.underlying, at));
        return;
      }
      default:
        size_of(type);  // throws: no serialized kind has a place in a POD message
    }
  }

  const TypeDescription& description_;
  std::span<const std::uint8_t> bytes_;
  MessageVisitor& visitor_;
};

/// Reads the MessagePack tree of a serialized message.
class SerializedWalker {
 public:
  SerializedWalker(const TypeDescription& description, MessageVisitor& visitor)
      : description_(description), visitor_(visitor) {}

  void message(const MessageType& type, const msgpack::object& object) {
    if (object.type != msgpack::type::ARRAY || object.via.array.size != type.fields.size()) {
      throw DecodeError("serialized message: " + type.name + ": expected an array of its " +
                        std::to_string(type.fields.size()) + " fields");
    }
    visitor_.begin_message(type);
    for (std::size_t i = 0; i < type.fields.size(); ++i) {
      visitor_.field(type.fields[i]);
      value(type.fields[i].type, object.via.array.ptr[i], type.fields[i].name);
    }
    visitor_.end_message(type);
  }

 private:
  /// `where`: the field (of a message, or whose element) the bad value is in.
  [[noreturn]] static void fail(const std::string& what) {
    throw DecodeError("serialized message: field " + what);
  }

  static bool is_integer(const msgpack::object& object) {
    return object.type == msgpack::type::POSITIVE_INTEGER ||
           object.type == msgpack::type::NEGATIVE_INTEGER;
  }

  /// An integer of `primitive`'s range, as the bits of a 64-bit value.
  static std::int64_t integer(Primitive primitive, const msgpack::object& object,
                              std::string_view where) {
    if (!is_integer(object)) fail(std::string(where) + ": expected an integer");
    const bool negative = object.type == msgpack::type::NEGATIVE_INTEGER;
    const std::size_t bits = 8 * primitive_size(primitive);
    const bool is_signed = primitive == Primitive::I8 || primitive == Primitive::I16 ||
                           primitive == Primitive::I32 || primitive == Primitive::I64;
    bool fits = false;
    if (is_signed) {
      const std::int64_t low =
          bits == 64 ? std::numeric_limits<std::int64_t>::min() : -(std::int64_t{1} << (bits - 1));
      const std::uint64_t high = (std::uint64_t{1} << (bits - 1)) - 1;
      fits = negative ? object.via.i64 >= low : object.via.u64 <= high;
    } else {
      fits = !negative && (bits == 64 || object.via.u64 < (std::uint64_t{1} << bits));
    }
    if (!fits)
      fail(std::string(where) + ": out of range for " + std::string(primitive_name(primitive)));
    return negative ? object.via.i64 : static_cast<std::int64_t>(object.via.u64);
  }

  void primitive(const TypeRef& type, const msgpack::object& object, std::string_view where) {
    switch (type.primitive) {
      case Primitive::Bool:
        if (object.type != msgpack::type::BOOLEAN) fail(std::string(where) + ": expected a bool");
        visitor_.boolean(object.via.boolean);
        return;
      case Primitive::F32:
      case Primitive::F64:
        // As msgpack-cxx's decoders do, an integer is read as a float too.
        if (object.type == msgpack::type::FLOAT32 || object.type == msgpack::type::FLOAT64) {
          visitor_.floating(type, object.via.f64);
        } else if (object.type == msgpack::type::POSITIVE_INTEGER) {
          visitor_.floating(type, static_cast<double>(object.via.u64));
        } else if (object.type == msgpack::type::NEGATIVE_INTEGER) {
          visitor_.floating(type, static_cast<double>(object.via.i64));
        } else {
          fail(std::string(where) + ": expected a number");
        }
        return;
      case Primitive::U8:
      case Primitive::U16:
      case Primitive::U32:
      case Primitive::U64:
        visitor_.unsigned_integer(
            type, static_cast<std::uint64_t>(integer(type.primitive, object, where)));
        return;
      default:
        visitor_.signed_integer(type, integer(type.primitive, object, where));
    }
  }

  /// A str or bin (msgpack-cxx reads either into std::string and std::vector<std::uint8_t>).
  static std::string_view block(const msgpack::object& object, std::string_view where,
                                std::string_view expected) {
    if (object.type == msgpack::type::STR) return {object.via.str.ptr, object.via.str.size};
    if (object.type == msgpack::type::BIN) return {object.via.bin.ptr, object.via.bin.size};
    fail(std::string(where) + ": expected " + std::string(expected));
  }

  void value(const TypeRef& type, const msgpack::object& object, std::string_view where) {
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        primitive(type, object, where);
        return;
      case TypeRef::Kind::FixedString:
      case TypeRef::Kind::String: {
        const std::string_view text = block(object, where, "a string");
        if (type.kind == TypeRef::Kind::FixedString && text.size() > type.length) {
          fail(std::string(where) + ": " + std::to_string(text.size()) +
               " bytes do not fit string<" + std::to_string(type.length) + ">");
        }
        visitor_.string(type, text);
        return;
      }
      case TypeRef::Kind::Bytes:
        bytes(type, object, where);
        return;
      case TypeRef::Kind::Array:
      case TypeRef::Kind::Vec: {
        if (type.is_byte_block()) {
          bytes(type, object, where);
          return;
        }
        if (object.type != msgpack::type::ARRAY) fail(std::string(where) + ": expected an array");
        const std::size_t count = object.via.array.size;
        if (type.kind == TypeRef::Kind::Array && count != type.length) {
          fail(std::string(where) + ": expected " + std::to_string(type.length) +
               " elements, got " + std::to_string(count));
        }
        visitor_.begin_sequence(type, count);
        for (std::size_t i = 0; i < count; ++i) {
          value(*type.element, object.via.array.ptr[i], where);
        }
        visitor_.end_sequence(type);
        return;
      }
      case TypeRef::Kind::Optional: {
        const bool present = object.type != msgpack::type::NIL;
        visitor_.begin_optional(type, present);
        if (present) value(*type.element, object, where);
        visitor_.end_optional(type);
        return;
      }
      case TypeRef::Kind::Message:
        message(description_.message(type), object);
        return;
      case TypeRef::Kind::Enum: {
        const EnumType& enumeration = description_.enumeration(type);
        visitor_.enumerator(enumeration, integer(enumeration.underlying, object, where));
        return;
      }
    }
  }

  void bytes(const TypeRef& type, const msgpack::object& object, std::string_view where) {
    const std::string_view data = block(object, where, "bytes (a bin)");
    if (type.kind == TypeRef::Kind::Array && data.size() != type.length) {
      fail(std::string(where) + ": expected " + std::to_string(type.length) + " bytes, got " +
           std::to_string(data.size()));
    }
    visitor_.bytes(type,
                   std::span(reinterpret_cast<const std::uint8_t*>(data.data()), data.size()));
  }

  const TypeDescription& description_;
  MessageVisitor& visitor_;
};

}  // namespace

void walk_message(const TypeDescription& description, const MessageType& type,
                  std::span<const std::uint8_t> bytes, MessageVisitor& visitor) {
  if (type.is_pod) {
    if (bytes.size() != type.size) {
      throw DecodeError(type.name + ": expected " + std::to_string(type.size) + " bytes, got " +
                        std::to_string(bytes.size()));
    }
    PodWalker(description, bytes, visitor).message(type, 0);
    return;
  }
  const msgpack::object_handle handle = types::unpack_whole<DecodeError>(
      reinterpret_cast<const char*>(bytes.data()), bytes.size(), type.name);
  SerializedWalker(description, visitor).message(type, handle.get());
}

}  // namespace horus
