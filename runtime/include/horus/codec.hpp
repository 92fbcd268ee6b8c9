// horus::encode / horus::decode: a message's wire bytes. POD messages are their raw struct bytes
// with padding zeroed (what Python's to_bytes() writes); serialized messages are MessagePack, an
// array of the fields in declaration order (horus/msgpack.hpp, included by their headers).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "horus/error.hpp"
#include "horus/type_info.hpp"

namespace horus {

namespace detail {
template <class T>
std::vector<std::uint8_t> msgpack_encode(const T& msg);
template <class T>
T msgpack_decode(std::span<const std::uint8_t> bytes);
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
template <Message T>
std::vector<std::uint8_t> encode(const T& msg) {
  if constexpr (TypeInfo<T>::is_pod) {
    std::vector<std::uint8_t> bytes(sizeof(T));
    encode_into(msg, bytes);
    return bytes;
  } else {
    return detail::msgpack_encode(msg);
  }
}

/// The message that `bytes` encode; throws horus::DecodeError when they are not one.
template <Message T>
T decode(std::span<const std::uint8_t> bytes) {
  if constexpr (TypeInfo<T>::is_pod) {
    if (bytes.size() != sizeof(T)) {
      throw DecodeError(std::string(TypeInfo<T>::name) + ": expected " +
                        std::to_string(sizeof(T)) + " bytes, got " +
                        std::to_string(bytes.size()));
    }
    T msg;
    std::memcpy(&msg, bytes.data(), sizeof(T));
    return msg;
  } else {
    return detail::msgpack_decode<T>(bytes);
  }
}

/// Like decode, but an empty optional instead of an exception.
template <Message T>
std::optional<T> try_decode(std::span<const std::uint8_t> bytes) noexcept {
  try {
    return decode<T>(bytes);
  } catch (...) {
    return std::nullopt;
  }
}

}  // namespace horus
