#include "zero_message.hpp"

#include <cstdint>
#include <map>
#include <set>
#include <stdexcept>
#include <string>

namespace horus::remote {

namespace {

/// The canonical text's definitions: each message's field types in order, and the enums.
struct Definitions {
  std::map<std::string, std::vector<std::string>, std::less<>> messages;
  std::set<std::string, std::less<>> enums;
};

/// Reads the blocks of canonical text: "message NAME {\n  field: TYPE,\n...}\n" and
/// "enum NAME: BASE {\n  VARIANT = N,\n...}\n".
Definitions read_definitions(std::string_view schema) {
  Definitions out;
  std::vector<std::string>* fields = nullptr;
  while (!schema.empty()) {
    const std::size_t end = schema.find('\n');
    std::string_view line = schema.substr(0, end);
    schema = end == std::string_view::npos ? std::string_view() : schema.substr(end + 1);
    if (line.starts_with("message ") && line.ends_with(" {")) {
      const std::string name(line.substr(8, line.size() - 10));
      fields = &out.messages[name];
    } else if (line.starts_with("enum ")) {
      out.enums.emplace(line.substr(5, line.find(':') - 5));
      fields = nullptr;
    } else if (line == "}") {
      fields = nullptr;
    } else if (fields != nullptr && line.ends_with(',')) {
      const std::size_t colon = line.find(": ");
      if (colon != std::string_view::npos) {
        fields->emplace_back(line.substr(colon + 2, line.size() - colon - 3));
      }
    }
  }
  return out;
}

void put_byte(std::vector<std::byte>& out, unsigned value) {
  out.push_back(static_cast<std::byte>(value & 0xffU));
}

/// A MessagePack array (`array` true) or bin header of `count` elements or bytes.
void put_header(std::vector<std::byte>& out, std::size_t count, bool array) {
  if (array && count < 16) {
    put_byte(out, 0x90U | static_cast<unsigned>(count));
    return;
  }
  int width = 4;
  if (!array && count < 256) {
    put_byte(out, 0xc4);
    width = 1;
  } else if (count < 65536) {
    put_byte(out, array ? 0xdc : 0xc5);
    width = 2;
  } else {
    put_byte(out, array ? 0xdd : 0xc6);
  }
  for (int shift = 8 * (width - 1); shift >= 0; shift -= 8) {
    put_byte(out, static_cast<unsigned>(count >> shift));
  }
}

void put_zero(const Definitions& definitions, std::string_view type, std::vector<std::byte>& out) {
  static const std::set<std::string_view> numbers{"u8",  "u16", "u32", "u64", "i8",
                                                  "i16", "i32", "i64", "f32", "f64"};
  if (numbers.count(type) != 0 || definitions.enums.count(type) != 0) {
    put_byte(out, 0x00);  // 0 (a decoder reads a float from an integer too)
  } else if (type == "bool") {
    put_byte(out, 0xc2);
  } else if (type == "String" || type.starts_with("string<")) {
    put_byte(out, 0xa0);
  } else if (type == "bytes" || type == "Vec<u8>") {
    put_header(out, 0, false);
  } else if (type.starts_with("Vec<")) {
    put_header(out, 0, true);
  } else if (type.starts_with("Option<")) {
    put_byte(out, 0xc0);
  } else if (type.starts_with('[') && type.ends_with(']')) {
    const std::string_view inside = type.substr(1, type.size() - 2);
    const std::size_t separator = inside.rfind("; ");
    const std::string_view element = inside.substr(0, separator);
    const std::size_t length = std::stoul(std::string(inside.substr(separator + 2)));
    if (element == "u8") {  // msgpack-cxx writes std::array<std::uint8_t, N> as bin
      put_header(out, length, false);
      out.insert(out.end(), length, std::byte{0});
      return;
    }
    put_header(out, length, true);
    for (std::size_t i = 0; i < length; ++i) put_zero(definitions, element, out);
  } else if (const auto message = definitions.messages.find(type);
             message != definitions.messages.end()) {
    put_header(out, message->second.size(), true);
    for (const std::string& field : message->second) put_zero(definitions, field, out);
  } else {
    throw std::runtime_error("the schema text does not define " + std::string(type));
  }
}

}  // namespace

std::vector<std::byte> zero_message(std::string_view schema, std::string_view type) {
  std::vector<std::byte> out;
  put_zero(read_definitions(schema), type, out);
  return out;
}

}  // namespace horus::remote
