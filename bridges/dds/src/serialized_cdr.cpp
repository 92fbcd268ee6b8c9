#include "horus/dds/serialized_cdr.hpp"

#include <msgpack.hpp>

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "horus/dds/cdr_plan.hpp"

namespace horus::dds_bridge {
namespace {

constexpr std::size_t kHeader = 4;

std::size_t aligned(std::size_t position, std::size_t size) {
  const std::size_t alignment = std::min<std::size_t>(size, 8);
  return (position + alignment - 1) / alignment * alignment;
}

// Writes CDR (little-endian) of the values the walker visits.
class CdrOut final : public MessageVisitor {
 public:
  explicit CdrOut(std::vector<std::byte>& sample) : sample_(sample) {
    sample_.assign({std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}});  // CDR_LE
  }

  void finish() {
    const std::size_t padding = (4 - (sample_.size() - kHeader) % 4) % 4;
    sample_.resize(sample_.size() + padding);
    sample_[3] = static_cast<std::byte>(padding);
  }

  void begin_message(const MessageType& type) override {
    if (type.fields.empty()) {
      sample_.push_back(std::byte{0});  // ROS 2's one member of a message without fields
    }
  }
  void end_message(const MessageType&) override {}
  void field(const MessageField&) override {}
  void boolean(bool value) override { sample_.push_back(std::byte{value}); }
  void unsigned_integer(const TypeRef& type, std::uint64_t value) override {
    put(&value, primitive_size(type.primitive));
  }
  void signed_integer(const TypeRef& type, std::int64_t value) override {
    put(&value, primitive_size(type.primitive));  // little-endian: the low bytes first
  }
  void floating(const TypeRef& type, double value) override {
    if (type.primitive == Primitive::F32) {
      const auto narrow = static_cast<float>(value);
      put(&narrow, 4);
    } else {
      put(&value, 8);
    }
  }
  void enumerator(const EnumType& type, std::int64_t value) override {
    put(&value, primitive_size(type.underlying));
  }
  void string(const TypeRef&, std::string_view text) override {
    count(static_cast<std::uint32_t>(text.size() + 1));
    append(text.data(), text.size());
    sample_.push_back(std::byte{0});
  }
  void bytes(const TypeRef& type, std::span<const std::uint8_t> data) override {
    if (type.kind != TypeRef::Kind::Array) {
      count(static_cast<std::uint32_t>(data.size()));
    }
    append(data.data(), data.size());
  }
  void begin_sequence(const TypeRef& type, std::size_t size) override {
    if (type.kind == TypeRef::Kind::Vec) {
      count(static_cast<std::uint32_t>(size));
    }
  }
  void end_sequence(const TypeRef&) override {}
  void begin_optional(const TypeRef&, bool present) override { count(present ? 1 : 0); }
  void end_optional(const TypeRef&) override {}

 private:
  void count(std::uint32_t value) { put(&value, 4); }
  // `size` bytes of `value` at their CDR alignment (counted from the body's start).
  void put(const void* value, std::size_t size) {
    sample_.resize(kHeader + aligned(sample_.size() - kHeader, size));
    append(value, size);
  }
  void append(const void* data, std::size_t size) {
    const auto* bytes = static_cast<const std::byte*>(data);
    sample_.insert(sample_.end(), bytes, bytes + size);
  }

  std::vector<std::byte>& sample_;
};

// Thrown inside the reader: why a sample does not decode.
struct Malformed {
  std::string why;
};

using Packer = msgpack::packer<msgpack::sbuffer>;

class CdrIn {
 public:
  CdrIn(const TypeDescription& description, std::span<const std::byte> body, bool big_endian,
        Packer& out)
      : description_(description), body_(body), big_endian_(big_endian), out_(out) {}

  std::size_t left() const { return body_.size() - position_; }

  void message(const MessageType& type) {
    if (type.fields.empty()) {
      take(1, 1);
      out_.pack_array(0);
      return;
    }
    out_.pack_array(static_cast<std::uint32_t>(type.fields.size()));
    for (const MessageField& field : type.fields) {
      value(field.type);
    }
  }

 private:
  const std::byte* take(std::size_t size, std::size_t alignment) {
    const std::size_t start = aligned(position_, alignment);
    if (start > body_.size() || size > body_.size() - start) {
      throw Malformed{std::to_string(size) + " bytes wanted at offset " + std::to_string(start) +
                      " of a " + std::to_string(body_.size()) + "-byte body"};
    }
    position_ = start + size;
    return body_.data() + start;
  }

  std::uint64_t unsigned_of(std::size_t size) {
    const std::byte* at = take(size, size);
    std::uint64_t value = 0;
    for (std::size_t i = 0; i < size; ++i) {
      const auto byte = std::to_integer<std::uint64_t>(at[big_endian_ ? size - 1 - i : i]);
      value |= byte << (8 * i);
    }
    return value;
  }

  std::uint32_t count() {
    const std::size_t at = aligned(position_, 4);
    const auto value = static_cast<std::uint32_t>(unsigned_of(4));
    if (value > left()) {
      throw Malformed{"a count of " + std::to_string(value) + " at offset " + std::to_string(at) +
                      " runs past the " + std::to_string(body_.size()) + "-byte body"};
    }
    return value;
  }

