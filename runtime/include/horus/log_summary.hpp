// The one-line text that generated `log_summary()` methods produce. Python's generated mirrors
// follow the same rules, so both languages print the same line for the same values:
//   numbers   integers in decimal, floats as printf("%g") of the value as a double
//   bool      true / false
//   enum      the enumerator's name (the number when the value is not in the enum)
//   strings   "text"
//   bytes     <N bytes>        ([u8; N], Vec<u8>, bytes)
//   arrays    [a, b, c] up to 8 numbers or 4 other elements; longer ones
//             [N x f32, min a, max b] for numbers, [N x Label] otherwise; [] when empty
//   Option    none, or the value
//   message   its own log_summary()
// A field with a unit is followed by a space and the unit.
#pragma once

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <type_traits>

#include "horus/fixed_string.hpp"
#include "horus/type_info.hpp"

namespace horus::summary {

inline constexpr std::size_t kMaxNumbersShown = 8;
inline constexpr std::size_t kMaxElementsShown = 4;

template <class T>
concept Number = std::is_arithmetic_v<T> && !std::same_as<T, bool>;

template <class T>
concept Sequence = requires(const T& v) {
  v.size();
  v.begin();
  typename T::value_type;
};

template <class T>
concept OptionalLike = requires(const T& v) {
  v.has_value();
  *v;
};

template <class T>
concept ByteSequence = Sequence<T> && std::same_as<typename T::value_type, std::uint8_t>;

inline void append_number(std::string& out, double value) {
  char text[32];
  int n = std::snprintf(text, sizeof text, "%g", value);
  out.append(text, static_cast<std::size_t>(n));
}

template <class T>
void append_value(std::string& out, const T& value, std::string_view element_label = {});

template <class T>
void append_sequence(std::string& out, const T& seq, std::string_view element_label) {
  using Element = typename T::value_type;
  const std::size_t count = seq.size();
  if (count == 0) {
    out += "[]";
    return;
  }
  if constexpr (Number<Element>) {
    if (count > kMaxNumbersShown) {
      Element lo = *seq.begin(), hi = *seq.begin();
      for (const Element& e : seq) {
        if (e < lo) lo = e;
        if (hi < e) hi = e;
      }
      out += '[';
      out += std::to_string(count);
      out += " x ";
      out += element_label;
      out += ", min ";
      append_number(out, static_cast<double>(lo));
      out += ", max ";
      append_number(out, static_cast<double>(hi));
      out += ']';
      return;
    }
  } else if (count > kMaxElementsShown) {
    out += '[';
    out += std::to_string(count);
    out += " x ";
    out += element_label;
    out += ']';
    return;
  }
  out += '[';
  bool first = true;
  for (const Element& e : seq) {
    if (!first) out += ", ";
    first = false;
    append_value(out, e);
  }
  out += ']';
}

template <class T>
void append_value(std::string& out, const T& value, std::string_view element_label) {
  if constexpr (std::same_as<T, bool>) {
    out += value ? "true" : "false";
  } else if constexpr (std::is_floating_point_v<T>) {
    append_number(out, static_cast<double>(value));
  } else if constexpr (std::is_integral_v<T>) {
    out += std::to_string(value);
  } else if constexpr (SchemaEnum<T>) {
    std::string_view name = TypeInfo<T>::to_string(value);
    if (name.empty()) {
      out += std::to_string(static_cast<std::underlying_type_t<T>>(value));
    } else {
      out += name;
    }
  } else if constexpr (std::convertible_to<const T&, std::string_view>) {
    out += '"';
    out += std::string_view(value);
    out += '"';
  } else if constexpr (ByteSequence<T>) {
    out += '<';
    out += std::to_string(value.size());
    out += " bytes>";
  } else if constexpr (Message<T>) {
    out += value.log_summary();
  } else if constexpr (OptionalLike<T>) {
    if (value.has_value()) {
      append_value(out, *value, element_label);
    } else {
      out += "none";
    }
  } else {
    static_assert(Sequence<T>, "no log summary rule for this field type");
    append_sequence(out, value, element_label);
  }
}

/// Appends `value`, then " unit" when the field has a unit.
template <class T>
void append_field(std::string& out, const T& value, std::string_view element_label,
                  std::string_view unit) {
  append_value(out, value, element_label);
  if (!unit.empty()) {
    out += ' ';
    out += unit;
  }
}

}  // namespace horus::summary
