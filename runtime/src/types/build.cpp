// build_message: a message written from values a MessageSource gives field by field, byte for
// byte what the generated C++ writes for the same values (horus::encode: the struct bytes of a
// POD message, the msgpack-cxx adaptors' MessagePack of a serialized one: each integer through the
// packer of its width, f32 as float 32, byte blocks as bin); zero_message / default_message are
// it with a source of zeros, or of the schema's defaults.
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <algorithm>
#include <cstring>
#include <functional>
#include <optional>

#include "horus/type_description.hpp"
#include "msgpack_input.hpp"

namespace horus {

namespace {

[[noreturn]] void bad_default(const std::string& what) {
  throw TypeDescriptionError("type description: default " + what);
}

/// The MessagePack tree of a field's stored default.
msgpack::object_handle default_tree(const MessageField& field) {
  return types::unpack_whole<TypeDescriptionError>(field.default_value.data(),
                                                   field.default_value.size(), field.name);
}

double number_of(const msgpack::object& value, std::string_view field) {
  switch (value.type) {
    case msgpack::type::FLOAT32:
    case msgpack::type::FLOAT64:
      return value.via.f64;
    case msgpack::type::POSITIVE_INTEGER:
      return static_cast<double>(value.via.u64);
    case msgpack::type::NEGATIVE_INTEGER:
      return static_cast<double>(value.via.i64);
    default:
      bad_default("of " + std::string(field) + " is not a number");
  }
}

/// An integer default as its 64 bits (what a cast to the field's width keeps).
std::uint64_t integer_of(const msgpack::object& value, std::string_view field) {
  if (value.type == msgpack::type::POSITIVE_INTEGER) return value.via.u64;
  if (value.type == msgpack::type::NEGATIVE_INTEGER)
    return static_cast<std::uint64_t>(value.via.i64);
  bad_default("of " + std::string(field) + " is not an integer");
}

/// An enum default: the enumerator's name, its value, or a map holding either.
std::int64_t enumerator_of(const EnumType& enumeration, const msgpack::object& value,
                           std::string_view field) {
  if (value.type == msgpack::type::MAP) {
    for (std::uint32_t i = 0; i < value.via.map.size; ++i) {
      const msgpack::object& key = value.via.map.ptr[i].key;
      const std::string_view name =
          key.type == msgpack::type::STR ? std::string_view(key.via.str.ptr, key.via.str.size) : "";
      if (name == "value") return enumerator_of(enumeration, value.via.map.ptr[i].val, field);
    }
    bad_default("of " + std::string(field) + " is a map without a \"value\"");
  }
  if (value.type == msgpack::type::STR) {
    std::string_view name(value.via.str.ptr, value.via.str.size);
    name = name.substr(name.rfind(':') == std::string_view::npos ? 0 : name.rfind(':') + 1);
    for (const Enumerator& enumerator : enumeration.values) {
      if (enumerator.name == name) return enumerator.value;
    }
    bad_default("of " + std::string(field) + ": " + std::string(name) +
                " is not an enumerator of " + enumeration.name);
  }
  return static_cast<std::int64_t>(integer_of(value, field));
}

std::string_view text_of(const msgpack::object& value, std::string_view field) {
  if (value.type != msgpack::type::STR)
    bad_default("of " + std::string(field) + " is not a string");
  return {value.via.str.ptr, value.via.str.size};
}

std::span<const msgpack::object> elements_of(const msgpack::object& value, std::size_t length,
                                             std::string_view field) {
  if (value.type != msgpack::type::ARRAY || value.via.array.size != length) {
    bad_default("of " + std::string(field) + " is not a list of " + std::to_string(length));
  }
  return {value.via.array.ptr, value.via.array.size};
}

/// `type` is one of `description`'s (what the writers index their tables by).
void check_is_of(const TypeDescription& description, const MessageType& type) {
  const std::less<const MessageType*> before;
  if (description.messages.empty() || before(&type, description.messages.data()) ||
      before(&description.messages.back(), &type)) {
    throw Error(type.name + " is not a message of the description it was given with");
  }
}

/// Writes one message from a source's answers: POD at the fields' offsets into zeroed bytes,
/// serialized through a msgpack packer.
class MessageBuilder {
 public:
  MessageBuilder(const TypeDescription& description, MessageSource& source)
      : description_(description), source_(source), packer_(buffer_) {}

