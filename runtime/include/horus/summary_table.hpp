// Log summaries as data: what a generated log_summary() hands to the one formatter compiled into
// horus::summary (runtime/src/summary/summary_table.cpp), which prints it by the rules of
// horus/log_summary.hpp. horus-gen writes, per package, a table of the types its fields hold and,
// per message, the parts of its line (literal text, or a field: its type, element label, unit);
// log_summary() then only lists its fields' addresses. A summary compiled this way costs no
// template instantiation per field type: a package's generated .cpp compiles in a fraction of the
// time, and the formatting code exists once in the program.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace horus::summary {

/// What a value is, as the formatter reads it from its address.
enum class Kind : std::uint8_t {
  kBool,
  kI8,
  kI16,
  kI32,
  kI64,
  kU8,
  kU16,
  kU32,
  kU64,
  kF32,
  kF64,
  kFixedString,  // horus::FixedString<length>
  kString,       // std::string
  kEnum,         // element: the underlying integer type; enumerators: its names
  kMessage,      // message_summary: its log_summary()
  kArray,        // std::array<element, length>
  kVector,       // std::vector<element> (bytes too); elements: its data and size
  kBoolVector,   // std::vector<bool>, which has no data()
  kOptional,     // std::optional<element>; optional_value: the value, or nullptr when empty
};

struct Elements {
  const void* data;
  std::size_t count;
};

/// A named value of an enum: the value as its underlying integer converted to 64 bits.
struct Enumerator {
  std::uint64_t value;
  std::string_view name;
};

/// One type a field (or an element of one) holds. `size` is sizeof the C++ type: the stride of a
/// sequence of it. Written with the functions below, which set what each kind reads.
struct Type {
  Kind kind;
  std::size_t size;
  std::size_t length;  // kArray: elements; kFixedString: capacity; kEnum: enumerators
  const Type* element;
  const Enumerator* enumerators;
  std::string (*message_summary)(const void* message);
  Elements (*elements)(const void* vector);
  const void* (*optional_value)(const void* optional);
};

/// One piece of a summary line: literal `text`, or (when `type` is set) the value of the next field
/// in the addresses log_summary() passes, followed by " unit" when it has one. `label` names the
/// element type in "[N x label]" forms.
struct Part {
  std::string_view text;
  const Type* type;
  std::string_view label;
  std::string_view unit;
};

// What generated tables are written with (every member named, whatever the kind).
constexpr Part text(std::string_view text) noexcept { return {text, nullptr, {}, {}}; }
constexpr Part field(const Type& type, std::string_view label = {},
                     std::string_view unit = {}) noexcept {
  return {{}, &type, label, unit};
}

/// Numbers, bool and std::string.
constexpr Type plain_type(Kind kind, std::size_t size) noexcept {
  return {kind, size, 0, nullptr, nullptr, nullptr, nullptr, nullptr};
}
constexpr Type fixed_string_type(std::size_t capacity) noexcept {
  return {Kind::kFixedString, capacity, capacity, nullptr, nullptr, nullptr, nullptr, nullptr};
}
constexpr Type array_type(std::size_t size, std::size_t length, const Type& element) noexcept {
  return {Kind::kArray, size, length, &element, nullptr, nullptr, nullptr, nullptr};
}
constexpr Type vector_type(std::size_t size, const Type& element,
                           Elements (*elements)(const void*)) noexcept {
  return {Kind::kVector, size, 0, &element, nullptr, nullptr, elements, nullptr};
}
constexpr Type bool_vector_type(std::size_t size, const Type& element) noexcept {
  return {Kind::kBoolVector, size, 0, &element, nullptr, nullptr, nullptr, nullptr};
}
constexpr Type optional_type(std::size_t size, const Type& element,
                             const void* (*optional_value)(const void*)) noexcept {
  return {Kind::kOptional, size, 0, &element, nullptr, nullptr, nullptr, optional_value};
}
constexpr Type enum_type(std::size_t size, const Type& underlying, const Enumerator* enumerators,
                         std::size_t count) noexcept {
  return {Kind::kEnum, size, count, &underlying, enumerators, nullptr, nullptr, nullptr};
}
constexpr Type message_type(std::size_t size,
                            std::string (*message_summary)(const void*)) noexcept {
  return {Kind::kMessage, size, 0, nullptr, nullptr, message_summary, nullptr, nullptr};
}

/// The line `parts` describe, reading the i-th field part's value at `fields[i]`.
std::string format(const Part* parts, std::size_t count, const void* const* fields);

template <std::size_t N>
std::string format(const Part (&parts)[N], const void* const* fields) {
  return format(parts, N, fields);
}

// The accessors a generated table names for the types whose layout the standard library does not
// fix. Each is instantiated once per C++ type in a package, and is a line of code.
template <class Vector>
Elements vector_elements(const void* vector) {
  const Vector& v = *static_cast<const Vector*>(vector);
  return {v.data(), v.size()};
}

template <class Optional>
const void* optional_value(const void* optional) {
  const Optional& o = *static_cast<const Optional*>(optional);
  return o.has_value() ? &*o : nullptr;
}

template <class Msg>
std::string message_summary(const void* message) {
  return static_cast<const Msg*>(message)->log_summary();
}

}  // namespace horus::summary
