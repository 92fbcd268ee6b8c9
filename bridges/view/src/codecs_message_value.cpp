// A message as a JSON value (a MessageVisitor over walk_message) and a JSON value back into a
// frame (a MessageSource for build_message): the runtime's type-description library does the
// reading and the writing, these only map its values to JSON and back.
#include <charconv>
#include <cmath>
#include <limits>

#include "codecs_internal.hpp"

namespace horus::view::detail {

// -- a message as a value -------------------------------------------------------------------------

namespace {

/// Builds the value of a walked message: each value lands in the innermost open container.
class ValueBuilder final : public MessageVisitor {
 public:
  explicit ValueBuilder(bool wide_integers_as_strings)
      : wide_integers_as_strings_(wide_integers_as_strings) {}

  JsonValue take() { return std::move(root_); }

  void begin_message(const MessageType&) override { open(JsonValue::object()); }
  void end_message(const MessageType&) override { close(); }
  void field(const MessageField& field) override { key_ = field.name; }
  void boolean(bool value) override { add(JsonValue::of_bool(value)); }

  void unsigned_integer(const TypeRef& type, std::uint64_t value) override {
    add(wide(type) ? JsonValue::of_string(std::to_string(value)) : JsonValue::of_unsigned(value));
  }

  void signed_integer(const TypeRef& type, std::int64_t value) override {
    add(wide(type) ? JsonValue::of_string(std::to_string(value)) : JsonValue::of_signed(value));
  }

  void floating(const TypeRef& type, double value) override {
    add(JsonValue::of_float(value, type.primitive == Primitive::F32));
  }

  void enumerator(const EnumType& type, std::int64_t value) override {
    const Enumerator* named = type.find_value(value);
    add(named != nullptr ? JsonValue::of_string(named->name) : JsonValue::of_signed(value));
  }

  void string(const TypeRef&, std::string_view text) override {
    add(JsonValue::of_string(std::string(text)));
  }

  void bytes(const TypeRef& type, std::span<const std::uint8_t> data) override {
    JsonValue value = JsonValue::of_bytes(data);
    // lang/jsonschema.py: bytes and Vec<u8> are base64, [u8; N] an array like any other.
    value.bytes_as_numbers = type.kind == TypeRef::Kind::Array;
    add(std::move(value));
  }

  void begin_sequence(const TypeRef&, std::size_t count) override {
    open(JsonValue::array());
    open_.back()->items.reserve(count);
  }
  void end_sequence(const TypeRef&) override { close(); }
  void begin_optional(const TypeRef&, bool present) override {
    if (!present) add(JsonValue::null());
  }
  void end_optional(const TypeRef&) override {}

 private:
  bool wide(const TypeRef& type) const {
    return wide_integers_as_strings_ &&
           (type.primitive == Primitive::U64 || type.primitive == Primitive::I64);
  }

  /// Where the next value goes: the root, the open object under the last field's name, or the
  /// open array's end.
  JsonValue& slot() {
    if (open_.empty()) return root_;
    JsonValue& container = *open_.back();
    if (container.kind == JsonValue::Kind::Array) {
      container.items.emplace_back();
      return container.items.back();
    }
    container.members.push_back({std::move(key_), JsonValue{}});
    return container.members.back().value;
  }

  void add(JsonValue value) { slot() = std::move(value); }

  void open(JsonValue container) {
    JsonValue& placed = slot();
    placed = std::move(container);
    open_.push_back(&placed);
  }

  void close() { open_.pop_back(); }

  bool wide_integers_as_strings_;
  JsonValue root_;
  std::string key_;
  /// The containers being filled, innermost last. Pointers stay valid: a container's vector is
  /// only appended to while it is the innermost one.
  std::vector<JsonValue*> open_;
};

}  // namespace

JsonValue message_value(const TypeDescription& description, const MessageType& type,
                        std::span<const std::uint8_t> bytes, bool wide_integers_as_strings) {
  ValueBuilder builder(wide_integers_as_strings);
  try {
    walk_message(description, type, bytes, builder);
  } catch (const DecodeError& error) {
    throw CodecError(std::string("a frame that is not a ") + type.name + ": " + error.what());
  }
  return builder.take();
}

// -- a value as a message -------------------------------------------------------------------------

namespace {

/// Answers build_message with the values of a JSON value (an object as message_value gives it,
/// wide integers as strings or numbers), refusing with a CodecError that names the value
/// ("horus.msg.PoseStamped.pose.position.x") one that does not fit its type.
class JsonSource final : public MessageSource {
 public:
  JsonSource(const JsonValue& root, std::string root_name)
      : root_(root), root_name_(std::move(root_name)) {}

