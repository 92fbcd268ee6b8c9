// horus::TypeDescription: the versioned type description (docs/type-description.md) read from
// its MessagePack bytes (`TypeInfo<T>::description`, a topic segment, a link), and what consumers
// do with a message of a type they were not compiled with: walk its fields, print it as JSON,
// write one from values asked for field by field (build_message: every field zero, at its
// default, or read from a viewer's JSON); and the tree written back as those bytes
// (encode(), what the runtime describes its own types with: service frames). The one C++ reader
// and writer of the format: no C++ consumer parses schema text.
//
// The bytes come from other users' segments and from the network: decode() checks everything
// (format, version, every name resolving, no cycles, POD fields inside their message, counts and
// sizes capped) and refuses bad input with a TypeDescriptionError; walking a message refuses bad
// message bytes with a DecodeError. Neither crashes nor allocates beyond a fixed multiple of the
// input on hostile bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "horus/error.hpp"
#include "horus/type_info.hpp"

namespace horus {

/// Bytes that are not a type description this reader understands, saying what is wrong where
/// (e.g. "types[2].fields[0].type: names message horus.msg.Nope, which is not in types").
class TypeDescriptionError : public Error {
 public:
  using Error::Error;
};

/// The description's "format" and the highest "version" this reader understands.
inline constexpr std::string_view kTypeDescriptionFormat = "horus.typedesc";
inline constexpr std::int64_t kTypeDescriptionVersion = 1;

/// Limits on what decode() accepts, so hostile bytes cannot make it (or what is built from the
/// description) allocate without bound. Far above anything a schema declares.
inline constexpr std::size_t kMaxDescriptionBytes = std::size_t{16} << 20;
inline constexpr std::size_t kMaxMessageBytes = std::size_t{256} << 20;
inline constexpr std::size_t kMaxTypeNesting = 64;

enum class Primitive : std::uint8_t { Bool, U8, U16, U32, U64, I8, I16, I32, I64, F32, F64 };

/// "bool", "u8", ... "f64".
std::string_view primitive_name(Primitive primitive) noexcept;
/// The primitive spelled `name` ("bool", "u8", ... "f64"); none for any other text.
std::optional<Primitive> primitive_named(std::string_view name) noexcept;
/// Bytes of the primitive in a POD message (bool: 1).
std::size_t primitive_size(Primitive primitive) noexcept;

/// The type of a field, a constant, or an element: TYPE of the format.
struct TypeRef {
  enum class Kind : std::uint8_t {
    Primitive,    // `primitive`
    FixedString,  // string<length>: NUL-padded bytes in POD, a str in MessagePack
    String,       // dynamic String
    Bytes,        // bytes: a bin
    Array,        // [element; length]
    Vec,          // Vec<element>
    Optional,     // Option<element>
    Message,      // `name`, TypeDescription::messages[index]
    Enum,         // `name`, TypeDescription::enums[index]
  };
  Kind kind = Kind::Primitive;
  Primitive primitive = Primitive::Bool;
  std::size_t length = 0;
  std::string name;
  std::size_t index = 0;
  std::shared_ptr<const TypeRef> element;

  /// True for the types written as one MessagePack bin (bytes, Vec<u8>, [u8; N]).
  bool is_byte_block() const noexcept;
};

struct MessageField {
  std::string name;
  TypeRef type;
  /// POD messages only: where the field is in the struct and its bytes.
  std::optional<std::size_t> offset;
  std::optional<std::size_t> size;
  /// The schema's default as MessagePack bytes of the description's VALUE; empty for none.
  std::string default_value;
  std::string unit;
  /// The type as the schema spells it ("[f32; 3]"), for display.
  std::string spelling;
  /// Declaration keys (a parameter's, horus/params.hpp), each written and read only when present,
  /// so descriptions without them keep their bytes. "doc": the doc comment.
  std::optional<std::string> doc;
  /// "range": [min | null, max | null], inclusive bounds of a number (of each element).
  struct Range {
    std::optional<double> min;
    std::optional<double> max;
  };
  std::optional<Range> range;
  /// "choices": the only values allowed, each MessagePack bytes of a VALUE.
  std::optional<std::vector<std::string>> choices;
  /// "read_only": not writable while the node runs.
  std::optional<bool> read_only;
};

struct MessageConstant {
  std::string name;
  TypeRef type;
  /// MessagePack bytes of the description's VALUE.
  std::string value;
  std::string spelling;
};

struct MessageType {
  std::string name;
  std::string package;
  std::uint64_t fingerprint = 0;
  bool is_pod = false;
  /// POD only (0 for serialized messages).
  std::size_t size = 0;
  std::size_t alignment = 0;
  std::vector<MessageField> fields;
  std::vector<MessageConstant> constants;
  std::vector<PaddingRange> padding;
  /// The #[summary] line: MessagePack bytes of the description's list of PARTs, kept as they
  /// came (empty: none).
  std::string summary;
  std::optional<std::string> topic;
  std::string schema;

