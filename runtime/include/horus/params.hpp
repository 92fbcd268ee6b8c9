// Parameters: a node's knobs (a top speed, a gain, a mode), declared with their type, default,
// range and unit, held in the namespace's shared memory so that every process reads them without
// asking anyone, and written only through the node that owns them.
//
// The store: one file per node, <root>/@params/<namespace>/<node>, under the ownership and mode
// rules of every shared-memory object (detail/shm_access.hpp). It holds the node's declarations
// as a type description (docs/type-description.md: a root message with one field per parameter,
// each field with the declaration keys "doc", "range", "choices", "read_only") and one record
// per parameter. A record is read lock-free: a scalar of up to 8 bytes is one atomic word; a
// string or an array is double-buffered, each buffer under its own sequence number, so a reader
// never waits for a writer, never sees a torn value, and a writer killed mid-write leaves the
// other buffer, the current value, intact. The owner (the process whose Scheduler runs the node)
// holds an exclusive flock(2) on the file while it runs, so a second owner is refused naming the
// first, and a dead owner's store is taken over by the next start.
//
// A write from anywhere else (another process, `horus param`, a YAML file, a remote peer) is
// checked against the declaration (type, range, allowed values, read-only), then travels to the
// owner as a HORUS service call on the service param_service_name(node); the owner offers it to
// the node's on_param_change() between two ticks, never beside another call of the node (see
// Node::on_param_change for which thread), and only an accepted value is stored: the record's
// version goes up and whoever waits on the store is woken. docs/parameters.md is the user's guide.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "horus/error.hpp"
#include "horus/type_description.hpp"

namespace horus {

/// A write was refused (by its declaration, by the owner's on_param_change, or because the owner
/// does not run), or a parameter, node or store does not exist; what() says which and why.
class ParamError : public Error {
 public:
  using Error::Error;
};

/// The most bytes a String or fixed-array parameter holds.
inline constexpr std::size_t kMaxParamValueBytes = 256;

/// What a declaration says about one parameter, whatever declared it (a .hnode params block,
/// Node::declare_param in C++ or Python). Values are MessagePack bytes of the description's VALUE
/// (docs/type-description.md: an enum's is the enumerator's name, an array's a list), the one
/// form in which parameter values cross every boundary (requests, recordings, links, viewers).
struct ParamDeclaration {
  /// [a-z_][a-z0-9_]*, at most 63 bytes, unique in the node.
  std::string name;
  /// A primitive, String, an enum of a generated schema, or a fixed array of primitives.
  TypeRef type;
  /// The type as the schema spells it ("f64", "[f32; 3]", "String", "my_robot.Mode").
  std::string spelling;
  /// The enum the type names (its description), when it is one.
  std::optional<EnumType> enumeration;
  std::string default_value;
  /// Inclusive bounds of a number (of each element of an array of numbers).
  std::optional<double> min;
  std::optional<double> max;
  /// The only values allowed, when not empty.
  std::vector<std::string> choices;
  std::string unit;
  std::string doc;
  bool read_only = false;
};

/// A parameter as a reader sees it.
struct ParamInfo {
  std::string node;
  ParamDeclaration declaration;
  /// The current value (MessagePack VALUE bytes).
  std::string value;
  /// 1 for the value the node started with, +1 for each accepted write.
  std::uint64_t version = 0;
};

/// A proposed change, as on_param_change() is offered it.
struct ParamChange {
  const ParamDeclaration* declaration = nullptr;
  /// The proposed value: MessagePack VALUE bytes (already checked against the declaration), and
  /// typed through as<T>().
  std::string value;
  /// Who asks: "horus param", "yaml:FILE", "remote:PEER", "view:PEER", "replay", a program name.
  std::string source;

