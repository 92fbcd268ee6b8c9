// Text built at compile time, for the identities the runtime spells itself (service frames, plain
// values): concatenation of static strings, decimal numbers, and the FNV-1a fingerprint of such a
// text.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace horus::detail {

/// The concatenation of static strings as one static string_view (for TypeInfo names and schemas).
template <const std::string_view&... Parts>
struct JoinedText {
  static constexpr std::size_t size = (Parts.size() + ... + 0);
  static constexpr std::array<char, size + 1> storage = [] {
    std::array<char, size + 1> out{};
    std::size_t at = 0;
    ((std::copy(Parts.begin(), Parts.end(), out.begin() + static_cast<std::ptrdiff_t>(at)),
      at += Parts.size()),
     ...);
    return out;
  }();
  static constexpr std::string_view value{storage.data(), size};
};

/// `Value` in decimal as a static string_view.
template <std::size_t Value>
struct DecimalText {
  static constexpr std::size_t size = [] {
    std::size_t digits = 1;
    for (std::size_t rest = Value; rest >= 10; rest /= 10) {
      ++digits;
    }
    return digits;
  }();
  static constexpr std::array<char, size + 1> storage = [] {
    std::array<char, size + 1> out{};
    std::size_t rest = Value;
    for (std::size_t i = size; i > 0; --i) {
      out[i - 1] = static_cast<char>('0' + rest % 10);
      rest /= 10;
    }
    return out;
  }();
  static constexpr std::string_view value{storage.data(), size};
};

/// The 64-bit FNV-1a hash of a text: the fingerprint of the identities the runtime spells itself.
constexpr std::uint64_t fnv1a(std::string_view text) noexcept {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (const char c : text) {
    hash = (hash ^ static_cast<std::uint8_t>(c)) * 0x100000001b3ULL;
  }
  return hash;
}

}  // namespace horus::detail
