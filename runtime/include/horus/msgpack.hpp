// MessagePack for serialized messages, over msgpack-cxx. Every generated message and enum packs
// through the adaptors below: a message as an array of its fields in declaration order, an enum
// as its underlying integer, string<N> as a str. Python's generated code writes the same bytes.
// A plain string or vector on a topic (horus/plain_value.hpp) is framed as a message's one field.
//
// Only the parts of msgpack-cxx that message fields need are included (the whole library takes
// longer to compile than all of horus's other headers together). To pack other types into a
// GenericMessage, include their msgpack-cxx adaptor too (or <msgpack.hpp>).
#pragma once

#ifndef MSGPACK_NO_BOOST
#define MSGPACK_NO_BOOST
#endif

#include <msgpack/adaptor/bool.hpp>
#include <msgpack/adaptor/cpp11/array.hpp>
#include <msgpack/adaptor/cpp11/array_char.hpp>
#include <msgpack/adaptor/cpp11/array_unsigned_char.hpp>
#include <msgpack/adaptor/cpp17/optional.hpp>
#include <msgpack/adaptor/float.hpp>
#include <msgpack/adaptor/int.hpp>
#include <msgpack/adaptor/map.hpp>
#include <msgpack/adaptor/nil.hpp>
#include <msgpack/adaptor/string.hpp>
#include <msgpack/adaptor/vector.hpp>
#include <msgpack/adaptor/vector_bool.hpp>
#include <msgpack/adaptor/vector_char.hpp>
#include <msgpack/adaptor/vector_unsigned_char.hpp>
#include <msgpack/object.hpp>
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>
#include <msgpack/unpack.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "horus/codec.hpp"
#include "horus/fixed_string.hpp"
#include "horus/plain_value.hpp"
#include "horus/type_info.hpp"

namespace msgpack {
MSGPACK_API_VERSION_NAMESPACE(MSGPACK_DEFAULT_API_NS) {
  namespace adaptor {

  template <class T>
  struct pack<T, std::enable_if_t<horus::Message<T>>> {
    template <class Stream>
    packer<Stream>& operator()(packer<Stream>& o, const T& msg) const {
      o.pack_array(static_cast<std::uint32_t>(horus::TypeInfo<T>::field_count));
      horus::TypeInfo<T>::visit(msg, [&o](std::string_view, const auto& field) { o.pack(field); });
      return o;
    }
  };

  template <class T>
  struct convert<T, std::enable_if_t<horus::Message<T>>> {
    const msgpack::object& operator()(const msgpack::object& obj, T& msg) const {
      if (obj.type != msgpack::type::ARRAY ||
          obj.via.array.size != horus::TypeInfo<T>::field_count) {
        throw msgpack::type_error();
      }
      std::size_t index = 0;
      horus::TypeInfo<T>::visit(
          msg, [&](std::string_view, auto& field) { obj.via.array.ptr[index++].convert(field); });
      return obj;
    }
  };

  template <class E>
  struct pack<E, std::enable_if_t<horus::SchemaEnum<E>>> {
    template <class Stream>
    packer<Stream>& operator()(packer<Stream>& o, const E& value) const {
      o.pack(static_cast<std::underlying_type_t<E>>(value));
      return o;
    }
  };

  template <class E>
  struct convert<E, std::enable_if_t<horus::SchemaEnum<E>>> {
    const msgpack::object& operator()(const msgpack::object& obj, E& value) const {
      value = static_cast<E>(obj.as<std::underlying_type_t<E>>());
      return obj;
    }
  };

  template <std::size_t N>
  struct pack<horus::FixedString<N>> {
    template <class Stream>
    packer<Stream>& operator()(packer<Stream>& o, const horus::FixedString<N>& text) const {
      const std::string_view view = text.view();
      o.pack_str(static_cast<std::uint32_t>(view.size()));
      o.pack_str_body(view.data(), static_cast<std::uint32_t>(view.size()));
      return o;
    }
  };

  template <std::size_t N>
  struct convert<horus::FixedString<N>> {
    const msgpack::object& operator()(const msgpack::object& obj,
                                      horus::FixedString<N>& text) const {
      if (obj.type != msgpack::type::STR ||
          !text.try_assign(std::string_view(obj.via.str.ptr, obj.via.str.size))) {
        throw msgpack::type_error();
      }
      return obj;
    }
  };

  }  // namespace adaptor
}  // MSGPACK_API_VERSION_NAMESPACE
}  // namespace msgpack

namespace horus::detail {

/// Packs what a topic carrying `V` sends. A serialized plain value goes as the one field of a
/// message (an array of one element), so a tool that decodes the topic from its stored schema
/// (`value String`) as the message `PlainValue { value: String }` reads it.
template <class Stream, class V>
void pack_payload(msgpack::packer<Stream>& packer, const V& value) {
  if constexpr (SerializedPlainValue<V>) {
    packer.pack_array(1);
  }
  packer.pack(value);
}

/// The one value `bytes` hold, read by `convert(object, value)`; DecodeError naming `what`.
template <class V, class Convert>
V unpack_with(std::span<const std::uint8_t> bytes, std::string_view what, Convert convert) {
  try {
    std::size_t offset = 0;
    msgpack::object_handle handle =
        msgpack::unpack(reinterpret_cast<const char*>(bytes.data()), bytes.size(), offset);
    if (offset != bytes.size()) {
      throw DecodeError(std::string(what) + ": " + std::to_string(bytes.size() - offset) +
                        " trailing bytes after the MessagePack value");
    }
    V value{};
    convert(handle.get(), value);
    return value;
  } catch (const DecodeError&) {
    throw;
  } catch (const std::exception& e) {
    throw DecodeError(std::string(what) + ": not a valid MessagePack encoding (" + e.what() + ")");
  }
}

/// The bytes `pack(packer)` writes.
template <class Pack>
std::vector<std::uint8_t> packed(Pack pack) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  pack(packer);
  const auto* data = reinterpret_cast<const std::uint8_t*>(buffer.data());
  return std::vector<std::uint8_t>(data, data + buffer.size());
}

/// A value as itself (a serialized message, a GenericMessage payload of any type).
template <class V>
struct Msgpack {
  static std::vector<std::uint8_t> pack(const V& value) {
    return packed([&](auto& packer) { packer.pack(value); });
  }

  static V unpack(std::span<const std::uint8_t> bytes, std::string_view what) {
    return unpack_with<V>(bytes, what,
                          [](const msgpack::object& object, V& value) { object.convert(value); });
  }
};

/// A serialized plain value as a topic carries it (pack_payload).
template <class V>
struct PlainValueFrame {
  static std::vector<std::uint8_t> pack(const V& value) {
    return packed([&](auto& packer) { pack_payload(packer, value); });
  }

  static V unpack(std::span<const std::uint8_t> bytes, std::string_view what) {
    return unpack_with<V>(bytes, what, [](const msgpack::object& object, V& value) {
      if (object.type != msgpack::type::ARRAY || object.via.array.size != 1) {
        throw msgpack::type_error();
      }
      object.via.array.ptr[0].convert(value);
    });
  }
};

}  // namespace horus::detail