  const std::string& name() const noexcept { return declaration->name; }
  /// The value as T (the parameter's own C++ type). Throws ParamError for another type.
  template <class T>
  T as() const;
};

/// The owner's answer to a change.
class ParamVerdict {
 public:
  static ParamVerdict accept() { return ParamVerdict(true, {}); }
  static ParamVerdict refuse(std::string reason) { return ParamVerdict(false, std::move(reason)); }
  bool accepted() const noexcept { return accepted_; }
  const std::string& reason() const noexcept { return reason_; }

 private:
  ParamVerdict(bool accepted, std::string reason)
      : accepted_(accepted), reason_(std::move(reason)) {}
  bool accepted_;
  std::string reason_;
};

/// What a write came to.
struct ParamSetResult {
  bool accepted = false;
  /// Why it was refused; empty when accepted.
  std::string reason;
  /// The parameter's version after the write (unchanged when refused).
  std::uint64_t version = 0;
};

/// How a parameter may be declared (Node::declare_param); T as the parameter's.
template <class T>
struct ParamOptions {
  /// Inclusive bounds of a number (of each element of an array of numbers).
  std::optional<double> min{};
  std::optional<double> max{};
  /// The only values allowed (numbers, strings, enums); empty: any.
  std::vector<T> choices{};
  std::string unit{};
  std::string doc{};
  /// Set only by its default, a parameter file or a persisted value at start, never while the
  /// node runs.
  bool read_only = false;
};

/// A parameter's value (MessagePack VALUE bytes) as JSON: numbers, true/false, strings (an
/// enumerator by its name), lists; a float keeps a fraction ("1.0"), NaN and infinities are
/// null. With its declaration, an f32 is written as the shortest text of the f32 ("0.1").
/// Throws ParamError for bytes that are no VALUE.
std::string param_value_json(std::string_view value, const ParamDeclaration* declaration = nullptr);

/// The declarations a store's type description carries (ParamStoreReader::description(), or a
/// copy of it from another machine), in declaration order. Throws ParamError when it holds none.
std::vector<ParamDeclaration> param_declarations_of(const TypeDescription& description);

/// The name of the HORUS service that carries writes to `node`'s owner (hidden from listings).
std::string param_service_name(std::string_view node);

/// The nodes of a namespace (empty: the current one) that have a parameter store, sorted.
std::vector<std::string> param_nodes(std::string_view namespace_name = {});

template <class T>
class Param;

namespace detail {
struct ParamSlot;
}  // namespace detail

/// One node's store, opened read-only by anyone: tools, other processes, bridges.
class ParamStoreReader {
 public:
  /// Throws ParamError naming the node and namespace when it has no store, horus::Error when the
  /// store cannot be trusted (owner, mode) or is malformed.
  explicit ParamStoreReader(std::string_view node, std::string_view namespace_name = {});
  ~ParamStoreReader();
  ParamStoreReader(ParamStoreReader&&) noexcept;
  ParamStoreReader& operator=(ParamStoreReader&&) noexcept;

  const std::string& node() const noexcept;
  /// The declarations as a type description (root: the node's parameter message).
  const TypeDescription& description() const noexcept;
  /// Every parameter with its current value, in declaration order.
  std::vector<ParamInfo> list() const;
  /// One parameter; throws ParamError (with the closest names) when the node has none of that name.
  ParamInfo get(std::string_view name) const;
  /// Whether the owner runs now, and its pid (0 when none ever ran or it ended).
  bool owner_alive() const noexcept;
  std::uint32_t owner_pid() const noexcept;
  /// Counts every accepted change of this node's parameters: pass the last value seen to
  /// wait_for_change(), which sleeps (a futex on the store, no polling) until it moves or the
  /// timeout passes; returns the new count.
  std::uint64_t change_count() const noexcept;
  std::uint64_t wait_for_change(std::uint64_t seen, std::chrono::nanoseconds timeout) const;
  /// A typed handle to one parameter for a process that reads it often: get() reads the store's
  /// record as the owner's own Param<T> does (one atomic load for a scalar), with no copy of the
  /// declaration and no MessagePack. T is the parameter's C++ type (as declare_param's); throws
  /// ParamError when the node has no parameter of that name or T is not its type. The handle
  /// keeps the store mapped; a node restarted with other declarations gets a new store, which a
  /// new reader opens.
  template <class T>
  Param<T> param(std::string_view name) const;