  std::vector<std::uint8_t> build(const MessageType& type) {
    if (type.is_pod) {
      pod_.assign(type.size, 0);
      pod_message(type, 0);
      return std::move(pod_);
    }
    std::vector<std::optional<std::size_t>> smallest(description_.messages.size());
    if (smallest_message(type, smallest) > kMaxMessageBytes) {
      throw TypeDescriptionError("type description: a " + type.name + " takes more than " +
                                 std::to_string(kMaxMessageBytes) + " bytes");
    }
    packed_message(type);
    const auto* data = reinterpret_cast<const std::uint8_t*>(buffer_.data());
    return std::vector<std::uint8_t>(data, data + buffer_.size());
  }

 private:
  [[noreturn]] void refuse(const std::string& what) const {
    throw Error("building a message: " +
                (field_ != nullptr ? "field " + field_->name + ": " : std::string()) + what);
  }

  /// `bits` (a signed value's two's complement when `is_signed`) inside `primitive`'s range.
  void check_range(Primitive primitive, std::uint64_t bits, bool is_signed) const {
    const std::size_t width = 8 * primitive_size(primitive);
    const bool signed_type = primitive == Primitive::I8 || primitive == Primitive::I16 ||
                             primitive == Primitive::I32 || primitive == Primitive::I64;
    bool fits = true;
    if (width < 64) {
      if (signed_type) {
        const auto value = static_cast<std::int64_t>(bits);
        const std::int64_t limit = std::int64_t{1} << (width - 1);
        fits = is_signed ? value >= -limit && value < limit : bits < std::uint64_t(limit);
      } else {
        fits = !(is_signed && static_cast<std::int64_t>(bits) < 0) &&
               bits < (std::uint64_t{1} << width);
      }
    } else if (signed_type != is_signed) {
      fits = static_cast<std::int64_t>(bits) >= 0;  // the half both readings share
    }
    if (!fits) {
      refuse((is_signed ? std::to_string(static_cast<std::int64_t>(bits)) : std::to_string(bits)) +
             " is out of range for " + std::string(primitive_name(primitive)));
    }
  }

  /// The next integer of `type` (a primitive, or an enum's underlying type) as its 64 bits.
  std::uint64_t integer(const TypeRef& type) {
    if (type.kind == TypeRef::Kind::Enum) {
      const EnumType& enumeration = description_.enumeration(type);
      const auto value = static_cast<std::uint64_t>(source_.enumerator(enumeration));
      // An enum over u64 holds values past i64's as their bits.
      check_range(enumeration.underlying, value, enumeration.underlying != Primitive::U64);
      return value;
    }
    if (type.primitive == Primitive::U8 || type.primitive == Primitive::U16 ||
        type.primitive == Primitive::U32 || type.primitive == Primitive::U64) {
      const std::uint64_t value = source_.unsigned_integer(type);
      check_range(type.primitive, value, false);
      return value;
    }
    const auto value = static_cast<std::uint64_t>(source_.signed_integer(type));
    check_range(type.primitive, value, true);
    return value;
  }

  Primitive integer_primitive(const TypeRef& type) const {
    return type.kind == TypeRef::Kind::Enum ? description_.enumeration(type).underlying
                                            : type.primitive;
  }

