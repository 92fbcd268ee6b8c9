// horus::FixedString<N>: the `string<N>` schema type. Exactly N bytes, alignment 1, NUL-padded;
// a string of exactly N bytes has no terminator. Trivially copyable, so messages that hold one
// stay POD and can live in shared memory.
#pragma once

#include <cstddef>
#include <cstring>
#include <string>
#include <string_view>

#include "horus/error.hpp"

namespace horus {

template <std::size_t N>
struct FixedString {
  static_assert(N > 0, "string<0> has no room for any text");

  char bytes[N]{};

  /// The text up to the first NUL (or all N bytes when the string is full).
  constexpr std::string_view view() const noexcept {
    std::size_t len = 0;
    while (len < N && bytes[len] != '\0') ++len;
    return {bytes, len};
  }
  std::string str() const { return std::string(view()); }
  constexpr std::size_t size() const noexcept { return view().size(); }
  constexpr bool empty() const noexcept { return bytes[0] == '\0'; }
  static constexpr std::size_t capacity() noexcept { return N; }

  /// Stores `text` NUL-padded; false (and unchanged) when it does not fit.
  constexpr bool try_assign(std::string_view text) noexcept {
    if (text.size() > N) return false;
    for (std::size_t i = 0; i < N; ++i) bytes[i] = i < text.size() ? text[i] : '\0';
    return true;
  }
  /// Stores `text`; throws horus::Error when it is longer than N bytes (never truncates silently).
  FixedString& assign(std::string_view text) {
    if (!try_assign(text)) {
      throw Error("string of " + std::to_string(text.size()) + " bytes does not fit in string<" +
                  std::to_string(N) + ">");
    }
    return *this;
  }
  FixedString& operator=(std::string_view text) { return assign(text); }

  constexpr operator std::string_view() const noexcept { return view(); }
  friend constexpr bool operator==(const FixedString& a, const FixedString& b) noexcept {
    return a.view() == b.view();
  }
  friend constexpr bool operator==(const FixedString& a, std::string_view b) noexcept {
    return a.view() == b;
  }
};

}  // namespace horus
