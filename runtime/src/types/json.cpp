// to_json: a message printed through walk_message, so tools print any type they were given the
// description of.
#include <array>
#include <charconv>
#include <cmath>
#include <vector>

#include "horus/type_description.hpp"

namespace horus {

namespace {

class JsonPrinter final : public MessageVisitor {
 public:
  std::string take() { return std::move(out_); }

  void begin_message(const MessageType&) override { open('{'); }
  void end_message(const MessageType&) override { close('}'); }

  void field(const MessageField& field) override {
    separate();
    quoted(field.name);
    out_ += ": ";
    after_key_ = true;
  }

  void boolean(bool value) override { scalar(value ? "true" : "false"); }

  void unsigned_integer(const TypeRef&, std::uint64_t value) override { number(value); }
  void signed_integer(const TypeRef&, std::int64_t value) override { number(value); }

  void floating(const TypeRef& type, double value) override {
    if (!std::isfinite(value)) {
      scalar("null");  // JSON has no NaN or infinity
      return;
    }
    // The shortest text that reads back as the same f32 / f64.
    std::array<char, 32> text{};
    const std::to_chars_result result =
        type.primitive == Primitive::F32
            ? std::to_chars(text.data(), text.data() + text.size(), static_cast<float>(value))
            : std::to_chars(text.data(), text.data() + text.size(), value);
    scalar(std::string_view(text.data(), static_cast<std::size_t>(result.ptr - text.data())));
  }

  void enumerator(const EnumType& type, std::int64_t value) override {
    if (const Enumerator* named = type.find_value(value)) {
      separate();
      quoted(named->name);
    } else {
      number(value);
    }
  }

  void string(const TypeRef&, std::string_view text) override {
    separate();
    quoted(text);
  }

  void bytes(const TypeRef&, std::span<const std::uint8_t> data) override {
    open('[');
    for (const std::uint8_t byte : data) number(byte);
    close(']');
  }

  void begin_sequence(const TypeRef&, std::size_t) override { open('['); }
  void end_sequence(const TypeRef&) override { close(']'); }

  void begin_optional(const TypeRef&, bool present) override {
    if (!present) scalar("null");
  }
  void end_optional(const TypeRef&) override {}

 private:
  /// A comma before every value of a container but its first (a field's value follows its key).
  void separate() {
    if (after_key_) {
      after_key_ = false;
    } else if (!first_.empty() && !first_.back()) {
      out_ += ", ";
    }
    if (!first_.empty()) first_.back() = false;
  }

  void open(char bracket) {
    separate();
    out_ += bracket;
    first_.push_back(true);
  }

  void close(char bracket) {
    first_.pop_back();
    out_ += bracket;
  }

  void scalar(std::string_view text) {
    separate();
    out_ += text;
  }

  template <class Integer>
  void number(Integer value) {
    std::array<char, 24> text{};
    const std::to_chars_result result =
        std::to_chars(text.data(), text.data() + text.size(), value);
    scalar(std::string_view(text.data(), static_cast<std::size_t>(result.ptr - text.data())));
  }

  /// `text` as a JSON string: control characters escaped, bytes that are not UTF-8 as U+FFFD.
  void quoted(std::string_view text) {
    out_ += '"';
    for (std::size_t i = 0; i < text.size();) {
      const auto byte = static_cast<unsigned char>(text[i]);
      if (byte == '"' || byte == '\\') {
        out_ += '\\';
        out_ += static_cast<char>(byte);
        ++i;
      } else if (byte < 0x20) {
        static constexpr char kHex[] = "0123456789abcdef";
        out_ += "\\u00";
        out_ += kHex[byte >> 4];
        out_ += kHex[byte & 0xf];
        ++i;
      } else if (byte < 0x80) {
        out_ += static_cast<char>(byte);
        ++i;
      } else {
        const std::size_t length = utf8_length(text.substr(i));
        out_ += length == 0 ? std::string_view("\xef\xbf\xbd") : text.substr(i, length);
        i += length == 0 ? 1 : length;
      }
    }
    out_ += '"';
  }

  /// Bytes of the well-formed UTF-8 sequence `text` starts with (its first byte >= 0x80), or 0.
  static std::size_t utf8_length(std::string_view text) {
    const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
    const unsigned char lead = byte(0);
    std::size_t length = 0;
    unsigned char low = 0x80;
    unsigned char high = 0xbf;
    if (lead >= 0xc2 && lead <= 0xdf) {
      length = 2;
    } else if (lead >= 0xe0 && lead <= 0xef) {
      length = 3;
      if (lead == 0xe0) low = 0xa0;
      if (lead == 0xed) high = 0x9f;  // no surrogates
    } else if (lead >= 0xf0 && lead <= 0xf4) {
      length = 4;
      if (lead == 0xf0) low = 0x90;
      if (lead == 0xf4) high = 0x8f;
    } else {
      return 0;
    }
    if (text.size() < length || byte(1) < low || byte(1) > high) return 0;
    for (std::size_t i = 2; i < length; ++i) {
      if (byte(i) < 0x80 || byte(i) > 0xbf) return 0;
    }
    return length;
  }

  std::string out_;
  std::vector<bool> first_;  // per open container: nothing written in it yet
  bool after_key_ = false;
};

}  // namespace

std::string to_json(const TypeDescription& description, const MessageType& type,
                    std::span<const std::uint8_t> bytes) {
  JsonPrinter printer;
  walk_message(description, type, bytes, printer);
  return printer.take();
}

}  // namespace horus
