// Parameter values: the declared types, the MessagePack VALUE form every value crosses a boundary
// in, the record form the store holds (a scalar's word, a string's or array's bytes), and the
// checks a declaration makes (type, range, allowed values, size).
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "../types/msgpack_input.hpp"
#include "horus/json_string.hpp"
#include "horus/node.hpp"
#include "horus/params.hpp"
#include "param_internal.hpp"

namespace horus::detail {
namespace {

using Packer = msgpack::packer<msgpack::sbuffer>;

std::string bytes_of(const msgpack::sbuffer& buffer) {
  return std::string(buffer.data(), buffer.size());
}

bool is_signed(Primitive primitive) {
  return primitive == Primitive::I8 || primitive == Primitive::I16 || primitive == Primitive::I32 ||
         primitive == Primitive::I64;
}

/// The element of an array parameter, the type itself otherwise.
const TypeRef& scalar_type(const TypeRef& type) {
  return type.kind == TypeRef::Kind::Array ? *type.element : type;
}

void pack_word(msgpack::sbuffer& buffer, Packer& packer, const ParamDeclaration& declaration,
               Primitive primitive, std::uint64_t word) {
  if (declaration.type.kind == TypeRef::Kind::Enum) {
    const auto value = static_cast<std::int64_t>(word);
    const Enumerator* enumerator =
        declaration.enumeration ? declaration.enumeration->find_value(value) : nullptr;
    if (enumerator == nullptr) {
      throw ParamError("parameter '" + declaration.name + "': " + std::to_string(value) +
                       " is no enumerator of " + declaration.spelling);
    }
    packer.pack_str(static_cast<std::uint32_t>(enumerator->name.size()));
    packer.pack_str_body(enumerator->name.data(),
                         static_cast<std::uint32_t>(enumerator->name.size()));
    return;
  }
  switch (primitive) {
    case Primitive::Bool:
      if (word != 0) {
        packer.pack_true();
      } else {
        packer.pack_false();
      }
      return;
    case Primitive::F32:
      pack_float64(buffer, std::bit_cast<float>(static_cast<std::uint32_t>(word)));
      return;
    case Primitive::F64:
      pack_float64(buffer, std::bit_cast<double>(word));
      return;
    default:
      if (is_signed(primitive)) {
        packer.pack_int64(static_cast<std::int64_t>(word));
      } else {
        packer.pack_uint64(word);
      }
  }
}

/// The word of one number or bool of `primitive`; the reason in `problem` when it is not one.
std::uint64_t word_of(const msgpack::object& value, Primitive primitive, std::string& problem) {
  switch (primitive) {
    case Primitive::Bool:
      if (value.type != msgpack::type::BOOLEAN) problem = "expected true or false";
      return value.type == msgpack::type::BOOLEAN && value.via.boolean ? 1 : 0;
    case Primitive::F32:
    case Primitive::F64: {
      double number = 0;
      if (value.type == msgpack::type::FLOAT32 || value.type == msgpack::type::FLOAT64) {
        number = value.via.f64;
      } else if (value.type == msgpack::type::POSITIVE_INTEGER) {
        number = static_cast<double>(value.via.u64);
      } else if (value.type == msgpack::type::NEGATIVE_INTEGER) {
        number = static_cast<double>(value.via.i64);
      } else {
        problem = "expected a number";
        return 0;
      }
      if (primitive == Primitive::F64) return std::bit_cast<std::uint64_t>(number);
      if (std::isfinite(number) && std::abs(number) > std::numeric_limits<float>::max()) {
        problem = "out of the range of f32";
        return 0;
      }
      return std::bit_cast<std::uint32_t>(static_cast<float>(number));
    }
    default: {
      const std::size_t bits = primitive_size(primitive) * 8;
      if (value.type == msgpack::type::POSITIVE_INTEGER) {
        const std::uint64_t number = value.via.u64;
        const std::uint64_t limit =
            is_signed(primitive)
                ? (std::uint64_t{1} << (bits - 1)) - 1
                : (bits == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1);
        if (number > limit)
          problem = std::to_string(number) + " is out of the range of " +
                    std::string(primitive_name(primitive));
        return number;
      }
      if (value.type == msgpack::type::NEGATIVE_INTEGER) {
        const std::int64_t number = value.via.i64;
        const std::int64_t lowest = bits == 64 ? std::numeric_limits<std::int64_t>::min()
                                               : -(std::int64_t{1} << (bits - 1));
        if (!is_signed(primitive) || number < lowest) {
          problem = std::to_string(number) + " is out of the range of " +
                    std::string(primitive_name(primitive));
        }
        return static_cast<std::uint64_t>(number);
      }
      problem = "expected an integer";
      return 0;
    }
  }
}

/// One scalar (a number, bool or enumerator) of the declaration's type as its word.
std::uint64_t scalar_word(const ParamDeclaration& declaration, const msgpack::object& value,
                          std::string& problem) {
  if (declaration.type.kind == TypeRef::Kind::Enum) {
    if (value.type != msgpack::type::STR) {
      problem = "expected an enumerator of " + declaration.spelling;
      return 0;
    }
    const std::string_view name(value.via.str.ptr, value.via.str.size);
    for (const Enumerator& enumerator : declaration.enumeration->values) {
      if (enumerator.name == name) return static_cast<std::uint64_t>(enumerator.value);
    }
    std::string names;
    for (const Enumerator& enumerator : declaration.enumeration->values) {
      names += (names.empty() ? "" : ", ") + enumerator.name;
    }
    problem = "'" + std::string(name) + "' is no enumerator of " + declaration.spelling + " (" +
              names + ")";
    return 0;
  }
  return word_of(value, declaration.type.primitive, problem);
}

double number_of(Primitive primitive, std::uint64_t word) {
  switch (primitive) {
    case Primitive::F32:
      return std::bit_cast<float>(static_cast<std::uint32_t>(word));
    case Primitive::F64:
      return std::bit_cast<double>(word);
    case Primitive::Bool:
      return word != 0 ? 1 : 0;
    default:
      return is_signed(primitive) ? static_cast<double>(static_cast<std::int64_t>(word))
                                  : static_cast<double>(word);
  }
}

std::uint64_t element_word(const std::string& bytes, std::size_t index, std::size_t size) {
  std::uint64_t word = 0;
  std::memcpy(&word, bytes.data() + index * size, size);
  return word;
}

/// Sign-extends a signed element read from its native bytes.
std::uint64_t widened(Primitive primitive, std::uint64_t word) {
  const std::size_t bits = primitive_size(primitive) * 8;
  if (!is_signed(primitive) || bits == 64) return word;
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  return (word ^ sign) - sign;
}

msgpack::object_handle unpacked(std::string_view value, const ParamDeclaration& declaration) {
  return types::unpack_whole<ParamError>(value.data(), value.size(),
                                         "parameter '" + declaration.name + "'");
}

}  // namespace

void pack_float64(msgpack::sbuffer& buffer, double value) {
  const auto bits = std::bit_cast<std::uint64_t>(value);
  char out[9] = {static_cast<char>(0xcb)};
  for (std::size_t i = 0; i < 8; ++i) out[1 + i] = static_cast<char>(bits >> (56 - 8 * i));
  buffer.write(out, sizeof out);
}

bool param_is_scalar(const ParamDeclaration& declaration) noexcept {
  return declaration.type.kind == TypeRef::Kind::Primitive ||
         declaration.type.kind == TypeRef::Kind::Enum;
}

TypeRef param_type_ref(Primitive primitive) {
  TypeRef type;
  type.kind = TypeRef::Kind::Primitive;
  type.primitive = primitive;
  return type;
}

TypeRef param_string_type_ref() {
  TypeRef type;
  type.kind = TypeRef::Kind::String;
  return type;
}

TypeRef param_array_type_ref(Primitive element, std::size_t length) {
  TypeRef type;
  type.kind = TypeRef::Kind::Array;
  type.length = length;
  type.element = std::make_shared<const TypeRef>(param_type_ref(element));
  return type;
}

std::pair<TypeRef, EnumType> param_enum_type(std::string_view description) {
  const TypeDescription decoded = TypeDescription::decode(description);
  const EnumType* enumeration = decoded.find_enum(decoded.root);
  if (enumeration == nullptr) {
    throw ParamError("the description of " + decoded.root + " is not an enum's");
  }
  TypeRef type;
  type.kind = TypeRef::Kind::Enum;
  type.name = enumeration->name;
  return {type, *enumeration};
}

std::string param_spelling(const TypeRef& type) {
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      return std::string(primitive_name(type.primitive));
    case TypeRef::Kind::String:
      return "String";
    case TypeRef::Kind::Array:
      return "[" + param_spelling(*type.element) + "; " + std::to_string(type.length) + "]";
    default:
      return type.name;
  }
}

