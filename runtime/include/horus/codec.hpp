// horus::encode / horus::decode: a message's wire bytes. POD messages are their raw struct bytes
// with padding zeroed (what Python's to_bytes() writes); serialized messages are MessagePack, an
// array of the fields in declaration order. Plain values (horus/plain_value.hpp) are encoded as a
// message of one field holding them would be.
//
// MessagePack support is in horus/msgpack.hpp, which a program includes where it encodes or
// decodes a serialized message (horus/topic.hpp includes it). Message headers do not include it:
// msgpack-cxx costs more compile time than everything else a message header needs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "horus/error.hpp"
#include "horus/plain_value.hpp"
#include "horus/type_info.hpp"

namespace horus {

namespace detail {
/// MessagePack of a value (a serialized message, a GenericMessage payload): pack(value) and
/// unpack(bytes, what), which throws DecodeError naming `what`. Defined in horus/msgpack.hpp:
/// "incomplete type Msgpack<...>" means that header is not included.
template <class V>
struct Msgpack;

/// The same for a serialized plain value, framed as the one field of a message (a MessagePack
/// array of one element); also defined in horus/msgpack.hpp.
template <class V>
struct PlainValueFrame;

template <class T>
concept MsgpackIncluded = requires {
  sizeof(Msgpack<T>);
};

template <class T>
concept Serialized = SerializedMessage<T> || SerializedPlainValue<T>;

template <Serialized T>
using MsgpackCodec = std::conditional_t<PlainValue<T>, PlainValueFrame<T>, Msgpack<T>>;
}  // namespace detail

/// Copies a POD message into `out` (at least sizeof(T) bytes) with its padding zeroed.
template <PodMessage T>
void encode_into(const T& msg, std::span<std::uint8_t> out) noexcept {
  std::memcpy(out.data(), &msg, sizeof(T));
  for (const PaddingRange& hole : TypeInfo<T>::padding) {
    std::memset(out.data() + hole.offset, 0, hole.size);
  }
}

/// The wire bytes of `msg`.
template <TopicValue T>
std::vector<std::uint8_t> encode(const T& msg) {
  if constexpr (PodPlainValue<T>) {
    std::vector<std::uint8_t> bytes(sizeof(T));
    std::memcpy(bytes.data(), &msg, sizeof(T));
    return bytes;
  } else if constexpr (TypeInfo<T>::is_pod) {
    std::vector<std::uint8_t> bytes(sizeof(T));
    encode_into(msg, bytes);
    return bytes;
  } else {
    static_assert(detail::MsgpackIncluded<T>,
                  "include <horus/msgpack.hpp> to encode serialized messages");
    return detail::MsgpackCodec<T>::pack(msg);
  }
}

/// The message that `bytes` encode; throws horus::DecodeError when they are not one.
template <TopicValue T>
T decode(std::span<const std::uint8_t> bytes) {
  if constexpr (TypeInfo<T>::is_pod) {
    if (bytes.size() != sizeof(T)) {
      throw DecodeError(std::string(TypeInfo<T>::name) + ": expected " + std::to_string(sizeof(T)) +
                        " bytes, got " + std::to_string(bytes.size()));
    }
    T msg;
    std::memcpy(&msg, bytes.data(), sizeof(T));
    return msg;
  } else {
    static_assert(detail::MsgpackIncluded<T>,
                  "include <horus/msgpack.hpp> to decode serialized messages");
    return detail::MsgpackCodec<T>::unpack(bytes, TypeInfo<T>::name);
  }
}

/// Like decode, but an empty optional instead of an exception.
template <TopicValue T>
std::optional<T> try_decode(std::span<const std::uint8_t> bytes) noexcept {
  try {
    return decode<T>(bytes);
  } catch (...) {
    return std::nullopt;
  }
}

}  // namespace horus
