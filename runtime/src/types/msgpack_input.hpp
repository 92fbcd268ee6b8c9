// The one way this library unpacks MessagePack it did not write: every count capped by the
// input's length (each element takes at least one byte), so a forged header cannot make
// msgpack-cxx allocate more than a fixed multiple of the bytes it was given.
#pragma once

#ifndef MSGPACK_NO_BOOST
#define MSGPACK_NO_BOOST
#endif

#include <msgpack/object.hpp>
#include <msgpack/unpack.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace horus::types {

/// Nesting of MessagePack containers accepted in any input: the format's trees and messages
/// nest far less (kMaxTypeNesting levels of types, a few containers each).
inline constexpr std::size_t kMaxMsgpackDepth = 512;

/// The one value `data` holds. Throws `Failure(text)` naming `what` when the bytes are not one
/// whole MessagePack value (truncated, trailing bytes, a count beyond the input).
template <class Failure>
msgpack::object_handle unpack_whole(const char* data, std::size_t size, std::string_view what) {
  const msgpack::unpack_limit limit(size, size, size, size, size, kMaxMsgpackDepth);
  std::size_t offset = 0;
  msgpack::object_handle handle;
  try {
    handle = msgpack::unpack(data, size, offset, nullptr, nullptr, limit);
  } catch (const std::exception& e) {
    throw Failure(std::string(what) + ": not a valid MessagePack value (" + e.what() + ")");
  }
  if (offset != size) {
    throw Failure(std::string(what) + ": " + std::to_string(size - offset) +
                  " trailing bytes after the MessagePack value");
  }
  return handle;
}

}  // namespace horus::types