  std::string_view fixed_or_dynamic_string(const TypeRef& type) {
    const std::string_view text = source_.string(type);
    if (type.kind == TypeRef::Kind::FixedString && text.size() > type.length) {
      refuse("a string of " + std::to_string(text.size()) + " bytes does not fit string<" +
             std::to_string(type.length) + ">");
    }
    return text;
  }

  std::span<const std::uint8_t> byte_block(const TypeRef& type) {
    const std::span<const std::uint8_t> data = source_.bytes(type);
    if (type.kind == TypeRef::Kind::Array && data.size() != type.length) {
      refuse(std::to_string(data.size()) + " bytes for [u8; " + std::to_string(type.length) + "]");
    }
    return data;
  }

  std::size_t sequence(const TypeRef& type) {
    const std::size_t count = source_.begin_sequence(type);
    if (type.kind == TypeRef::Kind::Array && count != type.length) {
      refuse(std::to_string(count) + " elements for an array of " + std::to_string(type.length));
    }
    return count;
  }

  // -- POD: values at the fields' offsets ---------------------------------------------------------

  void pod_message(const MessageType& type, std::size_t at) {
    source_.begin_message(type);
    for (const MessageField& field : type.fields) {
      field_ = &field;
      if (!field.offset || !field.size) refuse("has no place in its POD message");
      source_.field(field);
      pod_value(field.type, at + *field.offset, *field.size);
    }
    source_.end_message(type);
  }

  /// Where `size` bytes at `at` go; decode()'s layout checks make the bound hold, this keeps a
  /// description built by hand (not decoded) from writing past the message.
  std::uint8_t* span_at(std::size_t at, std::size_t size) {
    if (at > pod_.size() || size > pod_.size() - at) {
      refuse("lies past its POD message's " + std::to_string(pod_.size()) + " bytes");
    }
    return pod_.data() + at;
  }

  template <class T>
  void put(std::size_t at, T value) {
    std::memcpy(span_at(at, sizeof(T)), &value, sizeof(T));
  }

  void pod_integer(Primitive primitive, std::uint64_t bits, std::size_t at) {
    switch (primitive_size(primitive)) {
      case 1:
        put(at, static_cast<std::uint8_t>(bits));
        return;
      case 2:
        put(at, static_cast<std::uint16_t>(bits));
        return;
      case 4:
        put(at, static_cast<std::uint32_t>(bits));
        return;
      default:
        put(at, bits);
    }
  }

  /// A value of `size` bytes at `at` (an array's elements take equal shares of its bytes).
  void pod_value(const TypeRef& type, std::size_t at, std::size_t size) {
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        if (type.primitive == Primitive::Bool) {
          put(at, static_cast<std::uint8_t>(source_.boolean() ? 1 : 0));
        } else if (type.primitive == Primitive::F32) {
          put(at, static_cast<float>(source_.floating(type)));
        } else if (type.primitive == Primitive::F64) {
          put(at, source_.floating(type));
        } else {
          pod_integer(type.primitive, integer(type), at);
        }
        return;
      case TypeRef::Kind::FixedString: {
        const std::string_view text = fixed_or_dynamic_string(type);
        std::uint8_t* place = span_at(at, type.length);
        if (!text.empty()) std::memcpy(place, text.data(), text.size());
        return;
      }
      case TypeRef::Kind::Array: {
        if (type.is_byte_block()) {
          const std::span<const std::uint8_t> data = byte_block(type);
          std::uint8_t* place = span_at(at, type.length);
          if (!data.empty()) std::memcpy(place, data.data(), data.size());
          return;
        }
        span_at(at, size);
        sequence(type);
        const std::size_t stride = type.length == 0 ? 0 : size / type.length;
        for (std::size_t i = 0; i < type.length; ++i) {
          pod_value(*type.element, at + i * stride, stride);
        }
        source_.end_sequence(type);
        return;
      }
      case TypeRef::Kind::Message: {
        const MessageField* outer = field_;
        pod_message(description_.message(type), at);
        field_ = outer;
        return;
      }
      case TypeRef::Kind::Enum:
        pod_integer(integer_primitive(type), integer(type), at);
        return;
      default:
        refuse("a string, bytes, a Vec or an option in a POD message");
    }
  }

