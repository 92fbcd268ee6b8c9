#include "horus/dds/cdr_plan.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string_view>
#include <utility>

namespace horus::dds_bridge {
namespace {

constexpr std::size_t kHeader = 4;  // the encapsulation: scheme (2 bytes), options (2 bytes)

// CDR aligns a primitive to its size, 8 at most, counted from the start of the body.
std::size_t aligned(std::size_t position, std::size_t size) {
  const std::size_t alignment = std::min<std::size_t>(size, 8);
  return (position + alignment - 1) / alignment * alignment;
}

std::uint32_t load_u32(const std::byte* at, bool big_endian) {
  std::uint32_t value = 0;
  std::memcpy(&value, at, sizeof value);
  return big_endian ? __builtin_bswap32(value) : value;
}

// Reads a CDR body step by step, each read checked against the body's end.
class BodyReader {
 public:
  BodyReader(std::span<const std::byte> body, bool big_endian)
      : body_(body), big_endian_(big_endian) {}

  bool big_endian() const { return big_endian_; }
  std::size_t left() const { return body_.size() - position_; }

  // `size` bytes at the next multiple of `alignment`; null (and `error` set) past the end.
  const std::byte* take(std::size_t size, std::size_t alignment, std::string& error) {
    const std::size_t start = aligned(position_, alignment);
    if (start > body_.size() || size > body_.size() - start) {
      error = std::to_string(size) + " bytes wanted at offset " + std::to_string(start) + " of a " +
              std::to_string(body_.size()) + "-byte body";
      return nullptr;
    }
    position_ = start + size;
    return body_.data() + start;
  }

 private:
  std::span<const std::byte> body_;
  bool big_endian_;
  std::size_t position_ = 0;
};

void swap_elements(std::byte* data, std::size_t size, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    std::reverse(data + i * size, data + (i + 1) * size);
  }
}

std::string decode_step(const CdrStep& step, BodyReader& reader, std::byte* pod,
                        std::vector<std::byte>* pool_data) {
  std::string error;
  std::byte* field = pod + step.offset;
  switch (step.kind) {
    case CdrStep::Kind::kCopy: {
      const std::byte* data = reader.take(std::size_t{step.size} * step.count, step.size, error);
      if (data != nullptr) {
        std::memcpy(field, data, std::size_t{step.size} * step.count);
        if (reader.big_endian() && step.size > 1) {
          swap_elements(field, step.size, step.count);
        }
      }
      break;
    }
    case CdrStep::Kind::kBool: {
      const std::byte* data = reader.take(step.count, 1, error);
      for (std::uint32_t i = 0; data != nullptr && i < step.count; ++i) {
        field[i] = std::byte{data[i] != std::byte{0}};
      }
      break;
    }
    case CdrStep::Kind::kString: {
      const std::byte* length_at = reader.take(4, 4, error);
      if (length_at == nullptr) {
        break;
      }
      const std::uint32_t length = load_u32(length_at, reader.big_endian());
      if (length == 0) {
        return "a string has length 0 (no NUL)";
      }
      if (length > reader.left()) {
        return "a string length of " + std::to_string(length) + " runs past the body";
      }
      const std::byte* text = reader.take(length, 1, error);
      const std::size_t bytes = length - 1;
      if (bytes > step.size) {
        return "a string of " + std::to_string(bytes) + " bytes does not fit in string<" +
               std::to_string(step.size) + ">";
      }
      if (std::find(text, text + bytes, std::byte{0}) != text + bytes) {
        return "a string holds a NUL character, which string<" + std::to_string(step.size) +
               "> cannot hold";
      }
      std::memcpy(field, text, bytes);
      break;
    }
    case CdrStep::Kind::kEmpty:
      reader.take(1, 1, error);
      break;
    case CdrStep::Kind::kPoolData: {
      const std::byte* count_at = reader.take(4, 4, error);
      if (count_at == nullptr) {
        break;
      }
      const std::uint32_t count = load_u32(count_at, reader.big_endian());
      const std::byte* data = reader.take(count, 1, error);
      if (data != nullptr && pool_data != nullptr) {
        pool_data->assign(data, data + count);
      }
      break;
    }
  }
  return error;
}

}  // namespace