std::string encode_param_word(const ParamDeclaration& declaration, std::uint64_t word) {
  msgpack::sbuffer buffer;
  Packer packer(buffer);
  pack_word(buffer, packer, declaration, declaration.type.primitive, word);
  return bytes_of(buffer);
}

std::string encode_param_bytes(const ParamDeclaration& declaration, std::string_view bytes) {
  msgpack::sbuffer buffer;
  Packer packer(buffer);
  if (declaration.type.kind == TypeRef::Kind::String) {
    packer.pack_str(static_cast<std::uint32_t>(bytes.size()));
    packer.pack_str_body(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
    return bytes_of(buffer);
  }
  const Primitive element = declaration.type.element->primitive;
  const std::size_t size = primitive_size(element);
  const std::string copy(bytes);
  const std::size_t count = std::min(declaration.type.length, copy.size() / size);
  packer.pack_array(static_cast<std::uint32_t>(count));
  for (std::size_t i = 0; i < count; ++i) {
    pack_word(buffer, packer, declaration, element, widened(element, element_word(copy, i, size)));
  }
  return bytes_of(buffer);
}

std::uint64_t decode_param_word(const ParamDeclaration& declaration, std::string_view value) {
  const msgpack::object_handle handle = unpacked(value, declaration);
  std::string problem;
  const std::uint64_t word = scalar_word(declaration, handle.get(), problem);
  if (!problem.empty()) throw ParamError("parameter '" + declaration.name + "': " + problem);
  return word;
}

std::string decode_param_bytes(const ParamDeclaration& declaration, std::string_view value) {
  const msgpack::object_handle handle = unpacked(value, declaration);
  const msgpack::object& object = handle.get();
  const auto refuse = [&](const std::string& problem) {
    throw ParamError("parameter '" + declaration.name + "': " + problem);
  };
  if (declaration.type.kind == TypeRef::Kind::String) {
    if (object.type != msgpack::type::STR) refuse("expected a string");
    if (object.via.str.size > kMaxParamValueBytes) {
      refuse("a string of " + std::to_string(object.via.str.size) + " bytes is longer than the " +
             std::to_string(kMaxParamValueBytes) + " a parameter holds");
    }
    return std::string(object.via.str.ptr, object.via.str.size);
  }
  if (object.type != msgpack::type::ARRAY)
    refuse("expected a list of " + std::to_string(declaration.type.length));
  if (object.via.array.size != declaration.type.length) {
    refuse("expected " + std::to_string(declaration.type.length) + " elements, not " +
           std::to_string(object.via.array.size));
  }
  const Primitive element = declaration.type.element->primitive;
  const std::size_t size = primitive_size(element);
  std::string bytes(size * declaration.type.length, '\0');
  for (std::size_t i = 0; i < declaration.type.length; ++i) {
    std::string problem;
    const std::uint64_t word = word_of(object.via.array.ptr[i], element, problem);
    if (!problem.empty()) refuse("element " + std::to_string(i) + ": " + problem);
    std::memcpy(bytes.data() + i * size, &word, size);
  }
  return bytes;
}

void check_param_cpp_type(const ParamDeclaration& declaration, const TypeRef& cpp_type,
                          std::string_view cpp_enum) {
  const std::string asked = param_spelling(cpp_type);
  if (asked != declaration.spelling && asked != param_spelling(declaration.type) &&
      !(cpp_type.kind == TypeRef::Kind::Enum && cpp_enum == declaration.type.name)) {
    throw ParamError("parameter '" + declaration.name + "' is " + declaration.spelling + ", not " +
                     asked);
  }
}

std::string canonical_param_value(const ParamDeclaration& declaration, std::string_view value) {
  if (param_is_scalar(declaration)) {
    return encode_param_word(declaration, decode_param_word(declaration, value));
  }
  return encode_param_bytes(declaration, decode_param_bytes(declaration, value));
}

std::string param_value_problem(const ParamDeclaration& declaration, std::string_view value) {
  std::string canonical;
  std::vector<double> numbers;
  try {
    canonical = canonical_param_value(declaration, value);
    const TypeRef& scalar = scalar_type(declaration.type);
    if (scalar.kind == TypeRef::Kind::Primitive && scalar.primitive != Primitive::Bool) {
      if (param_is_scalar(declaration)) {
        numbers.push_back(number_of(scalar.primitive, decode_param_word(declaration, value)));
      } else {
        const std::string bytes = decode_param_bytes(declaration, value);
        const std::size_t size = primitive_size(scalar.primitive);
        for (std::size_t i = 0; i < declaration.type.length; ++i) {
          numbers.push_back(
              number_of(scalar.primitive, widened(scalar.primitive, element_word(bytes, i, size))));
        }
      }
    }
  } catch (const ParamError& e) {
    const std::string text = e.what();
    const std::string prefix = "parameter '" + declaration.name + "': ";
    return text.starts_with(prefix) ? text.substr(prefix.size()) : text;
  }
  const auto shown = [](double number) {
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", number);
    return std::string(text);
  };
  for (const double number : numbers) {
    if (std::isnan(number) && (declaration.min || declaration.max)) {
      return "NaN is outside the range";
    }
    if (declaration.min && number < *declaration.min) {
      return shown(number) + " is below the minimum " + shown(*declaration.min);
    }
    if (declaration.max && number > *declaration.max) {
      return shown(number) + " is above the maximum " + shown(*declaration.max);
    }
  }
  if (!declaration.choices.empty()) {
    bool allowed = false;
    for (const std::string& choice : declaration.choices) {
      try {
        allowed = allowed || canonical_param_value(declaration, choice) == canonical;
      } catch (const ParamError&) {
      }
    }
    if (!allowed) {
      std::ostringstream listed;
      for (const std::string& choice : declaration.choices) {
        if (listed.tellp() > 0) listed << ", ";
        listed << types::unpack_whole<ParamError>(choice.data(), choice.size(), "a choice").get();
      }
      return "not one of the allowed values (" + listed.str() + ")";
    }
  }
  return {};
}

std::shared_ptr<ParamSlot> declare_node_param(std::vector<ParamDeclaration>& declarations,
                                              std::vector<std::shared_ptr<ParamSlot>>& slots,
                                              ParamDeclaration declaration,
                                              std::uint64_t default_word,
                                              std::string default_bytes) {
  const std::string& name = declaration.name;
  bool valid = !name.empty() && name.size() <= 63 && !(name[0] >= '0' && name[0] <= '9');
  for (const char c : name) {
    valid = valid && ((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_');
  }
  if (!valid) {
    throw ParamError("parameter name '" + name +
                     "' is not valid: use 1 to 63 of [a-z0-9_], not starting with a digit");
  }
  for (const ParamDeclaration& existing : declarations) {
    if (existing.name == name) throw ParamError("parameter '" + name + "' is declared twice");
  }
  if (declaration.spelling.empty()) declaration.spelling = param_spelling(declaration.type);
  const TypeRef& scalar = scalar_type(declaration.type);
  const bool numeric =
      scalar.kind == TypeRef::Kind::Primitive && scalar.primitive != Primitive::Bool;
  if ((declaration.min || declaration.max) && !numeric) {
    throw ParamError("parameter '" + name + "': a range needs a number, not " +
                     declaration.spelling);
  }
  if (declaration.min && declaration.max && *declaration.min > *declaration.max) {
    throw ParamError("parameter '" + name + "': its minimum is above its maximum");
  }
  if (declaration.type.kind == TypeRef::Kind::Array &&
      declaration.type.length * primitive_size(scalar.primitive) > kMaxParamValueBytes) {
    throw ParamError("parameter '" + name + "': " + declaration.spelling + " is larger than the " +
                     std::to_string(kMaxParamValueBytes) + " bytes a parameter holds");
  }
  for (const std::string& choice : declaration.choices) {
    const std::string saved_choices_problem = [&] {
      ParamDeclaration plain = declaration;
      plain.choices.clear();
      return param_value_problem(plain, choice);
    }();
    if (!saved_choices_problem.empty()) {
      throw ParamError("parameter '" + name + "': an allowed value: " + saved_choices_problem);
    }
  }
  if (const std::string problem = param_value_problem(declaration, declaration.default_value);
      !problem.empty()) {
    throw ParamError("parameter '" + name + "': its default: " + problem);
  }
  auto slot = std::make_shared<ParamSlot>();
  slot->default_word.store(default_word, std::memory_order_relaxed);
  slot->default_bytes = std::move(default_bytes);
  slot->declaration = declaration;
  declarations.push_back(std::move(declaration));
  slots.push_back(slot);
  return slot;
}

void append_param_value_text(std::string& out, const msgpack::object& value, bool single_precision,
                             bool yaml) {
  switch (value.type) {
    case msgpack::type::BOOLEAN:
      out += value.via.boolean ? "true" : "false";
      return;
    case msgpack::type::POSITIVE_INTEGER:
      out += std::to_string(value.via.u64);
      return;
    case msgpack::type::NEGATIVE_INTEGER:
      out += std::to_string(value.via.i64);
      return;
    case msgpack::type::FLOAT32:
    case msgpack::type::FLOAT64: {
      const double number = value.via.f64;
      if (std::isnan(number)) {
        out += yaml ? ".nan" : "null";  // JSON has no NaN nor infinity
      } else if (std::isinf(number)) {
        out += !yaml ? "null" : number > 0 ? ".inf" : "-.inf";
      } else {
        // The shortest text that reads back as the same f32 / f64, and a float still.
        char text[64];
        const std::to_chars_result end =
            single_precision || value.type == msgpack::type::FLOAT32
                ? std::to_chars(text, text + sizeof text, static_cast<float>(number))
                : std::to_chars(text, text + sizeof text, number);
        const std::string_view shown(text, static_cast<std::size_t>(end.ptr - text));
        out += shown;
        if (shown.find_first_of(".en") == std::string_view::npos) out += ".0";
      }
      return;
    }
    case msgpack::type::STR:
      out += json_string(std::string_view(value.via.str.ptr, value.via.str.size));
      return;
    case msgpack::type::ARRAY:
      out += '[';
      for (std::uint32_t i = 0; i < value.via.array.size; ++i) {
        if (i > 0) out += ", ";
        append_param_value_text(out, value.via.array.ptr[i], single_precision, yaml);
      }
      out += ']';
      return;
    default:
      out += "null";  // no VALUE of a parameter is of another kind
  }
}

}  // namespace horus::detail

namespace horus {

std::string param_value_json(std::string_view value, const ParamDeclaration* declaration) {
  const msgpack::object_handle handle =
      types::unpack_whole<ParamError>(value.data(), value.size(), "a parameter's value");
  bool single_precision = false;
  if (declaration != nullptr) {
    const TypeRef& type = declaration->type.kind == TypeRef::Kind::Array
                              ? *declaration->type.element
                              : declaration->type;
    single_precision = type.kind == TypeRef::Kind::Primitive && type.primitive == Primitive::F32;
  }
  std::string out;
  detail::append_param_value_text(out, handle.get(), single_precision, false);
  return out;
}

ParamVerdict Node::on_param_change(const ParamChange&) { return ParamVerdict::accept(); }

ParamHandle Node::declare_param(ParamDeclaration declaration) {
  std::uint64_t word = 0;
  std::string bytes;
  if (detail::param_is_scalar(declaration)) {
    word = detail::decode_param_word(declaration, declaration.default_value);
  } else {
    bytes = detail::decode_param_bytes(declaration, declaration.default_value);
  }
  declaration.default_value = detail::canonical_param_value(declaration, declaration.default_value);
  for (std::string& choice : declaration.choices) {
    choice = detail::canonical_param_value(declaration, choice);
  }
  return ParamHandle(detail::declare_node_param(param_declarations_, param_slots_,
                                                std::move(declaration), word, std::move(bytes)));
}

std::string ParamHandle::value() const {
  const ParamDeclaration& declaration = slot_->declaration;
  if (detail::param_is_scalar(declaration)) {
    return detail::encode_param_word(
        declaration, slot_->word.load(std::memory_order_acquire)->load(std::memory_order_acquire));
  }
  return detail::encode_param_bytes(declaration, detail::read_param_bytes(*slot_));
}

}  // namespace horus