  // -- Serialized: MessagePack --------------------------------------------------------------------

  /// The fewest bytes a `type` value takes, at most kMaxMessageBytes + 1: checked before writing
  /// anything, so a description whose arrays multiply up to terabytes is refused at once.
  /// `smallest`: each message's, once computed (types may share a message many times over).
  std::size_t smallest_value(const TypeRef& type,
                             std::vector<std::optional<std::size_t>>& smallest) const {
    constexpr std::size_t kTooLarge = kMaxMessageBytes + 1;
    switch (type.kind) {
      case TypeRef::Kind::Array: {
        const std::size_t element =
            type.is_byte_block() ? 1 : smallest_value(*type.element, smallest);
        if (element != 0 && type.length > kTooLarge / element) return kTooLarge;
        return std::min(kTooLarge, 5 + type.length * element);
      }
      case TypeRef::Kind::Message:
        return smallest_message(description_.message(type), smallest);
      default:
        return 1;
    }
  }

  std::size_t smallest_message(const MessageType& type,
                               std::vector<std::optional<std::size_t>>& smallest) const {
    std::optional<std::size_t>& known =
        smallest[static_cast<std::size_t>(&type - description_.messages.data())];
    if (!known) {
      std::size_t total = 1;
      for (const MessageField& field : type.fields) {
        total = std::min(kMaxMessageBytes + 1, total + smallest_value(field.type, smallest));
      }
      known = total;
    }
    return *known;
  }

  /// Refuses a message of more than kMaxMessageBytes before writing `count` more values (each
  /// takes a byte at least): neither a hostile description's array lengths nor a source's counts
  /// can exhaust memory.
  void reserve(std::size_t count) {
    if (count > kMaxMessageBytes - std::min(buffer_.size(), kMaxMessageBytes)) {
      throw TypeDescriptionError("type description: a message of more than " +
                                 std::to_string(kMaxMessageBytes) + " bytes");
    }
  }

  void packed_message(const MessageType& type) {
    reserve(type.fields.size());
    source_.begin_message(type);
    packer_.pack_array(static_cast<std::uint32_t>(type.fields.size()));
    for (const MessageField& field : type.fields) {
      field_ = &field;
      source_.field(field);
      packed_value(field.type);
    }
    source_.end_message(type);
  }

  void packed_integer(Primitive primitive, std::uint64_t bits) {
    switch (primitive) {
      case Primitive::U8:
        packer_.pack_uint8(static_cast<std::uint8_t>(bits));
        return;
      case Primitive::U16:
        packer_.pack_uint16(static_cast<std::uint16_t>(bits));
        return;
      case Primitive::U32:
        packer_.pack_uint32(static_cast<std::uint32_t>(bits));
        return;
      case Primitive::U64:
        packer_.pack_uint64(bits);
        return;
      case Primitive::I8:
        packer_.pack_int8(static_cast<std::int8_t>(bits));
        return;
      case Primitive::I16:
        packer_.pack_int16(static_cast<std::int16_t>(bits));
        return;
      case Primitive::I32:
        packer_.pack_int32(static_cast<std::int32_t>(bits));
        return;
      default:
        packer_.pack_int64(static_cast<std::int64_t>(bits));
    }
  }

