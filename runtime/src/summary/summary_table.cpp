// The formatter of table-driven log summaries (horus/summary_table.hpp). It prints by the rules of
// horus/log_summary.hpp, which the golden and cross-language tests hold both to: generated
// messages' lines must not change with how they are compiled.
#include "horus/summary_table.hpp"

#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "horus/log_summary.hpp"

namespace horus::summary {
namespace {

template <class T>
T read(const void* address) {
  T value;
  std::memcpy(&value, address, sizeof value);
  return value;
}

bool is_number(Kind kind) { return kind >= Kind::kI8 && kind <= Kind::kF64; }

/// Calls `visit(T{})` with the C++ type T of a number kind.
template <class Visit>
void with_number_type(Kind kind, Visit visit) {
  switch (kind) {
    case Kind::kI8:
      return visit(std::int8_t{});
    case Kind::kI16:
      return visit(std::int16_t{});
    case Kind::kI32:
      return visit(std::int32_t{});
    case Kind::kI64:
      return visit(std::int64_t{});
    case Kind::kU8:
      return visit(std::uint8_t{});
    case Kind::kU16:
      return visit(std::uint16_t{});
    case Kind::kU32:
      return visit(std::uint32_t{});
    case Kind::kU64:
      return visit(std::uint64_t{});
    case Kind::kF32:
      return visit(float{});
    default:
      return visit(double{});
  }
}

/// An integer of a number kind, converted to 64 bits as Enumerator::value is.
std::uint64_t stored_integer(Kind kind, const void* address) {
  std::uint64_t bits = 0;
  with_number_type(kind, [&](auto zero) {
    const auto value = read<decltype(zero)>(address);
    if constexpr (std::is_signed_v<decltype(zero)>) {
      // Sign-extended, as the generated table converts a negative enumerator.
      bits = static_cast<std::uint64_t>(static_cast<std::int64_t>(value));
    } else {
      bits = static_cast<std::uint64_t>(value);
    }
  });
  return bits;
}

/// Integers in decimal, floats as %g of the value as a double.
void append_stored_number(std::string& out, Kind kind, const void* address) {
  with_number_type(kind, [&](auto zero) {
    const auto value = read<decltype(zero)>(address);
    if constexpr (std::is_floating_point_v<decltype(zero)>) {
      append_number(out, static_cast<double>(value));
    } else {
      out += std::to_string(value);
    }
  });
}

/// ", min a, max b" of `count` numbers at `data`, compared in their own type as log_summary.hpp
/// does (the first of a NaN and a number stays), printed as doubles.
void append_range(std::string& out, Kind kind, const void* data, std::size_t count) {
  with_number_type(kind, [&](auto zero) {
    using T = decltype(zero);
    const auto* bytes = static_cast<const unsigned char*>(data);
    T lo = read<T>(bytes), hi = lo;
    for (std::size_t i = 0; i < count; ++i) {
      const T e = read<T>(bytes + i * sizeof(T));
      if (e < lo) lo = e;
      if (hi < e) hi = e;
    }
    out += ", min ";
    append_number(out, static_cast<double>(lo));
    out += ", max ";
    append_number(out, static_cast<double>(hi));
  });
}

void append_value(std::string& out, const Type& type, const void* address,
                  std::string_view element_label);

/// "[N x label]" forms for long sequences, else the elements; `element(i)` is the i-th's address.
template <class ElementAt>
void append_sequence(std::string& out, const Type& element, std::size_t count,
                     std::string_view element_label, ElementAt element_at) {
  if (count == 0) {
    out += "[]";
    return;
  }
  const bool numbers = is_number(element.kind);
  if (count > (numbers ? kMaxNumbersShown : kMaxElementsShown)) {
    out += '[';
    out += std::to_string(count);
    out += " x ";
    out += element_label;
    if (numbers) append_range(out, element.kind, element_at(0), count);
    out += ']';
    return;
  }
  out += '[';
  for (std::size_t i = 0; i < count; ++i) {
    if (i != 0) out += ", ";
    append_value(out, element, element_at(i), {});
  }
  out += ']';
}

void append_elements(std::string& out, const Type& element, Elements elements,
                     std::string_view element_label) {
  if (element.kind == Kind::kU8) {
    out += '<';
    out += std::to_string(elements.count);
    out += " bytes>";
    return;
  }
  const auto* data = static_cast<const unsigned char*>(elements.data);
  append_sequence(out, element, elements.count, element_label,
                  [&](std::size_t i) { return data + i * element.size; });
}

void append_value(std::string& out, const Type& type, const void* address,
                  std::string_view element_label) {
  switch (type.kind) {
    case Kind::kBool:
      out += read<bool>(address) ? "true" : "false";
      break;
    case Kind::kFixedString: {
      const auto* text = static_cast<const char*>(address);
      out += '"';
      out += std::string_view(text, strnlen(text, type.length));
      out += '"';
      break;
    }
    case Kind::kString:
      out += '"';
      out += *static_cast<const std::string*>(address);
      out += '"';
      break;
    case Kind::kEnum: {
      const std::uint64_t value = stored_integer(type.element->kind, address);
      for (const Enumerator* e = type.enumerators; e != type.enumerators + type.length; ++e) {
        if (e->value == value) {
          out += e->name;
          return;
        }
      }
      append_stored_number(out, type.element->kind, address);
      break;
    }
    case Kind::kMessage:
      out += type.message_summary(address);
      break;
    case Kind::kArray:
      append_elements(out, *type.element, {address, type.length}, element_label);
      break;
    case Kind::kVector:
      append_elements(out, *type.element, type.elements(address), element_label);
      break;
    case Kind::kBoolVector: {
      const auto& bits = *static_cast<const std::vector<bool>*>(address);
      const bool values[2] = {false, true};
      append_sequence(out, *type.element, bits.size(), element_label,
                      [&](std::size_t i) { return &values[bits[i] ? 1 : 0]; });
      break;
    }
    case Kind::kOptional:
      if (const void* value = type.optional_value(address)) {
        append_value(out, *type.element, value, element_label);
      } else {
        out += "none";
      }
      break;
    default:
      append_stored_number(out, type.kind, address);
      break;
  }
}

}  // namespace

std::string format(const Part* parts, std::size_t count, const void* const* fields) {
  std::string out;
  std::size_t field = 0;
  for (const Part* part = parts; part != parts + count; ++part) {
    if (part->type == nullptr) {
      out += part->text;
      continue;
    }
    append_value(out, *part->type, fields[field++], part->label);
    if (!part->unit.empty()) {
      out += ' ';
      out += part->unit;
    }
  }
  return out;
}

}  // namespace horus::summary