  void begin_message(const MessageType& type) override {
    const JsonValue& value = take();
    if (value.kind != JsonValue::Kind::Object) fail("expected an object");
    for (const JsonMember& member : value.members) {
      if (type.find_field(member.key) == nullptr) {
        fail("no field '" + member.key + "' in " + type.name);
      }
    }
    for (const MessageField& field : type.fields) {
      if (value.find(field.name) == nullptr) fail("missing field '" + field.name + "'");
    }
    open(value);
  }

  void end_message(const MessageType&) override { open_.pop_back(); }

  void field(const MessageField& field) override {
    Container& message = open_.back();
    message.field = message.value->find(field.name);
    message.field_where = message.where + "." + field.name;
  }

  bool boolean() override {
    const JsonValue& value = take();
    if (value.kind != JsonValue::Kind::Bool) fail("expected true or false");
    return value.boolean;
  }

  std::uint64_t unsigned_integer(const TypeRef& type) override {
    return integer(type.primitive, take());
  }

  std::int64_t signed_integer(const TypeRef& type) override {
    return static_cast<std::int64_t>(integer(type.primitive, take()));
  }

  double floating(const TypeRef&) override {
    const JsonValue& value = take();
    if (value.kind == JsonValue::Kind::Null) return std::numeric_limits<double>::quiet_NaN();
    if (!value.is_number()) fail("expected a number or null");
    return value.number();
  }

  std::int64_t enumerator(const EnumType& enumeration) override {
    const JsonValue& value = take();
    if (value.kind == JsonValue::Kind::String) {
      for (const Enumerator& named : enumeration.values) {
        if (named.name == value.text) return named.value;
      }
      fail("\"" + value.text + "\" is not an enumerator of " + enumeration.name);
    }
    return static_cast<std::int64_t>(integer(enumeration.underlying, value));
  }

  std::string_view string(const TypeRef& type) override {
    const JsonValue& value = take();
    if (value.kind != JsonValue::Kind::String) fail("expected a string");
    if (type.kind == TypeRef::Kind::FixedString && value.text.size() > type.length) {
      fail("a string of " + std::to_string(value.text.size()) + " bytes, longer than " +
           std::to_string(type.length));
    }
    return value.text;
  }

  std::span<const std::uint8_t> bytes(const TypeRef& type) override {
    const JsonValue& value = take();
    if (type.kind == TypeRef::Kind::Array) {
      // [u8; N]: an array of numbers, as the schema says.
      if (value.kind != JsonValue::Kind::Array || value.items.size() != type.length) {
        fail("expected an array of " + std::to_string(type.length) + " integers");
      }
      open(value);
      block_.clear();
      for (std::size_t i = 0; i < value.items.size(); ++i) {
        block_.push_back(static_cast<char>(integer(Primitive::U8, take())));
      }
      open_.pop_back();
    } else {
      if (value.kind != JsonValue::Kind::String) fail("expected a base64 string");
      block_ = decode_base64(value.text, where_);
    }
    return {reinterpret_cast<const std::uint8_t*>(block_.data()), block_.size()};
  }

  std::size_t begin_sequence(const TypeRef& type) override {
    const JsonValue& value = take();
    if (value.kind != JsonValue::Kind::Array ||
        (type.kind == TypeRef::Kind::Array && value.items.size() != type.length)) {
      fail(type.kind == TypeRef::Kind::Array ? "expected an array of " + std::to_string(type.length)
                                             : std::string("expected an array"));
    }
    open(value);
    return value.items.size();
  }

  void end_sequence(const TypeRef&) override { open_.pop_back(); }

  bool begin_optional(const TypeRef&) override {
    // The element, when present, is the same JSON value: looked at here, taken by its question.
    const bool present = peek().kind != JsonValue::Kind::Null;
    if (!present) take();
    return present;
  }

  void end_optional(const TypeRef&) override {}

 private:
  /// An open object (its current field's value) or array (its next element).
  struct Container {
    const JsonValue* value = nullptr;
    std::string where;
    const JsonValue* field = nullptr;
    std::string field_where;
    std::size_t next = 0;
  };