  void packed_value(const TypeRef& type) {
    reserve(1);
    if (type.is_byte_block()) {
      const std::span<const std::uint8_t> data = byte_block(type);
      reserve(data.size());
      packer_.pack_bin(static_cast<std::uint32_t>(data.size()));
      // An empty block may have no data pointer, which memcpy must not be given.
      if (!data.empty()) {
        packer_.pack_bin_body(reinterpret_cast<const char*>(data.data()),
                              static_cast<std::uint32_t>(data.size()));
      }
      return;
    }
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        if (type.primitive == Primitive::Bool) {
          source_.boolean() ? packer_.pack_true() : packer_.pack_false();
        } else if (type.primitive == Primitive::F32) {
          packer_.pack_float(static_cast<float>(source_.floating(type)));
        } else if (type.primitive == Primitive::F64) {
          packer_.pack_double(source_.floating(type));
        } else {
          packed_integer(type.primitive, integer(type));
        }
        return;
      case TypeRef::Kind::FixedString:
      case TypeRef::Kind::String: {
        const std::string_view text = fixed_or_dynamic_string(type);
        reserve(text.size());
        packer_.pack_str(static_cast<std::uint32_t>(text.size()));
        if (!text.empty()) {
          packer_.pack_str_body(text.data(), static_cast<std::uint32_t>(text.size()));
        }
        return;
      }
      case TypeRef::Kind::Array:
      case TypeRef::Kind::Vec: {
        const std::size_t count = sequence(type);
        reserve(count);
        packer_.pack_array(static_cast<std::uint32_t>(count));
        for (std::size_t i = 0; i < count; ++i) packed_value(*type.element);
        source_.end_sequence(type);
        return;
      }
      case TypeRef::Kind::Optional:
        if (source_.begin_optional(type)) {
          packed_value(*type.element);
        } else {
          packer_.pack_nil();
        }
        source_.end_optional(type);
        return;
      case TypeRef::Kind::Message: {
        // A POD message inside a serialized one is an array of its fields too.
        const MessageField* outer = field_;
        packed_message(description_.message(type));
        field_ = outer;
        return;
      }
      case TypeRef::Kind::Enum:
        packed_integer(integer_primitive(type), integer(type));
        return;
      case TypeRef::Kind::Bytes:
        return;  // a byte block: written above
    }
  }

  const TypeDescription& description_;
  MessageSource& source_;
  /// The field being written, for errors.
  const MessageField* field_ = nullptr;
  std::vector<std::uint8_t> pod_;
  msgpack::sbuffer buffer_;
  msgpack::packer<msgpack::sbuffer> packer_;
};

/// Every number 0, bools false, strings, Vecs and bytes empty, options none, arrays full.
class ZeroSource : public MessageSource {
 public:
  void begin_message(const MessageType&) override {}
  void end_message(const MessageType&) override {}
  void field(const MessageField&) override {}
  bool boolean() override { return false; }
  std::uint64_t unsigned_integer(const TypeRef&) override { return 0; }
  std::int64_t signed_integer(const TypeRef&) override { return 0; }
  double floating(const TypeRef&) override { return 0.0; }
  std::int64_t enumerator(const EnumType&) override { return 0; }
  std::string_view string(const TypeRef&) override { return {}; }
  std::span<const std::uint8_t> bytes(const TypeRef& type) override {
    const std::size_t length = type.kind == TypeRef::Kind::Array ? type.length : 0;
    if (zeros_.size() < length) zeros_.resize(length, 0);
    return {zeros_.data(), length};
  }
  std::size_t begin_sequence(const TypeRef& type) override {
    return type.kind == TypeRef::Kind::Array ? type.length : 0;
  }
  void end_sequence(const TypeRef&) override {}
  bool begin_optional(const TypeRef&) override { return false; }
  void end_optional(const TypeRef&) override {}

 private:
  std::vector<std::uint8_t> zeros_;
};

/// The schema's defaults where a field has one (its MessagePack VALUE, element by element for
/// an array), zeros elsewhere: what `T{}` holds.
class DefaultSource final : public ZeroSource {
 public:
  void begin_message(const MessageType&) override {
    if (tree_) refuse(": its type takes no default");
  }
  // The message's last field's default is spent: the next value is the enclosing one's.
  void end_message(const MessageType&) override { tree_.reset(); }