  void primitive(Primitive kind) {
    const std::size_t size = primitive_size(kind);
    const std::uint64_t bits = unsigned_of(size);
    switch (kind) {
      case Primitive::Bool:
        out_.pack(bits != 0);
        return;
      case Primitive::U8:
      case Primitive::U16:
      case Primitive::U32:
      case Primitive::U64:
        out_.pack_uint64(bits);
        return;
      case Primitive::I8:
      case Primitive::I16:
      case Primitive::I32:
      case Primitive::I64: {
        const unsigned shift = static_cast<unsigned>(64 - 8 * size);
        out_.pack_int64(static_cast<std::int64_t>(bits << shift) >> shift);  // sign-extended
        return;
      }
      case Primitive::F32: {
        const auto narrow = static_cast<std::uint32_t>(bits);
        float value = 0;
        std::memcpy(&value, &narrow, 4);
        out_.pack_float(value);
        return;
      }
      case Primitive::F64: {
        double value = 0;
        std::memcpy(&value, &bits, 8);
        out_.pack_double(value);
        return;
      }
    }
  }

  void text(std::size_t bound) {
    const std::size_t at = aligned(position_, 4);
    const std::uint32_t length = count();
    if (length == 0) {
      throw Malformed{"a string at offset " + std::to_string(at) + " has length 0 (no NUL)"};
    }
    const std::byte* data = take(length, 1);
    if (bound != 0 && length - 1 > bound) {
      throw Malformed{"a string of " + std::to_string(length - 1) +
                      " bytes does not fit in string<" + std::to_string(bound) + ">"};
    }
    out_.pack_str(length - 1);
    out_.pack_str_body(reinterpret_cast<const char*>(data), length - 1);
  }

  void block(std::size_t size) {
    const std::byte* data = take(size, 1);
    out_.pack_bin(static_cast<std::uint32_t>(size));
    out_.pack_bin_body(reinterpret_cast<const char*>(data), static_cast<std::uint32_t>(size));
  }

  void value(const TypeRef& type) {
    switch (type.kind) {
      case TypeRef::Kind::Primitive:
        primitive(type.primitive);
        return;
      case TypeRef::Kind::Enum:
        primitive(description_.enumeration(type).underlying);
        return;
      case TypeRef::Kind::FixedString:
        text(type.length);
        return;
      case TypeRef::Kind::String:
        text(0);
        return;
      case TypeRef::Kind::Bytes:
        block(count());
        return;
      case TypeRef::Kind::Array:
        if (type.is_byte_block()) {
          block(type.length);
          return;
        }
        out_.pack_array(static_cast<std::uint32_t>(type.length));
        for (std::size_t i = 0; i < type.length; ++i) {
          value(*type.element);
        }
        return;
      case TypeRef::Kind::Vec: {
        const std::uint32_t size = count();
        if (type.is_byte_block()) {
          block(size);
          return;
        }
        out_.pack_array(size);
        for (std::uint32_t i = 0; i < size; ++i) {
          value(*type.element);
        }
        return;
      }
      case TypeRef::Kind::Optional: {
        const auto present = static_cast<std::uint32_t>(unsigned_of(4));
        if (present > 1) {
          throw Malformed{"an Option (sequence<T, 1>) holds " + std::to_string(present) +
                          " elements"};
        }
        if (present == 0) {
          out_.pack_nil();
        } else {
          value(*type.element);
        }
        return;
      }
      case TypeRef::Kind::Message:
        message(description_.message(type));
        return;
    }
  }

  const TypeDescription& description_;
  std::span<const std::byte> body_;
  bool big_endian_;
  Packer& out_;
  std::size_t position_ = 0;
};

}  // namespace

SerializedCdr::SerializedCdr(const TypeDescription& description, const MessageType& type)
    : description_(&description), type_(&type) {}

void SerializedCdr::encode(std::span<const std::uint8_t> message,
                           std::vector<std::byte>& sample) const {
  CdrOut out(sample);
  walk_message(*description_, *type_, message, out);
  out.finish();
}

std::string SerializedCdr::decode(std::span<const std::byte> sample,
                                  std::vector<std::uint8_t>& message) const {
  bool big = false;
  if (std::string error = encapsulation_error(sample, big); !error.empty()) {
    return error;
  }
  msgpack::sbuffer buffer;
  Packer packer(buffer);
  CdrIn reader(*description_, sample.subspan(kHeader), big, packer);
  try {
    reader.message(*type_);
  } catch (const Malformed& malformed) {
    return "a CDR sample does not decode as " + type_->name + ": " + malformed.why;
  }
  // Up to 3 bytes pad a sample to a multiple of 4; more is not this type.
  if (reader.left() > 3) {
    return "a CDR sample does not decode as " + type_->name + ": " + std::to_string(reader.left()) +
           " bytes are left over";
  }
  const auto* data = reinterpret_cast<const std::uint8_t*>(buffer.data());
  message.assign(data, data + buffer.size());
  return {};
}

}  // namespace horus::dds_bridge
