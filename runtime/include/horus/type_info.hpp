// horus::TypeInfo<T>: the identity and layout of a generated type, specialised by horus-gen.
//
// The runtime and tools rely only on what is declared here; everything a generated header needs
// from the runtime is in this header, fixed_string.hpp, log_summary.hpp and codec.hpp
// (plus msgpack.hpp for serialized messages).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <type_traits>

namespace horus {

/// Specialised by horus-gen for every message and enum. A message's specialisation holds:
///   name         "pkg.Name"                   (std::string_view)
///   package      "pkg"                        (std::string_view)
///   fingerprint  hash of the canonical schema (std::uint64_t, equal to the Python value)
///   is_pod       all fields fixed-size: raw struct bytes on the wire, zero copy in shared memory
///   size         sizeof(T), also the wire size of a POD message
///   alignment    alignof(T)
///   schema       canonical schema text of T and every type it uses, so tools can decode any topic
///   description  the type description of T and every type it uses (docs/type-description.md), as
///                MessagePack bytes (std::string_view over a static array)
///   field_count  number of fields
///   padding      the byte ranges that are padding (POD only), zeroed by horus::encode
///   visit(msg, fn)  calls fn(std::string_view field_name, field&) for every field in order
/// An enum's specialisation holds name, package, fingerprint, schema, description, is_enum = true,
/// and to_string(E) (the enumerator name, or an empty view for a value outside the enum).
template <class T>
struct TypeInfo;

/// A byte range of a POD message that belongs to no field.
struct PaddingRange {
  std::size_t offset;
  std::size_t size;
};

/// True for every generated message type.
template <class T>
concept Message = requires {
  { TypeInfo<T>::name } -> std::convertible_to<std::string_view>;
  { TypeInfo<T>::fingerprint } -> std::convertible_to<std::uint64_t>;
  { TypeInfo<T>::is_pod } -> std::convertible_to<bool>;
  { TypeInfo<T>::field_count } -> std::convertible_to<std::size_t>;
  { TypeInfo<T>::description } -> std::convertible_to<std::string_view>;
};

/// True for generated messages that are plain old data (shared memory, zero copy).
template <class T>
concept PodMessage = Message<T> && TypeInfo<T>::is_pod && std::is_trivially_copyable_v<T> &&
    std::is_standard_layout_v<T>;

/// True for generated messages carried as MessagePack.
template <class T>
concept SerializedMessage = Message<T> && !TypeInfo<T>::is_pod;

/// True for generated enums.
template <class E>
concept SchemaEnum = std::is_enum_v<E> && requires {
  { TypeInfo<E>::is_enum } -> std::convertible_to<bool>;
};

}  // namespace horus
