// Plain values on topics, as seed 002 uses them (`Topic<f32>`, `Topic<u64>`, `Topic<String>`):
// bool, the fixed-width integers, float and double, and std::array of those (nested too), carried
// byte for byte like a POD message; std::string and std::vector of plain values, carried as
// MessagePack like a serialized message. None has a schema file of its own.
//
// Their identity is spelled the way the schema language spells the type: the name is `f32`,
// `u64`, `[f32; 3]`, `[[u8; 4]; 2]`, `String`, `Vec<u8>`, `Vec<[f32; 3]>`; the schema text is
// `value <name>\n`; the fingerprint is the FNV-1a hash of that text, as for the other identities
// the runtime spells itself (service frames). Python computes the same three from the same rule
// (runtime/python/horus/_values.py).
//
// On the wire a plain value is what the message `PlainValue { value: <name> }` would be: its
// bytes for a fixed-size value, a MessagePack array of the one value for a string or a vector
// (horus/msgpack.hpp). So each carries the type description of that message
// (TypeInfo<T>::description, docs/type-description.md): named, fingerprinted and with the schema
// text of its identity, its one field `value` at offset 0, the summary the plain value's
// log_summary() prints. It is built with the description encoder the first time it is read
// (runtime/src/types/plain_value_description.cpp); Python builds the same bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "horus/detail/service_description.hpp"
#include "horus/detail/static_text.hpp"
#include "horus/log_summary.hpp"
#include "horus/type_description.hpp"
#include "horus/type_info.hpp"

