// CRC-32 and the bounds-checked reads of mcap_format.hpp.
#include "mcap_format.hpp"

#include <zlib.h>

#include <limits>

#include "horus/error.hpp"

namespace horus::detail::mcap {

std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size) noexcept {
  // zlib's CRC-32 is the one MCAP specifies, and faster than a table of our own.
  const auto* bytes = static_cast<const Bytef*>(data);
  while (size > 0) {
    const std::size_t step = std::min<std::size_t>(size, std::numeric_limits<uInt>::max());
    crc = static_cast<std::uint32_t>(::crc32(crc, bytes, static_cast<uInt>(step)));
    bytes += step;
    size -= step;
  }
  return crc;
}

namespace {

constexpr std::string_view kBase64Alphabet =
    "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

}  // namespace

std::string base64_encode(std::string_view bytes) {
  std::string text;
  text.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t at = 0; at < bytes.size(); at += 3) {
    const std::size_t taken = std::min<std::size_t>(3, bytes.size() - at);
    std::uint32_t group = 0;
    for (std::size_t i = 0; i < 3; ++i) {
      group = (group << 8) | (i < taken ? static_cast<std::uint8_t>(bytes[at + i]) : 0U);
    }
    for (std::size_t i = 0; i < 4; ++i) {
      text += i <= taken ? kBase64Alphabet[(group >> (18 - 6 * i)) & 0x3F] : '=';
    }
  }
  return text;
}

std::string base64_decode(std::string_view text, const std::string& what) {
  if (text.size() % 4 != 0) {
    throw Error(what + ": not base64 (" + std::to_string(text.size()) +
                " characters, not a multiple of 4)");
  }
  std::string bytes;
  bytes.reserve(text.size() / 4 * 3);
  for (std::size_t at = 0; at < text.size(); at += 4) {
    std::uint32_t group = 0;
    std::size_t padding = 0;
    for (std::size_t i = 0; i < 4; ++i) {
      const char c = text[at + i];
      const bool last_group = at + 4 == text.size();
      if (c == '=' && last_group && i >= 2 && (i == 3 || text[at + 3] == '=')) {
        ++padding;
        group <<= 6;
        continue;
      }
      const std::size_t value = kBase64Alphabet.find(c);
      if (value == std::string_view::npos || padding > 0) {
        throw Error(what + ": not base64 (character " + std::to_string(at + i) + ")");
      }
      group = (group << 6) | static_cast<std::uint32_t>(value);
    }
    for (std::size_t i = 0; i < 3 - padding; ++i) {
      bytes += static_cast<char>((group >> (16 - 8 * i)) & 0xFF);
    }
  }
  return bytes;
}

const std::uint8_t* Cursor::take(std::size_t size) {
  if (size > size_ - at_) {
    throw Error(what_ + ": a record ends early (needs " + std::to_string(size) + " bytes, " +
                std::to_string(size_ - at_) + " left)");
  }
  const std::uint8_t* at = data_ + at_;
  at_ += size;
  return at;
}

}  // namespace horus::detail::mcap