 private:
  /// The slot of parameter `name` of C++ type `cpp_type` (its enum's name for an enum), leading
  /// to the store's record.
  std::shared_ptr<const detail::ParamSlot> record_slot(std::string_view name,
                                                       const TypeRef& cpp_type) const;

  struct State;
  std::unique_ptr<State> state_;
};

/// Options of a write.
struct ParamSetOptions {
  /// Keep the value for the node's next start when the node does not run now (otherwise such a
  /// write is refused).
  bool persist = false;
  std::chrono::nanoseconds timeout = std::chrono::seconds(5);
  /// Who writes (ParamChange::source); empty: this program's name.
  std::string source;
  std::string namespace_name;
};

/// Writes one parameter through its owner. The value is MessagePack VALUE bytes; a refusal (by
/// the declaration, a value of another type included, by the owner or because it does not run)
/// is a result with the reason, not an exception; a node without a store or an unknown
/// parameter throws ParamError.
ParamSetResult set_param(std::string_view node, std::string_view name, std::string_view value,
                         const ParamSetOptions& options = {});

/// A parameter file: `node: {name: value, ...}` per node, YAML. load_param_file() checks every
/// value of the file against the nodes' declarations first (all errors: file:line: reason) and
/// then writes them through their owners; dump_param_file() writes the current values of the
/// given nodes (all with a store when empty) in declaration order.
std::vector<ParamSetResult> load_param_file(const std::filesystem::path& path,
                                            const ParamSetOptions& options = {});
std::string dump_param_file(const std::vector<std::string>& nodes = {},
                            std::string_view namespace_name = {});

/// A typed, lock-free handle to one of a node's parameters (see Node::declare_param and
/// ParamStoreReader::param). Before the node's scheduler opens its store the owner's handle reads
/// the default; after, the store's record.

namespace detail {

struct ParamRecord;

/// Where a declared parameter's value is, shared by its Param<T> handles and the node: its
/// default until the node's store is open, then the store's record (the mapping stays while
/// any handle does, through `mapping`).
struct ParamSlot {
  ParamDeclaration declaration;
  /// A scalar's bits (see param_word_of) as declared, read until the store opens.
  std::atomic<std::uint64_t> default_word{0};
  std::atomic<std::uint64_t> default_version{1};
  /// A string's or array's bytes as declared (see param_bytes_of).
  std::string default_bytes;
  /// The scalar word and version read by get(): the defaults above, then the record's.
  std::atomic<const std::atomic<std::uint64_t>*> word{&default_word};
  std::atomic<const std::atomic<std::uint64_t>*> version{&default_version};
  std::atomic<const ParamRecord*> record{nullptr};
  std::shared_ptr<const void> mapping;
};

/// A string's or an array's current bytes (lock-free, never torn).
std::string read_param_bytes(const ParamSlot& slot);

template <class T>
struct IsStdArray : std::false_type {};
template <class E, std::size_t N>
struct IsStdArray<std::array<E, N>> : std::true_type {};

template <class T>
inline constexpr bool kParamNumber =
    std::is_same_v<T, bool> || std::is_same_v<T, float> || std::is_same_v<T, double> ||
    std::is_same_v<T, std::int8_t> || std::is_same_v<T, std::int16_t> ||
    std::is_same_v<T, std::int32_t> || std::is_same_v<T, std::int64_t> ||
    std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint16_t> ||
    std::is_same_v<T, std::uint32_t> || std::is_same_v<T, std::uint64_t>;

/// Whether T is held as one atomic word (a number, bool or enum).
template <class T>
inline constexpr bool kParamScalar = kParamNumber<T> || SchemaEnum<T>;

template <class T>
constexpr Primitive param_primitive() {
  if constexpr (std::is_same_v<T, bool>)
    return Primitive::Bool;
  else if constexpr (std::is_same_v<T, std::uint8_t>)
    return Primitive::U8;
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return Primitive::U16;
  else if constexpr (std::is_same_v<T, std::uint32_t>)
    return Primitive::U32;
  else if constexpr (std::is_same_v<T, std::uint64_t>)
    return Primitive::U64;
  else if constexpr (std::is_same_v<T, std::int8_t>)
    return Primitive::I8;
  else if constexpr (std::is_same_v<T, std::int16_t>)
    return Primitive::I16;
  else if constexpr (std::is_same_v<T, std::int32_t>)
    return Primitive::I32;
  else if constexpr (std::is_same_v<T, std::int64_t>)
    return Primitive::I64;
  else if constexpr (std::is_same_v<T, float>)
    return Primitive::F32;
  else
    return Primitive::F64;
}

/// A scalar as the record's word: integers sign- or zero-extended, floats by their bits (f32 in
/// the low half), an enum by its value.
template <class T>
std::uint64_t param_word_of(T value) noexcept {
  if constexpr (std::is_same_v<T, float>) {
    return std::bit_cast<std::uint32_t>(value);
  } else if constexpr (std::is_same_v<T, double>) {
    return std::bit_cast<std::uint64_t>(value);
  } else if constexpr (std::is_same_v<T, bool>) {
    return value ? 1 : 0;
  } else if constexpr (SchemaEnum<T> || std::is_signed_v<T>) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(value));
  } else {
    return static_cast<std::uint64_t>(value);
  }
}

