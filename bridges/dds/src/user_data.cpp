#include "horus/dds/user_data.hpp"

#include <cstdint>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <utility>

#include "horus/type_description.hpp"

namespace horus::dds_bridge {
namespace {

// A JSON string as Python's json.dumps writes it (ASCII only: others as \uXXXX).
void put_string(std::string& out, std::string_view text) {
  out += '"';
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    char escaped[16];
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c < 0x20) {
      std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
      out += escaped;
    } else if (c < 0x80) {
      out += static_cast<char>(c);
    } else {
      // UTF-8 to a code point, then \uXXXX (a surrogate pair above the BMP).
      const int extra = c >= 0xf0 ? 3 : c >= 0xe0 ? 2 : 1;
      std::uint32_t point = c & (0x3f >> extra);
      for (int k = 0; k < extra && i + 1 < text.size(); ++k) {
        point = point << 6 | (static_cast<unsigned char>(text[++i]) & 0x3f);
      }
      if (point >= 0x10000) {
        point -= 0x10000;
        std::snprintf(escaped, sizeof escaped, "\\u%04x\\u%04x", 0xd800 + (point >> 10),
                      0xdc00 + (point & 0x3ff));
      } else {
        std::snprintf(escaped, sizeof escaped, "\\u%04x", point);
      }
      out += escaped;
    }
  }
  out += '"';
}

void put_utf8(std::string& out, std::uint32_t point) {
  if (point < 0x80) {
    out += static_cast<char>(point);
  } else if (point < 0x800) {
    out += static_cast<char>(0xc0 | point >> 6);
    out += static_cast<char>(0x80 | (point & 0x3f));
  } else if (point < 0x10000) {
    out += static_cast<char>(0xe0 | point >> 12);
    out += static_cast<char>(0x80 | (point >> 6 & 0x3f));
    out += static_cast<char>(0x80 | (point & 0x3f));
  } else {
    out += static_cast<char>(0xf0 | point >> 18);
    out += static_cast<char>(0x80 | (point >> 12 & 0x3f));
    out += static_cast<char>(0x80 | (point >> 6 & 0x3f));
    out += static_cast<char>(0x80 | (point & 0x3f));
  }
}

// Reads a flat JSON object of string values.
class Reader {
 public:
  explicit Reader(std::string_view text) : text_(text) {}

  std::map<std::string, std::string> object() {
    std::map<std::string, std::string> out;
    expect('{');
    if (peek() == '}') {
      ++at_;
      return out;
    }
    for (;;) {
      std::string key = string();
      expect(':');
      out[std::move(key)] = string();
      const char next = peek();
      ++at_;
      if (next == '}') {
        break;
      }
      if (next != ',') {
        fail("',' or '}'");
      }
    }
    if (peek() != '\0') {
      fail("the end");
    }
    return out;
  }

 private:
  [[noreturn]] void fail(const char* wanted) const {
    throw std::invalid_argument("user data that is no HORUS identity: " + std::string(wanted) +
                                " wanted at offset " + std::to_string(at_));
  }
  char peek() {
    while (at_ < text_.size() &&
           (text_[at_] == ' ' || text_[at_] == '\n' || text_[at_] == '\t' || text_[at_] == '\r')) {
      ++at_;
    }
    return at_ < text_.size() ? text_[at_] : '\0';
  }
  void expect(char c) {
    if (peek() != c) {
      fail(std::string(1, c).c_str());
    }
    ++at_;
  }
  std::uint32_t hex4() {
    if (at_ + 4 > text_.size()) {
      fail("4 hex digits");
    }
    std::uint32_t value = 0;
    for (int k = 0; k < 4; ++k) {
      const char c = text_[at_++];
      value <<= 4;
      if (c >= '0' && c <= '9') {
        value |= static_cast<std::uint32_t>(c - '0');
      } else if (c >= 'a' && c <= 'f') {
        value |= static_cast<std::uint32_t>(c - 'a' + 10);
      } else if (c >= 'A' && c <= 'F') {
        value |= static_cast<std::uint32_t>(c - 'A' + 10);
      } else {
        fail("a hex digit");
      }
    }
    return value;
  }
  std::string string() {
    expect('"');
    std::string out;
    while (at_ < text_.size() && text_[at_] != '"') {
      const char c = text_[at_++];
      if (c != '\\') {
        out += c;
        continue;
      }
      if (at_ >= text_.size()) {
        fail("an escape");
      }
      const char e = text_[at_++];
      switch (e) {
        case 'n':
          out += '\n';
          break;
        case 't':
          out += '\t';
          break;
        case 'r':
          out += '\r';
          break;
        case 'b':
          out += '\b';
          break;
        case 'f':
          out += '\f';
          break;
        case 'u': {
          std::uint32_t point = hex4();
          if (point >= 0xd800 && point < 0xdc00 && at_ + 6 <= text_.size() && text_[at_] == '\\' &&
              text_[at_ + 1] == 'u') {
            at_ += 2;
            point = 0x10000 + ((point - 0xd800) << 10) + (hex4() - 0xdc00);
          }
          put_utf8(out, point);
          break;
        }
        default:
          out += e;
      }
    }
    expect('"');
    return out;
  }