  [[noreturn]] void fail(std::string_view what) const {
    throw CodecError(where_ + ": " + std::string(what));
  }

  /// The value the next question is about, naming it in where_.
  const JsonValue& peek() {
    if (open_.empty()) {
      where_ = root_name_;
      return root_;
    }
    Container& container = open_.back();
    if (container.value->kind == JsonValue::Kind::Object) {
      where_ = container.field_where;
      return *container.field;
    }
    where_ = container.where + "[" + std::to_string(container.next) + "]";
    return container.value->items[container.next];
  }

  /// `value` (the one just taken) as the container the next questions are about.
  void open(const JsonValue& value) {
    Container container;
    container.value = &value;
    container.where = where_;
    open_.push_back(std::move(container));
  }

  const JsonValue& take() {
    const JsonValue& value = peek();
    if (!open_.empty() && open_.back().value->kind == JsonValue::Kind::Array) ++open_.back().next;
    return value;
  }

  /// An integer of `primitive`'s range as its 64 bits: a JSON integer, or a string of digits (u64
  /// and i64 come as strings from a JavaScript viewer).
  std::uint64_t integer(Primitive primitive, const JsonValue& value) const {
    bool negative = false;
    std::uint64_t magnitude = 0;
    if (value.kind == JsonValue::Kind::Unsigned) {
      magnitude = value.unsigned_value;
    } else if (value.kind == JsonValue::Kind::Signed) {
      negative = value.signed_value < 0;
      magnitude = negative ? 0 - static_cast<std::uint64_t>(value.signed_value)
                           : static_cast<std::uint64_t>(value.signed_value);
    } else if (value.kind == JsonValue::Kind::Float &&
               std::trunc(value.float_value) == value.float_value) {
      // A JSON number is read as a double, which holds every integer up to 2^53 exactly and
      // none past it for sure: those come as strings of digits, as the schema asks.
      if (std::fabs(value.float_value) > 0x1p53) {
        fail(
            "an integer past 2^53 as a JSON number, which cannot hold it exactly (send its "
            "digits as a string)");
      }
      negative = value.float_value < 0;
      magnitude = static_cast<std::uint64_t>(std::fabs(value.float_value));
    } else if (value.kind == JsonValue::Kind::String && !value.text.empty()) {
      std::string_view digits = value.text;
      negative = digits.front() == '-';
      if (negative) digits.remove_prefix(1);
      const char* last = digits.data() + digits.size();
      if (digits.empty() || std::from_chars(digits.data(), last, magnitude).ptr != last) {
        fail("expected an integer, got the string \"" + value.text + "\"");
      }
    } else {
      fail("expected an integer");
    }
    const std::size_t bits = primitive_size(primitive) * 8;
    const bool is_signed = primitive == Primitive::I8 || primitive == Primitive::I16 ||
                           primitive == Primitive::I32 || primitive == Primitive::I64;
    const std::uint64_t positive_limit =
        is_signed ? (std::uint64_t{1} << (bits - 1)) - 1
                  : (bits == 64 ? std::numeric_limits<std::uint64_t>::max()
                                : (std::uint64_t{1} << bits) - 1);
    const std::uint64_t negative_limit = is_signed ? std::uint64_t{1} << (bits - 1) : 0;
    if (negative ? magnitude > negative_limit : magnitude > positive_limit) {
      fail("out of range for " + std::string(primitive_name(primitive)));
    }
    return negative ? 0 - magnitude : magnitude;
  }

  const JsonValue& root_;
  std::string root_name_;
  std::vector<Container> open_;
  /// The value being answered about, for errors ("horus.msg.CmdVel.linear").
  std::string where_;
  std::string block_;
};

}  // namespace

void encode_message(const TypeDescription& description, const MessageType& type,
                    const JsonValue& value, std::vector<std::byte>& frame) {
  JsonSource source(value, type.name);
  std::vector<std::uint8_t> bytes;
  try {
    bytes = build_message(description, type, source);
  } catch (const Error& error) {
    throw CodecError(type.name + ": " + error.what());
  }
  const auto* data = reinterpret_cast<const std::byte*>(bytes.data());
  frame.assign(data, data + bytes.size());
}

}  // namespace horus::view::detail