template <class T>
T param_from_word(std::uint64_t word) noexcept {
  if constexpr (SchemaEnum<T>) {
    return static_cast<T>(static_cast<std::int64_t>(word));
  } else if constexpr (std::is_same_v<T, float>) {
    return std::bit_cast<float>(static_cast<std::uint32_t>(word));
  } else if constexpr (std::is_same_v<T, double>) {
    return std::bit_cast<double>(word);
  } else if constexpr (std::is_same_v<T, bool>) {
    return word != 0;
  } else {
    return static_cast<T>(word);
  }
}

/// A string's or array's bytes as the record holds them: the text; the elements' native bytes.
template <class T>
std::string param_bytes_of(const T& value) {
  if constexpr (std::is_same_v<T, std::string>) {
    return value;
  } else {
    std::string bytes(sizeof(T), '\0');
    std::memcpy(bytes.data(), value.data(), sizeof(T));
    return bytes;
  }
}

template <class T>
T param_from_bytes(std::string_view bytes) {
  if constexpr (std::is_same_v<T, std::string>) {
    return std::string(bytes);
  } else {
    T value{};
    std::memcpy(value.data(), bytes.data(), std::min(bytes.size(), sizeof(T)));
    return value;
  }
}

/// The declared type of a C++ parameter type (its enum's description filled for an enum).
TypeRef param_type_ref(Primitive primitive);
TypeRef param_string_type_ref();
TypeRef param_array_type_ref(Primitive element, std::size_t length);
/// An enum's TypeRef and description, from its generated TypeInfo's description bytes.
std::pair<TypeRef, EnumType> param_enum_type(std::string_view description);

template <class T>
void describe_param_type(ParamDeclaration& declaration) {
  if constexpr (SchemaEnum<T>) {
    auto [type, enumeration] = param_enum_type(TypeInfo<T>::description);
    declaration.type = std::move(type);
    declaration.enumeration = std::move(enumeration);
  } else if constexpr (kParamNumber<T>) {
    declaration.type = param_type_ref(param_primitive<T>());
  } else if constexpr (std::is_same_v<T, std::string>) {
    declaration.type = param_string_type_ref();
  } else if constexpr (IsStdArray<T>::value && kParamNumber<typename T::value_type>) {
    declaration.type =
        param_array_type_ref(param_primitive<typename T::value_type>(), std::tuple_size_v<T>);
  } else {
    static_assert(kParamNumber<T>,
                  "a parameter is a number, bool, generated enum, std::string "
                  "or std::array of numbers or bools");
  }
}