  std::string_view text_;
  std::size_t at_ = 0;
};

std::string hex_of(std::string_view bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (const char c : bytes) {
    out += kDigits[static_cast<unsigned char>(c) >> 4];
    out += kDigits[static_cast<unsigned char>(c) & 0xf];
  }
  return out;
}

std::string bytes_of_hex(std::string_view hex) {
  const auto digit = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  if (hex.size() % 2 != 0) {
    throw std::invalid_argument(
        "a HORUS identity whose description is an odd number of hex digits");
  }
  std::string out(hex.size() / 2, '\0');
  for (std::size_t i = 0; i < out.size(); ++i) {
    const int high = digit(hex[2 * i]);
    const int low = digit(hex[2 * i + 1]);
    if (high < 0 || low < 0) {
      throw std::invalid_argument("a HORUS identity whose description is not hex");
    }
    out[i] = static_cast<char>(high << 4 | low);
  }
  return out;
}

// The value of `key`, which must be there (`what`: the kind of identity, for the error).
std::string& field_of(std::map<std::string, std::string>& fields, const std::string& key,
                      const char* what) {
  const auto found = fields.find(key);
  if (found == fields.end()) {
    throw std::invalid_argument(std::string(what) + " without its \"" + key + "\"");
  }
  return found->second;
}

std::uint64_t fingerprint_of(const std::string& fingerprint, const char* what) {
  std::size_t used = 0;
  std::uint64_t value = 0;
  try {
    value = std::stoull(fingerprint, &used, 16);
  } catch (const std::exception&) {
    used = 0;
  }
  if (fingerprint.empty() || used != fingerprint.size()) {
    throw std::invalid_argument(std::string(what) +
                                " whose fingerprint is not hex: " + fingerprint);
  }
  return value;
}

}  // namespace

std::string identity_user_data(const WriterIdentity& identity) {
  std::string out = "{\"type\": ";
  put_string(out, identity.topic.type_name);
  out += ", \"fingerprint\": ";
  put_string(out, bridge::fingerprint_hex(identity.topic.fingerprint));
  out += ", \"schema\": ";
  put_string(out, identity.topic.schema);
  out += ", \"description\": ";
  put_string(out, hex_of(identity.description));
  out += '}';
  return out;
}

std::optional<WriterIdentity> parse_identity_user_data(std::string_view user_data) {
  if (user_data.empty()) {
    return std::nullopt;
  }
  std::map<std::string, std::string> fields = Reader(user_data).object();
  constexpr const char* kWhat = "a HORUS identity";
  WriterIdentity out;
  out.topic.type_name = std::move(field_of(fields, "type", kWhat));
  out.topic.fingerprint = fingerprint_of(field_of(fields, "fingerprint", kWhat), kWhat);
  out.topic.schema = std::move(field_of(fields, "schema", kWhat));
  if (fields.contains("description")) {
    out.description = bytes_of_hex(fields["description"]);
  }
  return out;
}

std::string service_user_data(const ServiceIdentity& identity) {
  std::string out = "{\"service\": ";
  put_string(out, identity.service);
  out += ", \"fingerprint\": ";
  put_string(out, bridge::fingerprint_hex(identity.fingerprint));
  for (const auto& [prefix, type] :
       {std::pair{"request_", &identity.request}, std::pair{"response_", &identity.response}}) {
    const std::string key = std::string(", \"") + prefix;
    out += key + "type\": ";
    put_string(out, type->name);
    out += key + "fingerprint\": ";
    put_string(out, bridge::fingerprint_hex(type->fingerprint));
    out += key + "schema\": ";
    put_string(out, type->schema);
    out += key + "description\": ";
    put_string(out, hex_of(type->description));
  }
  out += '}';
  return out;
}

ServiceIdentity parse_service_user_data(std::string_view user_data) {
  std::map<std::string, std::string> fields = Reader(user_data).object();
  constexpr const char* kWhat = "a HORUS service identity";
  ServiceIdentity out;
  out.service = std::move(field_of(fields, "service", kWhat));
  out.fingerprint = fingerprint_of(field_of(fields, "fingerprint", kWhat), kWhat);
  for (const auto& [prefix, type] :
       {std::pair{"request_", &out.request}, std::pair{"response_", &out.response}}) {
    const std::string key = prefix;
    type->name = std::move(field_of(fields, key + "type", kWhat));
    type->fingerprint = fingerprint_of(field_of(fields, key + "fingerprint", kWhat), kWhat);
    type->schema = std::move(field_of(fields, key + "schema", kWhat));
    type->description = bytes_of_hex(field_of(fields, key + "description", kWhat));
    const TypeDescription description =
        TypeDescription::decode(std::string_view(type->description));
    const MessageType& message = description.root_message();
    if (message.name != type->name || message.fingerprint != type->fingerprint) {
      throw std::invalid_argument(std::string(kWhat) + " whose " + prefix + "description is of " +
                                  message.name + ", not " + type->name);
    }
    type->is_pod = message.is_pod;
    type->size = message.size;
    type->alignment = message.is_pod ? message.alignment : 1;
  }
  return out;
}

}  // namespace horus::dds_bridge