namespace horus {

/// True for the plain values a topic carries (see above). A plain value is not a Message: it has
/// no fields.
template <class T>
concept PlainValue = requires {
  requires TypeInfo<T>::is_plain_value;
};

/// The plain values of a fixed size (numbers, bools, arrays of them): copied byte for byte.
template <class T>
concept PodPlainValue = PlainValue<T> && TypeInfo<T>::is_pod;

/// The plain values whose size is known only at run time (std::string, std::vector).
template <class T>
concept SerializedPlainValue = PlainValue<T> && !TypeInfo<T>::is_pod;

/// What a Topic carries: a generated message or a plain value.
template <class T>
concept TopicValue = Message<T> || PlainValue<T>;

/// What a Topic copies byte for byte into shared memory (zero copy, loans).
template <class T>
concept PodTopicValue = PodMessage<T> || PodPlainValue<T>;

namespace detail {

inline constexpr std::string_view kPlainValueSchemaOpen = "value ";
inline constexpr std::string_view kPlainValueSchemaClose = "\n";

/// The type description of the message `PlainValue { value: <name> }` a plain value is on the
/// wire: `value_type` is the field's TYPE, `label` the summary's element label; `size` and
/// `alignment` its POD layout (both 0 for a serialized value).
std::string plain_value_description(std::string_view name, const TypeRef& value_type,
                                    std::string_view label, std::size_t size,
                                    std::size_t alignment);

/// The TYPE of the plain value T, as horus-gen writes it for a field of that spelling.
template <class T>
TypeRef plain_value_type();

template <class T>
std::string plain_value_description_of();

template <class T, const std::string_view& Name>
struct PlainValueIdentity {
  using type = T;
  static constexpr std::string_view name = Name;
  static constexpr std::string_view package = "";
  static constexpr std::string_view schema =
      JoinedText<kPlainValueSchemaOpen, Name, kPlainValueSchemaClose>::value;
  static constexpr std::uint64_t fingerprint = fnv1a(schema);
  static constexpr BuiltDescription<plain_value_description_of<T>> description{};
  static constexpr bool is_plain_value = true;
};

template <class T, const std::string_view& Name>
struct PlainValueTypeInfo : PlainValueIdentity<T, Name> {
  static_assert(std::is_trivially_copyable_v<T> && std::is_standard_layout_v<T>);
  static constexpr bool is_pod = true;
  static constexpr std::size_t size = sizeof(T);
  static constexpr std::size_t alignment = alignof(T);
};

template <class T, const std::string_view& Name>
struct SerializedPlainValueTypeInfo : PlainValueIdentity<T, Name> {
  static constexpr bool is_pod = false;
};

inline constexpr std::string_view kBoolName = "bool";
inline constexpr std::string_view kI8Name = "i8";
inline constexpr std::string_view kI16Name = "i16";
inline constexpr std::string_view kI32Name = "i32";
inline constexpr std::string_view kI64Name = "i64";
inline constexpr std::string_view kU8Name = "u8";
inline constexpr std::string_view kU16Name = "u16";
inline constexpr std::string_view kU32Name = "u32";
inline constexpr std::string_view kU64Name = "u64";
inline constexpr std::string_view kF32Name = "f32";
inline constexpr std::string_view kF64Name = "f64";

inline constexpr std::string_view kArrayOpen = "[";
inline constexpr std::string_view kArrayLength = "; ";
inline constexpr std::string_view kArrayClose = "]";
inline constexpr std::string_view kStringName = "String";
inline constexpr std::string_view kVecOpen = "Vec<";
inline constexpr std::string_view kVecClose = ">";

/// The label of the elements in a summary's `[N x label]` form: the element type's name.
template <class T>
inline constexpr std::string_view kElementLabel{};
template <class T, std::size_t N>
inline constexpr std::string_view kElementLabel<std::array<T, N>> = TypeInfo<T>::name;
template <class T>
inline constexpr std::string_view kElementLabel<std::vector<T>> = TypeInfo<T>::name;

template <class T>
struct PlainValueTypeOf {
  static TypeRef make() {
    TypeRef type;
    type.kind = TypeRef::Kind::Primitive;
    // A number's or bool's plain-value name is its primitive's spelling.
    type.primitive = *primitive_named(TypeInfo<T>::name);
    return type;
  }
};
template <>
struct PlainValueTypeOf<std::string> {
  static TypeRef make() {
    TypeRef type;
    type.kind = TypeRef::Kind::String;
    return type;
  }
};
template <class T, std::size_t N>
struct PlainValueTypeOf<std::array<T, N>> {
  static TypeRef make() {
    TypeRef type;
    type.kind = TypeRef::Kind::Array;
    type.length = N;
    type.element = std::make_shared<const TypeRef>(plain_value_type<T>());
    return type;
  }
};
template <class T>
struct PlainValueTypeOf<std::vector<T>> {
  static TypeRef make() {
    TypeRef type;
    type.kind = TypeRef::Kind::Vec;
    type.element = std::make_shared<const TypeRef>(plain_value_type<T>());
    return type;
  }
};

template <class T>
TypeRef plain_value_type() {
  return PlainValueTypeOf<T>::make();
}

template <class T>
std::string plain_value_description_of() {
  using Info = TypeInfo<T>;
  if constexpr (Info::is_pod) {
    return plain_value_description(Info::name, plain_value_type<T>(), kElementLabel<T>, sizeof(T),
                                   alignof(T));
  } else {
    return plain_value_description(Info::name, plain_value_type<T>(), kElementLabel<T>, 0, 0);
  }
}

}  // namespace detail

template <>
struct TypeInfo<bool> : detail::PlainValueTypeInfo<bool, detail::kBoolName> {};
template <>
struct TypeInfo<std::int8_t> : detail::PlainValueTypeInfo<std::int8_t, detail::kI8Name> {};
template <>
struct TypeInfo<std::int16_t> : detail::PlainValueTypeInfo<std::int16_t, detail::kI16Name> {};
template <>
struct TypeInfo<std::int32_t> : detail::PlainValueTypeInfo<std::int32_t, detail::kI32Name> {};
template <>
struct TypeInfo<std::int64_t> : detail::PlainValueTypeInfo<std::int64_t, detail::kI64Name> {};
template <>
struct TypeInfo<std::uint8_t> : detail::PlainValueTypeInfo<std::uint8_t, detail::kU8Name> {};
template <>
struct TypeInfo<std::uint16_t> : detail::PlainValueTypeInfo<std::uint16_t, detail::kU16Name> {};
template <>
struct TypeInfo<std::uint32_t> : detail::PlainValueTypeInfo<std::uint32_t, detail::kU32Name> {};
template <>
struct TypeInfo<std::uint64_t> : detail::PlainValueTypeInfo<std::uint64_t, detail::kU64Name> {};
template <>
struct TypeInfo<float> : detail::PlainValueTypeInfo<float, detail::kF32Name> {};
template <>
struct TypeInfo<double> : detail::PlainValueTypeInfo<double, detail::kF64Name> {};

/// `[<element>; <N>]`, the schema language's spelling of a fixed array.
template <PodPlainValue T, std::size_t N>
requires(N > 0) struct TypeInfo<std::array<T, N>>
    : detail::PlainValueTypeInfo<
          std::array<T, N>,
          detail::JoinedText<detail::kArrayOpen, TypeInfo<T>::name, detail::kArrayLength,
                             detail::DecimalText<N>::value, detail::kArrayClose>::value> {
};

template <>
struct TypeInfo<std::string>
    : detail::SerializedPlainValueTypeInfo<std::string, detail::kStringName> {};

/// `Vec<<element>>`: a std::vector<std::uint8_t> is `Vec<u8>`, carried as MessagePack bin.
template <PlainValue T>
struct TypeInfo<std::vector<T>>
    : detail::SerializedPlainValueTypeInfo<
          std::vector<T>,
          detail::JoinedText<detail::kVecOpen, TypeInfo<T>::name, detail::kVecClose>::value> {};

/// The one-line summary of a plain value, by the rules of horus/log_summary.hpp (a message's is
/// its log_summary()): what Python's plain values print too.
template <PlainValue T>
std::string log_summary(const T& value) {
  std::string out;
  summary::append_value(out, value, detail::kElementLabel<T>);
  return out;
}

}  // namespace horus