/// MessagePack VALUE bytes of a scalar word / of a string's or array's bytes, as `declaration`
/// types them; and back (ParamError when the value is not of the declared type).
std::string encode_param_word(const ParamDeclaration& declaration, std::uint64_t word);
std::string encode_param_bytes(const ParamDeclaration& declaration, std::string_view bytes);
std::uint64_t decode_param_word(const ParamDeclaration& declaration, std::string_view value);
std::string decode_param_bytes(const ParamDeclaration& declaration, std::string_view value);
/// Throws ParamError unless T is the declared type.
void check_param_cpp_type(const ParamDeclaration& declaration, const TypeRef& cpp_type,
                          std::string_view cpp_enum);

template <class T>
std::string encode_param_value(const ParamDeclaration& declaration, const T& value) {
  if constexpr (kParamScalar<T>) {
    return encode_param_word(declaration, param_word_of(value));
  } else {
    return encode_param_bytes(declaration, param_bytes_of(value));
  }
}

}  // namespace detail

template <class T>
class Param {
 public:
  /// The current value: one atomic load for a scalar; a short double-buffered copy otherwise.
  T get() const {
    if constexpr (detail::kParamScalar<T>) {
      return detail::param_from_word<T>(
          slot_->word.load(std::memory_order_acquire)->load(std::memory_order_acquire));
    } else if constexpr (std::is_same_v<T, std::string>) {
      return detail::read_param_bytes(*slot_);
    } else {
      return detail::param_from_bytes<T>(detail::read_param_bytes(*slot_));
    }
  }
  std::uint64_t version() const noexcept {
    return slot_->version.load(std::memory_order_acquire)->load(std::memory_order_acquire);
  }
  const std::string& name() const noexcept { return slot_->declaration.name; }

 private:
  friend class Node;
  friend class ParamStoreReader;
  using Slot = detail::ParamSlot;
  explicit Param(std::shared_ptr<const Slot> slot) : slot_(std::move(slot)) {}
  std::shared_ptr<const Slot> slot_;
};

/// A parameter whose type is known only at run time (a language binding's node, the mirror of a
/// remote node; see Node::declare_param(ParamDeclaration)): its value as MessagePack VALUE bytes,
/// read as Param<T> reads, lock-free.
class ParamHandle {
 public:
  std::string value() const;
  std::uint64_t version() const noexcept {
    return slot_->version.load(std::memory_order_acquire)->load(std::memory_order_acquire);
  }
  const ParamDeclaration& declaration() const noexcept { return slot_->declaration; }

 private:
  friend class Node;
  explicit ParamHandle(std::shared_ptr<const detail::ParamSlot> slot) : slot_(std::move(slot)) {}
  std::shared_ptr<const detail::ParamSlot> slot_;
};

template <class T>
Param<T> ParamStoreReader::param(std::string_view name) const {
  ParamDeclaration expected;
  detail::describe_param_type<T>(expected);
  return Param<T>(record_slot(name, expected.type));
}

template <class T>
T ParamChange::as() const {
  ParamDeclaration expected;
  detail::describe_param_type<T>(expected);
  detail::check_param_cpp_type(*declaration, expected.type, expected.type.name);
  if constexpr (detail::kParamScalar<T>) {
    return detail::param_from_word<T>(detail::decode_param_word(*declaration, value));
  } else {
    return detail::param_from_bytes<T>(detail::decode_param_bytes(*declaration, value));
  }
}

}  // namespace horus