  void field(const MessageField& field) override {
    field_ = &field;
    cursors_.clear();
    tree_.reset();
    if (!field.default_value.empty()) tree_ = default_tree(field);
  }

  bool boolean() override {
    const msgpack::object* value = next();
    if (value == nullptr) return false;
    if (value->type != msgpack::type::BOOLEAN) refuse(" is not a bool");
    return value->via.boolean;
  }

  std::uint64_t unsigned_integer(const TypeRef&) override {
    const msgpack::object* value = next();
    return value == nullptr ? 0 : integer_of(*value, field_->name);
  }

  std::int64_t signed_integer(const TypeRef&) override {
    const msgpack::object* value = next();
    return value == nullptr ? 0 : static_cast<std::int64_t>(integer_of(*value, field_->name));
  }

  double floating(const TypeRef&) override {
    const msgpack::object* value = next();
    return value == nullptr ? 0.0 : number_of(*value, field_->name);
  }

  std::int64_t enumerator(const EnumType& type) override {
    const msgpack::object* value = next();
    return value == nullptr ? 0 : enumerator_of(type, *value, field_->name);
  }

  std::string_view string(const TypeRef& type) override {
    const msgpack::object* value = next();
    if (value == nullptr) return {};
    const std::string_view text = text_of(*value, field_->name);
    if (type.kind == TypeRef::Kind::FixedString && text.size() > type.length) {
      refuse(" does not fit string<" + std::to_string(type.length) + ">");
    }
    return text;
  }

  std::span<const std::uint8_t> bytes(const TypeRef& type) override {
    if (!tree_) return ZeroSource::bytes(type);
    if (type.kind != TypeRef::Kind::Array) refuse(": its type takes no default");
    block_.clear();
    for (const msgpack::object& element : elements_of(*next(), type.length, field_->name)) {
      block_.push_back(static_cast<std::uint8_t>(integer_of(element, field_->name)));
    }
    return block_;
  }

  std::size_t begin_sequence(const TypeRef& type) override {
    if (!tree_) return ZeroSource::begin_sequence(type);
    if (type.kind != TypeRef::Kind::Array) refuse(": its type takes no default");
    cursors_.push_back({elements_of(*next(), type.length, field_->name), 0});
    return type.length;
  }

  void end_sequence(const TypeRef&) override {
    if (!cursors_.empty()) cursors_.pop_back();
  }

  bool begin_optional(const TypeRef&) override {
    if (tree_) refuse(": its type takes no default");
    return false;
  }

 private:
  /// `what` follows the field's name: " is not a bool", ": its type takes no default".
  [[noreturn]] void refuse(const std::string& what) const {
    bad_default("of " + field_->name + what);
  }

  /// The default's next value (the whole default, or the innermost array's next element), or
  /// nullptr when the field has none.
  const msgpack::object* next() {
    if (!tree_) return nullptr;
    if (cursors_.empty()) return &tree_->get();
    Cursor& cursor = cursors_.back();
    return &cursor.elements[cursor.next++];
  }

  struct Cursor {
    std::span<const msgpack::object> elements;
    std::size_t next = 0;
  };

  const MessageField* field_ = nullptr;
  std::optional<msgpack::object_handle> tree_;
  std::vector<Cursor> cursors_;
  std::vector<std::uint8_t> block_;
};

}  // namespace

std::vector<std::uint8_t> build_message(const TypeDescription& description, const MessageType& type,
                                        MessageSource& source) {
  check_is_of(description, type);
  return MessageBuilder(description, source).build(type);
}

std::vector<std::uint8_t> zero_message(const TypeDescription& description,
                                       const MessageType& type) {
  ZeroSource zeros;
  return build_message(description, type, zeros);
}

std::vector<std::uint8_t> default_message(const TypeDescription& description,
                                          const MessageType& type) {
  DefaultSource defaults;
  return build_message(description, type, defaults);
}

}  // namespace horus