CdrPlan::CdrPlan(std::string type_name, std::size_t pod_size, std::vector<CdrStep> steps)
    : type_name_(std::move(type_name)), pod_size_(pod_size), steps_(std::move(steps)) {
  for (const CdrStep& step : steps_) {
    const bool primitive = step.size == 1 || step.size == 2 || step.size == 4 || step.size == 8;
    const bool sized = step.kind == CdrStep::Kind::kString || step.kind == CdrStep::Kind::kPoolData
                           ? step.size > 0
                       : step.kind == CdrStep::Kind::kCopy ? primitive
                                                           : step.size == 1;
    const std::size_t end = std::size_t{step.offset} + std::size_t{step.size} * step.count;
    if (!sized || step.count == 0 || end > pod_size_) {
      throw std::invalid_argument("a CDR step (offset " + std::to_string(step.offset) + ", size " +
                                  std::to_string(step.size) + ", count " +
                                  std::to_string(step.count) + ") does not fit a " +
                                  std::to_string(pod_size_) + "-byte " + type_name_);
    }
  }
}

void CdrPlan::encode(const std::byte* pod, std::vector<std::byte>& sample,
                     std::span<const std::byte> pool_data,
                     std::span<const std::byte> body_prefix) const {
  sample.assign({std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}});  // CDR_LE
  sample.insert(sample.end(), body_prefix.begin(), body_prefix.end());
  const auto pad_to = [&](std::size_t size) {
    sample.resize(kHeader + aligned(sample.size() - kHeader, size));
  };
  const auto append = [&](const void* data, std::size_t size) {
    const auto* bytes = static_cast<const std::byte*>(data);
    sample.insert(sample.end(), bytes, bytes + size);
  };
  for (const CdrStep& step : steps_) {
    const std::byte* field = pod + step.offset;
    switch (step.kind) {
      case CdrStep::Kind::kCopy:
        pad_to(step.size);
        append(field, std::size_t{step.size} * step.count);
        break;
      case CdrStep::Kind::kBool:
        for (std::uint32_t i = 0; i < step.count; ++i) {
          sample.push_back(std::byte{field[i] != std::byte{0}});
        }
        break;
      case CdrStep::Kind::kString: {
        const auto* end = std::find(field, field + step.size, std::byte{0});
        const auto length = static_cast<std::uint32_t>(end - field + 1);
        pad_to(4);
        append(&length, 4);
        append(field, length - 1);
        sample.push_back(std::byte{0});
        break;
      }
      case CdrStep::Kind::kEmpty:
        sample.push_back(std::byte{0});
        break;
      case CdrStep::Kind::kPoolData: {
        const auto count = static_cast<std::uint32_t>(pool_data.size());
        pad_to(4);
        append(&count, 4);
        append(pool_data.data(), pool_data.size());
        break;
      }
    }
  }
  const std::size_t padding = (4 - (sample.size() - kHeader) % 4) % 4;
  sample.resize(sample.size() + padding);
  sample[3] = static_cast<std::byte>(padding);
}

std::string encapsulation_error(std::span<const std::byte> sample, bool& big_endian) {
  if (sample.size() < kHeader) {
    return "a CDR sample of " + std::to_string(sample.size()) +
           " bytes has no encapsulation header";
  }
  const bool little = sample[0] == std::byte{0} && sample[1] == std::byte{1};
  big_endian = sample[0] == std::byte{0} && sample[1] == std::byte{0};
  if (little || big_endian) {
    return {};
  }
  static constexpr char digits[] = "0123456789abcdef";
  std::string scheme;
  for (const std::byte byte : sample.first(2)) {
    scheme += digits[std::to_integer<unsigned>(byte) >> 4];
    scheme += digits[std::to_integer<unsigned>(byte) & 15];
  }
  // 0x0006 to 0x000b: XCDR2's plain, delimited and parameter-list encapsulations.
  const auto kind = std::to_integer<unsigned>(sample[1]);
  if (sample[0] == std::byte{0} && kind >= 6 && kind <= 11) {
    return "encapsulation " + scheme +
           " is XCDR2, and the bridge reads XCDR1 (plain CDR) only: the writer must offer XCDR1 "
           "(its data representation QoS)";
  }
  return "encapsulation " + scheme +
         " is not plain CDR (XCDR1): the writer's type is not a @final struct of the IDL "
         "horus-gen emits";
}

std::string CdrPlan::decode(std::span<const std::byte> sample, std::byte* pod,
                            std::vector<std::byte>* pool_data, std::size_t body_prefix) const {
  bool big = false;
  if (std::string error = encapsulation_error(sample, big); !error.empty()) {
    return error;
  }
  std::memset(pod, 0, pod_size_);
  BodyReader reader(sample.subspan(kHeader), big);
  if (std::string error; reader.take(body_prefix, 1, error) == nullptr) {
    return "a CDR sample does not decode as " + type_name_ + ": " + error;
  }
  for (const CdrStep& step : steps_) {
    const std::string error = decode_step(step, reader, pod, pool_data);
    if (!error.empty()) {
      return "a CDR sample does not decode as " + type_name_ + ": " + error;
    }
  }
  // Up to 3 bytes pad a sample to a multiple of 4; more is not this type.
  if (reader.left() > 3) {
    return "a CDR sample does not decode as " + type_name_ + ": " + std::to_string(reader.left()) +
           " bytes are left over";
  }
  return {};
}

