// A generated message with every field set: non-empty vectors and strings, options present,
// numbers of both signs, each value different from the one before. Tests that must reach every
// kind of value (a round trip pinned by a golden hash, a walk of the type description) fill
// their messages with it.
#pragma once

#include <horus/message.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace horus_test {

template <class T>
struct IsStdArray : std::false_type {};
template <class E, std::size_t N>
struct IsStdArray<std::array<E, N>> : std::true_type {};
template <class T>
struct IsVector : std::false_type {};
template <class E>
struct IsVector<std::vector<E>> : std::true_type {};
template <class T>
struct IsOptional : std::false_type {};
template <class E>
struct IsOptional<std::optional<E>> : std::true_type {};
template <class T>
struct IsFixedString : std::false_type {};
template <std::size_t N>
struct IsFixedString<horus::FixedString<N>> : std::true_type {};

/// Which value an enum field gets: always its first enumerator (what the golden hashes of
/// msg_roundtrip_test pinned), or the first and second in turn.
enum class Enums { First, Alternate };

/// Sets every field of `value`; `k` numbers the values and is advanced past them.
template <class T>
void fill_every_field(T& value, std::uint64_t& k, Enums enums = Enums::First) {
  if constexpr (std::is_same_v<T, bool>) {
    value = (k++ % 2) == 1;
  } else if constexpr (std::is_enum_v<T>) {
    value = static_cast<T>(enums == Enums::Alternate ? k % 2 : 0);
    ++k;
  } else if constexpr (std::is_floating_point_v<T>) {
    value = static_cast<T>(static_cast<double>(k++) + 0.25);
  } else if constexpr (std::is_unsigned_v<T>) {
    value = static_cast<T>(k++);
  } else if constexpr (std::is_signed_v<T>) {
    constexpr std::uint64_t modulus = std::uint64_t{1} << (sizeof(T) * 8 - 1);
    value = static_cast<T>(-static_cast<std::int64_t>(k++ % modulus));
  } else if constexpr (IsFixedString<T>::value) {
    const std::string text = "s" + std::to_string(k++);
    value.assign(std::string_view(text).substr(0, T::capacity()));
  } else if constexpr (std::is_same_v<T, std::string>) {
    value = "text" + std::to_string(k++);
  } else if constexpr (std::is_same_v<T, std::vector<std::uint8_t>>) {
    value = {static_cast<std::uint8_t>(k), static_cast<std::uint8_t>(k + 1),
             static_cast<std::uint8_t>(k + 2)};
    ++k;
  } else if constexpr (IsStdArray<T>::value) {
    for (auto& element : value) fill_every_field(element, k, enums);
  } else if constexpr (IsVector<T>::value) {
    value.resize(2);
    for (auto& element : value) fill_every_field(element, k, enums);
  } else if constexpr (IsOptional<T>::value) {
    value.emplace();
    fill_every_field(*value, k, enums);
  } else {
    static_assert(horus::Message<T>, "a field type the filler does not know");
    horus::TypeInfo<T>::visit(
        value, [&k, enums](std::string_view, auto& field) { fill_every_field(field, k, enums); });
  }
}

}  // namespace horus_test