  /// The field called `field_name`, or nullptr.
  const MessageField* find_field(std::string_view field_name) const noexcept;
};

struct Enumerator {
  std::string name;
  std::int64_t value = 0;
};

struct EnumType {
  std::string name;
  std::string package;
  std::uint64_t fingerprint = 0;
  Primitive underlying = Primitive::I32;
  std::vector<Enumerator> values;
  std::string schema;

  /// The enumerator whose value is `value`, or nullptr (a value outside the enum).
  const Enumerator* find_value(std::int64_t value) const noexcept;
};

struct ServiceType {
  std::string name;
  std::string package;
  std::uint64_t fingerprint = 0;
  std::string request;
  std::string response;
  std::string request_topic;
  std::string response_topic;
};

/// One decoded description: the carried form (one root type and every type it uses) or the
/// describe form (every type of the inputs, no root).
struct TypeDescription {
  std::int64_t version = 0;
  /// "pkg.Name" of the type the description is for; empty in the describe form.
  std::string root;
  /// In the order of "types" (dependencies before users in the carried form).
  std::vector<MessageType> messages;
  std::vector<EnumType> enums;
  std::vector<ServiceType> services;

  /// Reads the MessagePack bytes; throws TypeDescriptionError saying what is wrong and where.
  static TypeDescription decode(std::span<const std::uint8_t> bytes);
  static TypeDescription decode(std::string_view bytes);
  /// The tree as MessagePack bytes of this reader's version, keys in the format's order, each
  /// value in its smallest form: for a description horus-gen wrote, its bytes exactly. The
  /// carried form's types are written as horus-gen orders them (depth first from the root, each
  /// after the types it uses), then any the root does not use; the describe form's as messages,
  /// enums, services. Throws TypeDescriptionError when the root, or a type it uses, is not in
  /// its types.
  std::string encode() const;

