// The type descriptions of the types the service layer defines itself (detail/service_frame.hpp,
// horus/service_registration.hpp), in the format horus-gen writes for generated types
// (docs/type-description.md): a frame's built from its payload's description, so tools decode,
// print and write frames as they do any message. Each entry is what horus-gen gives for the same
// schema text (its layout, and the summary it makes when a message declares none), named and
// fingerprinted as the runtime names them; horus.typedesc (Python) builds the same trees.
#include <msgpack/pack.hpp>
#include <msgpack/sbuffer.hpp>

#include <algorithm>
#include <utility>

#include "horus/detail/service_frame.hpp"
#include "horus/type_description.hpp"

namespace horus::detail {

namespace {

std::size_t aligned(std::size_t value, std::size_t alignment) {
  return (value + alignment - 1) / alignment * alignment;
}

TypeRef primitive(Primitive kind) {
  TypeRef type;
  type.kind = TypeRef::Kind::Primitive;
  type.primitive = kind;
  return type;
}

TypeRef fixed_string(std::size_t capacity) {
  TypeRef type;
  type.kind = TypeRef::Kind::FixedString;
  type.length = capacity;
  return type;
}

TypeRef message_ref(const TypeDescription& description, const MessageType& message) {
  TypeRef type;
  type.kind = TypeRef::Kind::Message;
  type.name = message.name;
  type.index = static_cast<std::size_t>(&message - description.messages.data());
  return type;
}

MessageField field(std::string name, TypeRef type, std::string spelling) {
  MessageField out;
  out.name = std::move(name);
  out.type = std::move(type);
  out.spelling = std::move(spelling);
  return out;
}

/// Size and alignment of a field of a POD message.
std::pair<std::size_t, std::size_t> pod_layout(const TypeDescription& description,
                                               const TypeRef& type) {
  switch (type.kind) {
    case TypeRef::Kind::Primitive:
      return {primitive_size(type.primitive), primitive_size(type.primitive)};
    case TypeRef::Kind::FixedString:
      return {type.length, 1};
    default: {
      const MessageType& message = description.message(type);
      return {message.size, message.alignment};
    }
  }
}

/// The C++ layout of a POD message's fields, in order, each at its alignment: offsets, size,
/// alignment and the padding between and after them (what horus-gen computes).
void lay_out(const TypeDescription& description, MessageType& message) {
  std::size_t end = 0;
  std::size_t alignment = 1;
  for (MessageField& each : message.fields) {
    const auto [size, align] = pod_layout(description, each.type);
    const std::size_t offset = aligned(end, align);
    if (offset > end) message.padding.push_back(PaddingRange{end, offset - end});
    each.offset = offset;
    each.size = size;
    end = offset + size;
    alignment = std::max(alignment, align);
  }
  message.alignment = alignment;
  message.size = aligned(end, alignment);
  if (message.size > end) message.padding.push_back(PaddingRange{end, message.size - end});
}

/// The summary horus-gen makes for a message without #[summary]: "Name{a: <a>, b: <b>}".
std::string default_summary(const MessageType& message) {
  msgpack::sbuffer buffer;
  msgpack::packer<msgpack::sbuffer> packer(buffer);
  const auto text_part = [&](const std::string& text) {
    packer.pack_map(1);
    packer.pack(std::string("text"));
    packer.pack(text);
  };
  packer.pack_array(static_cast<std::uint32_t>(2 * message.fields.size() + 1));
  const std::string short_name = message.name.substr(0, message.name.find('<'));
  std::string before = short_name.substr(short_name.rfind('.') + 1) + "{";
  for (const MessageField& each : message.fields) {
    text_part(before + each.name + ": ");
    packer.pack_map(3);
    packer.pack(std::string("field"));
    packer.pack(each.name);
    packer.pack(std::string("label"));
    packer.pack(std::string());
    packer.pack(std::string("unit"));
    packer.pack(std::string());
    before = ", ";
  }
  text_part("}");
  return std::string(buffer.data(), buffer.size());
}

/// `message`, with its layout and summary, as the root of `description`: its encoding.
std::string described_root(TypeDescription& description, MessageType message) {
  if (message.is_pod) lay_out(description, message);
  message.summary = default_summary(message);
  description.root = message.name;
  description.messages.push_back(std::move(message));
  return description.encode();
}

}  // namespace

std::string service_frame_name(std::string_view payload_name, bool response) {
  return std::string(response ? kResponseFrameName : kRequestFrameName) +
         std::string(payload_name) + std::string(kNameClose);
}

std::string service_frame_schema(std::string_view payload_name, std::string_view payload_schema,
                                 bool response, bool pod) {
  const std::string_view fields = !response ? kRequestFrameFields
                                  : pod     ? kResponseFrameFieldsPod
                                            : kResponseFrameFieldsSerialized;
  return std::string(kSchemaOpen) + service_frame_name(payload_name, response) +
         std::string(fields) + std::string(payload_name) + std::string(kSchemaClose) +
         std::string(payload_schema);
}

std::string service_frame_description(std::string_view payload_name,
                                      std::string_view payload_description, bool response) {
  if (payload_description.empty()) {
    throw TypeDescriptionError("the description of " + std::string(payload_name) +
                               "'s service frames: the payload carries no description");
  }
  TypeDescription description = TypeDescription::decode(payload_description);
  if (description.root != payload_name) {
    throw TypeDescriptionError("the description of " + std::string(payload_name) +
                               "'s service frames: the payload's description is of " +
                               (description.root.empty() ? "no root" : description.root));
  }
  const MessageType& payload = description.root_message();
  MessageType frame;
  frame.name = service_frame_name(payload.name, response);
  frame.package = "horus";
  frame.is_pod = payload.is_pod;
  frame.schema = service_frame_schema(payload.name, payload.schema, response, payload.is_pod);
  frame.fingerprint = fnv1a(frame.schema);
  frame.fields.push_back(field("client_id", primitive(Primitive::U64), "u64"));
  frame.fields.push_back(field("request_id", primitive(Primitive::U64), "u64"));
  if (response) {
    frame.fields.push_back(field("status", primitive(Primitive::U32), "u32"));
    if (payload.is_pod) {
      frame.fields.push_back(field("error", fixed_string(kPodErrorCapacity),
                                   "string<" + std::to_string(kPodErrorCapacity) + ">"));
    } else {
      TypeRef text;
      text.kind = TypeRef::Kind::String;
      frame.fields.push_back(field("error", std::move(text), "String"));
    }
  } else {
    frame.fields.push_back(field("reply_to", primitive(Primitive::U64), "u64"));
  }
  frame.fields.push_back(field("payload", message_ref(description, payload), payload.name));
  return described_root(description, std::move(frame));
}

std::string service_registration_description() {
  using Info = TypeInfo<ServiceRegistration>;
  TypeDescription description;
  MessageType registration;
  registration.name = Info::name;
  registration.package = Info::package;
  registration.is_pod = true;
  registration.schema = Info::schema;
  registration.fingerprint = Info::fingerprint;
  const std::string text = "string<256>";
  registration.fields = {field("server_instance", primitive(Primitive::U64), "u64"),
                         field("fingerprint", primitive(Primitive::U64), "u64"),
                         field("request_type", fixed_string(256), text),
                         field("response_type", fixed_string(256), text),
                         field("server_pid", primitive(Primitive::U64), "u64")};
  return described_root(description, std::move(registration));
}

}  // namespace horus::detail