namespace {

// The bytes of one element of `type` inside a POD struct.
std::size_t pod_size_of(const TypeDescription& description, const TypeRef& type) {
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      return primitive_size(type.primitive);
    case TypeRef::Kind::Enum:
      return primitive_size(description.enumeration(type).underlying);
    case TypeRef::Kind::FixedString:
      return type.length;
    case TypeRef::Kind::Message:
      return description.message(type).size;
    case TypeRef::Kind::Array:
      return type.length * pod_size_of(description, *type.element);
    default:
      throw std::invalid_argument("a field of type kind " +
                                  std::to_string(static_cast<int>(type.kind)) +
                                  " has no POD layout");
  }
}

constexpr std::string_view kPoolBlock = "horus.msg.PoolBlock";

void plan_message(const TypeDescription& description, const MessageType& type, std::size_t base,
                  bool pool_data, std::vector<CdrStep>& steps);

void plan_field(const TypeDescription& description, const TypeRef& type, std::size_t offset,
                bool pool_data, std::vector<CdrStep>& steps) {
  const auto at = static_cast<std::uint32_t>(offset);
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      steps.push_back(type.primitive == Primitive::Bool
                          ? CdrStep{CdrStep::Kind::kBool, at, 1, 1}
                          : CdrStep{CdrStep::Kind::kCopy, at,
                                    static_cast<std::uint32_t>(primitive_size(type.primitive)), 1});
      return;
    case TypeRef::Kind::Enum:
      steps.push_back(CdrStep{
          CdrStep::Kind::kCopy, at,
          static_cast<std::uint32_t>(primitive_size(description.enumeration(type).underlying)), 1});
      return;
    case TypeRef::Kind::FixedString:
      steps.push_back(
          CdrStep{CdrStep::Kind::kString, at, static_cast<std::uint32_t>(type.length), 1});
      return;
    case TypeRef::Kind::Array: {
      const std::size_t element = pod_size_of(description, *type.element);
      for (std::size_t index = 0; index < type.length; ++index) {
        plan_field(description, *type.element, offset + index * element, pool_data, steps);
      }
      return;
    }
    case TypeRef::Kind::Message:
      if (pool_data && type.name == kPoolBlock) {
        steps.push_back(CdrStep{CdrStep::Kind::kPoolData, at,
                                static_cast<std::uint32_t>(description.message(type).size), 1});
        return;
      }
      plan_message(description, description.message(type), offset, pool_data, steps);
      return;
    default:
      throw std::invalid_argument("a field of type kind " +
                                  std::to_string(static_cast<int>(type.kind)) +
                                  " has no POD CDR step");
  }
}

void plan_message(const TypeDescription& description, const MessageType& type, std::size_t base,
                  bool pool_data, std::vector<CdrStep>& steps) {
  if (!type.is_pod) {
    throw std::invalid_argument(type.name + " is a serialized message: it has no POD layout");
  }
  if (type.fields.empty()) {
    steps.push_back(CdrStep{CdrStep::Kind::kEmpty, static_cast<std::uint32_t>(base), 1, 1});
  }
  for (const MessageField& field : type.fields) {
    if (!field.offset) {
      throw std::invalid_argument(type.name + "." + field.name + " has no offset");
    }
    plan_field(description, field.type, base + *field.offset, pool_data, steps);
  }
}

}  // namespace

CdrPlan pod_cdr_plan(const TypeDescription& description, const MessageType& type, bool pool_data) {
  std::vector<CdrStep> steps;
  plan_message(description, type, 0, pool_data, steps);
  // Neighbouring numbers (or bools) of one size are one step: one copy, one alignment.
  std::vector<CdrStep> merged{steps.front()};
  for (auto step = steps.begin() + 1; step != steps.end(); ++step) {
    CdrStep& last = merged.back();
    const bool mergeable =
        step->kind == last.kind &&
        (step->kind == CdrStep::Kind::kCopy || step->kind == CdrStep::Kind::kBool) &&
        step->size == last.size && step->offset == last.offset + last.size * last.count;
    if (mergeable) {
      last.count += step->count;
    } else {
      merged.push_back(*step);
    }
  }
  return {type.name, type.size, std::move(merged)};
}

}  // namespace horus::dds_bridge
