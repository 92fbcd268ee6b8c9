// The type descriptions of plain values (horus/plain_value.hpp): a plain value is on the wire
// what the message `PlainValue { value: <name> }` is, so it is described as that message, named,
// fingerprinted and with the schema text of the plain value's own identity. horus._values
// (Python) builds the same tree and bytes.
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <utility>

#include "horus/plain_value.hpp"

namespace horus::detail {

namespace {

using Packer = msgpack::packer<msgpack::sbuffer>;

void text(Packer& packer, std::string_view value) {
  packer.pack_str(static_cast<std::uint32_t>(value.size()));
  packer.pack_str_body(value.data(), static_cast<std::uint32_t>(value.size()));
}

/// The summary line horus::log_summary() prints for a plain value: the value alone, with the
/// element label of its `[N x label]` form.
std::string value_summary(std::string_view label) {
  msgpack::sbuffer buffer;
  Packer packer(buffer);
  packer.pack_array(1);
  packer.pack_map(3);
  text(packer, "field");
  text(packer, "value");
  text(packer, "label");
  text(packer, label);
  text(packer, "unit");
  text(packer, "");
  return std::string(buffer.data(), buffer.size());
}

}  // namespace

std::string plain_value_description(std::string_view name, const TypeRef& value_type,
                                    std::string_view label, std::size_t size,
                                    std::size_t alignment) {
  MessageType message;
  message.name = name;
  message.schema =
      std::string(kPlainValueSchemaOpen) + std::string(name) + std::string(kPlainValueSchemaClose);
  message.fingerprint = fnv1a(message.schema);
  message.is_pod = size != 0;
  MessageField value;
  value.name = "value";
  value.type = value_type;
  value.spelling = name;
  if (message.is_pod) {
    // One field at offset 0 filling the value: a plain value's bytes are the value's, no padding.
    message.size = size;
    message.alignment = alignment;
    value.offset = 0;
    value.size = size;
  }
  message.fields.push_back(std::move(value));
  message.summary = value_summary(label);
  TypeDescription description;
  description.root = message.name;
  description.messages.push_back(std::move(message));
  return description.encode();
}

}  // namespace horus::detail