  const MessageType* find_message(std::string_view type_name) const noexcept;
  const EnumType* find_enum(std::string_view type_name) const noexcept;
  const ServiceType* find_service(std::string_view type_name) const noexcept;
  /// The message called `type_name`; throws TypeDescriptionError when there is none.
  const MessageType& message(std::string_view type_name) const;
  /// The root message; throws TypeDescriptionError when the root is not a message (or absent).
  const MessageType& root_message() const;
  /// The message or enum a TypeRef of kind Message / Enum names.
  const MessageType& message(const TypeRef& type) const noexcept { return messages[type.index]; }
  const EnumType& enumeration(const TypeRef& type) const noexcept { return enums[type.index]; }
};

/// What walk_message() reports, in field order, depth first. Every value arrives with the TypeRef
/// it was declared with, so a CDR encoder or a JSON printer needs no schema of its own.
class MessageVisitor {
 public:
  virtual ~MessageVisitor() = default;
  /// A message (the walked one, or a field's / element's); its fields follow, then end_message.
  virtual void begin_message(const MessageType& type) = 0;
  virtual void end_message(const MessageType& type) = 0;
  /// Before each field's value.
  virtual void field(const MessageField& field) = 0;
  /// Primitive values: integers of any width as 64 bits (their TypeRef says which width).
  virtual void boolean(bool value) = 0;
  virtual void unsigned_integer(const TypeRef& type, std::uint64_t value) = 0;
  virtual void signed_integer(const TypeRef& type, std::int64_t value) = 0;
  virtual void floating(const TypeRef& type, double value) = 0;
  virtual void enumerator(const EnumType& type, std::int64_t value) = 0;
  /// string<N> (the text up to its first NUL) and String.
  virtual void string(const TypeRef& type, std::string_view text) = 0;
  /// bytes, Vec<u8> and [u8; N]: the whole block at once, never element by element.
  virtual void bytes(const TypeRef& type, std::span<const std::uint8_t> data) = 0;
  /// Other arrays and Vecs: `count` elements follow, then end_sequence.
  virtual void begin_sequence(const TypeRef& type, std::size_t count) = 0;
  virtual void end_sequence(const TypeRef& type) = 0;
  /// Option<T>: the element follows when `present`, then end_optional.
  virtual void begin_optional(const TypeRef& type, bool present) = 0;
  virtual void end_optional(const TypeRef& type) = 0;
};

/// Visits one encoded message of `type`: POD bytes (exactly type.size of them) through the
/// fields' offsets, a serialized message through its MessagePack encoding (horus/msgpack.hpp:
/// arrays of fields, enums as integers, byte blocks as bin). Throws DecodeError when the bytes
/// are not such a message: before any visitor call when they are not one whole MessagePack value
/// (or not type.size bytes of POD), at the value when one has the wrong type or range (the
/// visitor has then seen the values before it, so a consumer drops what it wrote).
void walk_message(const TypeDescription& description, const MessageType& type,
                  std::span<const std::uint8_t> bytes, MessageVisitor& visitor);

/// What build_message() asks for, in the order walk_message() reports it (field order, depth
/// first): the inverse of a MessageVisitor, each question with the TypeRef the value is declared
/// with. A source that cannot answer (a value of the wrong kind, say) throws an exception of its
/// own, which build_message lets through; what it answers must fit the type, or build_message
/// throws Error naming the field.
class MessageSource {
 public:
  virtual ~MessageSource() = default;
  /// A message (the built one, or a field's / element's); its fields follow, then end_message.
  virtual void begin_message(const MessageType& type) = 0;
  virtual void end_message(const MessageType& type) = 0;
  /// Before each field's value.
  virtual void field(const MessageField& field) = 0;
  virtual bool boolean() = 0;
  /// Integers of any width as 64 bits, inside the range of the TypeRef's primitive.
  virtual std::uint64_t unsigned_integer(const TypeRef& type) = 0;
  virtual std::int64_t signed_integer(const TypeRef& type) = 0;
  /// f32 and f64 (an f32 is written as the double cast to float).
  virtual double floating(const TypeRef& type) = 0;
  /// Any value of the enum's underlying type, an enumerator's or not.
  virtual std::int64_t enumerator(const EnumType& type) = 0;
  /// string<N> (at most N bytes) and String; the text need only outlive the next call.
  virtual std::string_view string(const TypeRef& type) = 0;
  /// bytes, Vec<u8> and [u8; N] (exactly N): the whole block at once; the bytes need only
  /// outlive the next call.
  virtual std::span<const std::uint8_t> bytes(const TypeRef& type) = 0;
  /// Other arrays (their length exactly) and Vecs: how many elements follow, then end_sequence.
  virtual std::size_t begin_sequence(const TypeRef& type) = 0;
  virtual void end_sequence(const TypeRef& type) = 0;
  /// Option<T>: whether the element follows, then end_optional.
  virtual bool begin_optional(const TypeRef& type) = 0;
  virtual void end_optional(const TypeRef& type) = 0;
};

/// Writes one `type` message (one of `description.messages`) from the values `source` gives,
/// byte for byte what the generated code encodes for them (horus::encode): the struct bytes of a
/// POD message (padding zero), or the msgpack-cxx adaptors' MessagePack of a serialized one
/// (each integer through the packer of its width, f32 as float 32, byte blocks as bin, none as
/// nil). Replaying a walk_message() of some bytes gives those bytes back. Throws Error naming
/// the field when an answer does not fit its type, TypeDescriptionError when the message would
/// take more than kMaxMessageBytes.
std::vector<std::uint8_t> build_message(const TypeDescription& description, const MessageType& type,
                                        MessageSource& source);

/// The encoding of a `type` message (one of `description.messages`) whose numbers are 0, bools
/// false, strings, Vecs and bytes empty, options none, enums 0, arrays full of such elements: POD
/// bytes all zero, or the MessagePack bytes C++'s and Python's decoders read back.
std::vector<std::uint8_t> zero_message(const TypeDescription& description, const MessageType& type);
/// The same with every field that has a schema default at that default (what `T{}` encodes to).
std::vector<std::uint8_t> default_message(const TypeDescription& description,
                                          const MessageType& type);

/// One encoded `type` message as JSON text: an object of its fields in order; enums as their
/// enumerator's name (the number when outside the enum), byte blocks as arrays of numbers,
/// non-finite floats as null, none as null. Throws DecodeError as walk_message does.
std::string to_json(const TypeDescription& description, const MessageType& type,
                    std::span<const std::uint8_t> bytes);

}  // namespace horus
