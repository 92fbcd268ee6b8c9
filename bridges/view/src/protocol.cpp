#include "protocol.hpp"

#include <kj/encoding.h>
#include <kj/exception.h>

#include <cmath>
#include <cstring>
#include <iterator>

#include "horus/json_string.hpp"

namespace horus::view {

namespace {

std::string_view trimmed(std::string_view text) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  const auto last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

void append_u32(std::vector<std::byte>& out, std::size_t at, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out[at + i] = static_cast<std::byte>(value >> (8 * i));
}

void append_u64(std::vector<std::byte>& out, std::size_t at, std::uint64_t value) {
  for (int i = 0; i < 8; ++i) out[at + i] = static_cast<std::byte>(value >> (8 * i));
}

std::string json_list(const std::vector<std::string>& items) {
  std::string out = "[";
  for (const std::string& item : items) {
    if (out.size() > 1) out += ",";
    out += json_string(item);
  }
  return out + "]";
}

std::string what_member(std::string_view what, std::string_view name) {
  return std::string(what) + " needs \"" + std::string(name) + "\"";
}

}  // namespace

std::optional<std::string> choose_subprotocol(std::string_view offered) {
  while (!offered.empty()) {
    const auto comma = offered.find(',');
    const std::string_view one = trimmed(offered.substr(0, comma));
    for (const std::string_view spoken : kSubprotocols) {
      if (one == spoken) return std::string(spoken);
    }
    if (comma == std::string_view::npos) break;
    offered.remove_prefix(comma + 1);
  }
  return std::nullopt;
}

std::string server_info(const std::string& name, const std::vector<std::string>& capabilities,
                        const std::string& session_id, const std::string& namespace_name) {
  return "{\"op\":\"serverInfo\",\"name\":" + json_string(name) +
         ",\"capabilities\":" + json_list(capabilities) +
         ",\"supportedEncodings\":[\"json\"],\"metadata\":{\"namespace\":" +
         json_string(namespace_name) + "},\"sessionId\":" + json_string(session_id) + "}";
}

std::string advertise(const std::vector<const Channel*>& channels) {
  std::string out = "{\"op\":\"advertise\",\"channels\":[";
  bool first = true;
  for (const Channel* channel : channels) {
    if (!first) out += ",";
    first = false;
    const ChannelSchema& schema = channel->schema;
    // A binary schema (a protobuf FileDescriptorSet) travels base64'd, as the spec's example.
    const std::string schema_text =
        schema.schema_is_binary
            ? std::string(kj::encodeBase64(
                              kj::arrayPtr(reinterpret_cast<const kj::byte*>(schema.schema.data()),
                                           schema.schema.size()))
                              .cStr())
            : schema.schema;
    out += "{\"id\":" + std::to_string(channel->id) + ",\"topic\":" + json_string(channel->topic) +
           ",\"encoding\":" + json_string(schema.encoding) +
           ",\"schemaName\":" + json_string(schema.schema_name) +
           ",\"schemaEncoding\":" + json_string(schema.schema_encoding) +
           ",\"schema\":" + json_string(schema_text) + "}";
  }
  return out + "]}";
}

std::string unadvertise(const std::vector<std::uint32_t>& channel_ids) {
  std::string out = "{\"op\":\"unadvertise\",\"channelIds\":[";
  for (std::size_t i = 0; i < channel_ids.size(); ++i) {
    if (i != 0) out += ",";
    out += std::to_string(channel_ids[i]);
  }
  return out + "]}";
}

std::string status(StatusLevel level, const std::string& message) {
  return "{\"op\":\"status\",\"level\":" + std::to_string(static_cast<int>(level)) +
         ",\"message\":" + json_string(message) + "}";
}

void message_data(std::uint32_t subscription, std::uint64_t receive_time_ns,
                  std::span<const std::byte> payload, std::vector<std::byte>& out) {
  std::byte header[kMessageDataHeader];
  header[0] = static_cast<std::byte>(ServerOpcode::MessageData);
  for (int i = 0; i < 4; ++i) header[1 + i] = static_cast<std::byte>(subscription >> (8 * i));
  for (int i = 0; i < 8; ++i) header[5 + i] = static_cast<std::byte>(receive_time_ns >> (8 * i));
  // Appended into the kept capacity: a resize() first would zero-fill what the copy overwrites.
  out.clear();
  out.reserve(kMessageDataHeader + payload.size());
  out.insert(out.end(), std::begin(header), std::end(header));
  out.insert(out.end(), payload.begin(), payload.end());
}

std::string time_message(std::uint64_t time_ns) {
  std::vector<std::byte> bytes(1 + 8);
  bytes[0] = static_cast<std::byte>(ServerOpcode::Time);
  append_u64(bytes, 1, time_ns);
  return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

std::string advertise_services(const std::vector<std::string>& services) {
  std::string out = "{\"op\":\"advertiseServices\",\"services\":[";
  for (std::size_t i = 0; i < services.size(); ++i) {
    if (i != 0) out += ",";
    out += services[i];
  }
  return out + "]}";
}

std::string unadvertise_services(const std::vector<std::uint32_t>& service_ids) {
  std::string out = "{\"op\":\"unadvertiseServices\",\"serviceIds\":[";
  for (std::size_t i = 0; i < service_ids.size(); ++i) {
    if (i != 0) out += ",";
    out += std::to_string(service_ids[i]);
  }
  return out + "]}";
}

std::string service_call_response(std::uint32_t service, std::uint32_t call,
                                  std::string_view encoding, std::span<const std::byte> payload) {
  std::vector<std::byte> bytes(1 + 4 + 4 + 4);
  bytes[0] = static_cast<std::byte>(ServerOpcode::ServiceCallResponse);
  append_u32(bytes, 1, service);
  append_u32(bytes, 5, call);
  append_u32(bytes, 9, static_cast<std::uint32_t>(encoding.size()));
  std::string out(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  out.append(encoding);
  out.append(reinterpret_cast<const char*>(payload.data()), payload.size());
  return out;
}

std::string service_call_failure(std::uint32_t service, std::uint32_t call,
                                 const std::string& message) {
  return "{\"op\":\"serviceCallFailure\",\"serviceId\":" + std::to_string(service) +
         ",\"callId\":" + std::to_string(call) + ",\"message\":" + json_string(message) + "}";
}

std::string parameter_values(const std::vector<std::string>& entries,
                             const std::optional<std::string>& id) {
  std::string out = "{\"op\":\"parameterValues\",\"parameters\":[";
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (i != 0) out += ",";
    out += entries[i];
  }
  out += "]";
  if (id) out += ",\"id\":" + json_string(*id);
  return out + "}";
}

std::uint32_t read_u32(std::span<const std::byte> bytes, std::size_t offset) {
  std::uint32_t value = 0;
  for (int i = 0; i < 4; ++i) {
    value |= static_cast<std::uint32_t>(bytes[offset + i]) << (8 * i);
  }
  return value;
}

JsonDocument::JsonDocument(std::string_view text) {
  capnp::JsonCodec codec;
  auto root = arena_.initRoot<capnp::json::Value>();
  // Cap'n Proto reports malformed JSON as a kj::Exception: the client is told its text.
  KJ_IF_MAYBE (error, kj::runCatchingExceptions(
                          [&] { codec.decodeRaw(kj::arrayPtr(text.data(), text.size()), root); })) {
    throw ProtocolError("a message that is not JSON (" +
                        std::string(error->getDescription().cStr()) + ")");
  }
  root_ = root.asReader();
}

ClientMessage::ClientMessage(std::string_view text) : document_(text) {
  if (root().which() != capnp::json::Value::OBJECT) {
    throw ProtocolError("a JSON message that is not an object");
  }
  const auto op = member(root(), "op");
  if (!op || op->which() != capnp::json::Value::STRING) {
    throw ProtocolError("a JSON message without a string \"op\"");
  }
  op_ = op->getString().cStr();
}

std::string connection_graph_update(const ConnectionGraph& before, const ConnectionGraph& after) {
  // Entries that are new or changed (each replaces what the client knew), and names now gone.
  const auto changed = [](const std::map<std::string, std::set<std::string>>& old_map,
                          const std::map<std::string, std::set<std::string>>& new_map,
                          const char* ids_key) {
    std::set<std::string> names;
    for (const auto& [name, ids] : old_map) names.insert(name);
    for (const auto& [name, ids] : new_map) names.insert(name);
    std::string out = "[";
    const std::set<std::string> none;
    for (const std::string& name : names) {
      const auto old = old_map.find(name);
      const auto now = new_map.find(name);
      const std::set<std::string>& ids = now == new_map.end() ? none : now->second;
      if (old != old_map.end() && old->second == ids) continue;
      if (out.size() > 1) out += ",";
      out += "{\"name\":" + json_string(name) + ",\"" + ids_key +
             "\":" + json_list(std::vector<std::string>(ids.begin(), ids.end())) + "}";
    }
    return out + "]";
  };
  const auto gone =
      [](const std::vector<const std::map<std::string, std::set<std::string>>*>& old_maps,
         const std::vector<const std::map<std::string, std::set<std::string>>*>& new_maps) {
        std::set<std::string> names;
        for (const auto* old_map : old_maps) {
          for (const auto& [name, ids] : *old_map) {
            bool kept = false;
            for (const auto* new_map : new_maps) kept = kept || new_map->count(name) != 0;
            if (!kept) names.insert(name);
          }
        }
        return json_list(std::vector<std::string>(names.begin(), names.end()));
      };
  return "{\"op\":\"connectionGraphUpdate\",\"publishedTopics\":" +
         changed(before.publishers, after.publishers, "publisherIds") + ",\"subscribedTopics\":" +
         changed(before.subscribers, after.subscribers, "subscriberIds") +
         ",\"advertisedServices\":" + changed(before.providers, after.providers, "providerIds") +
         ",\"removedTopics\":" +
         gone({&before.publishers, &before.subscribers}, {&after.publishers, &after.subscribers}) +
         ",\"removedServices\":" + gone({&before.providers}, {&after.providers}) + "}";
}

std::optional<capnp::json::Value::Reader> member(capnp::json::Value::Reader object,
                                                 std::string_view name) {
  if (object.which() != capnp::json::Value::OBJECT) return std::nullopt;
  for (const auto field : object.getObject()) {
    if (std::string_view(field.getName().cStr()) == name) {
      if (field.getValue().which() == capnp::json::Value::NULL_) return std::nullopt;
      return field.getValue();
    }
  }
  return std::nullopt;
}

capnp::List<capnp::json::Value>::Reader array_member(capnp::json::Value::Reader object,
                                                     std::string_view name, std::string_view what) {
  const auto value = member(object, name);
  if (!value || value->which() != capnp::json::Value::ARRAY) {
    throw ProtocolError(what_member(what, name) + " as an array");
  }
  return value->getArray();
}

std::uint32_t id_value(capnp::json::Value::Reader value, std::string_view what) {
  if (value.which() != capnp::json::Value::NUMBER) {
    throw ProtocolError(std::string(what) + " needs ids that are numbers");
  }
  const double number = value.getNumber();
  if (!(number >= 0) || number > 4294967295.0 || std::floor(number) != number) {
    throw ProtocolError(std::string(what) + " needs ids that are whole numbers from 0 to 2^32-1");
  }
  return static_cast<std::uint32_t>(number);
}

std::uint32_t id_member(capnp::json::Value::Reader object, std::string_view name,
                        std::string_view what) {
  const auto value = member(object, name);
  if (!value) throw ProtocolError(what_member(what, name));
  return id_value(*value, std::string(what) + "'s \"" + std::string(name) + "\"");
}

std::optional<double> optional_number_member(capnp::json::Value::Reader object,
                                             std::string_view name, std::string_view what) {
  const auto value = member(object, name);
  if (!value) return std::nullopt;
  if (value->which() != capnp::json::Value::NUMBER) {
    throw ProtocolError(std::string(what) + "'s \"" + std::string(name) + "\" must be a number");
  }
  return value->getNumber();
}

std::string string_member(capnp::json::Value::Reader object, std::string_view name,
                          std::string_view what) {
  const auto value = member(object, name);
  if (!value || value->which() != capnp::json::Value::STRING) {
    throw ProtocolError(what_member(what, name) + " as a string");
  }
  return value->getString().cStr();
}

}  // namespace horus::view
