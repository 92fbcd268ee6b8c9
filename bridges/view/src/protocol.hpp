// The Foxglove WebSocket protocol's messages as the live view writes and reads them
// (github.com/foxglove/ws-protocol, docs/spec.md): the server's JSON messages built as text, its
// binary ones as bytes, and the client's JSON messages read through Cap'n Proto's JSON parser.
#pragma once

#include <capnp/compat/json.capnp.h>
#include <capnp/compat/json.h>
#include <capnp/message.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "horus/view/codecs.hpp"

namespace horus::view {

/// The subprotocols a client may offer; the one it offered first is answered.
inline constexpr std::string_view kSubprotocols[] = {"foxglove.websocket.v1", "foxglove.sdk.v1"};

/// Binary opcodes, server to client and client to server.
enum class ServerOpcode : std::uint8_t { MessageData = 1, Time = 2, ServiceCallResponse = 3 };
enum class ClientOpcode : std::uint8_t { MessageData = 1, ServiceCallRequest = 2 };

/// Bytes before a Message Data's payload: opcode, subscription id, receive time.
inline constexpr std::size_t kMessageDataHeader = 1 + 4 + 8;

/// A client message the server cannot act on, with the reason the client is told (a status).
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The subprotocol of `offered` (a Sec-WebSocket-Protocol header: comma separated) the server
/// speaks, the first offered that is one of kSubprotocols; none when none is.
std::optional<std::string> choose_subprotocol(std::string_view offered);

/// A channel as advertised.
struct Channel {
  std::uint32_t id = 0;
  std::string topic;
  ChannelSchema schema;
};

enum class StatusLevel { Info = 0, Warning = 1, Error = 2 };

std::string server_info(const std::string& name, const std::vector<std::string>& capabilities,
                        const std::string& session_id, const std::string& namespace_name);
/// An advertise of `channels` (an empty list too: a new client is always sent one).
std::string advertise(const std::vector<const Channel*>& channels);
std::string unadvertise(const std::vector<std::uint32_t>& channel_ids);
std::string status(StatusLevel level, const std::string& message);

/// The Message Data of `payload` for `subscription` into `out` (overwritten; its capacity is
/// reused, and grown only for a larger message than any before).
void message_data(std::uint32_t subscription, std::uint64_t receive_time_ns,
                  std::span<const std::byte> payload, std::vector<std::byte>& out);
/// A Time message.
std::string time_message(std::uint64_t time_ns);
/// An advertiseServices of `services` (each an entry as ViewService::advertisement() writes it).
std::string advertise_services(const std::vector<std::string>& services);
std::string unadvertise_services(const std::vector<std::uint32_t>& service_ids);
/// A Service Call Response (binary) with the response's payload in `encoding`.
std::string service_call_response(std::uint32_t service, std::uint32_t call,
                                  std::string_view encoding, std::span<const std::byte> payload);
std::string service_call_failure(std::uint32_t service, std::uint32_t call,
                                 const std::string& message);

/// A parameterValues of `entries` (each as parameter_entry() writes it), answering the request
/// `id` when there is one.
std::string parameter_values(const std::vector<std::string>& entries,
                             const std::optional<std::string>& id);

/// Little-endian integers of a binary client message.
std::uint32_t read_u32(std::span<const std::byte> bytes, std::size_t offset);

/// A JSON text, parsed. Throws ProtocolError on text that is not JSON.
class JsonDocument {
 public:
  explicit JsonDocument(std::string_view text);
  JsonDocument(const JsonDocument&) = delete;
  JsonDocument& operator=(const JsonDocument&) = delete;

  capnp::json::Value::Reader root() const { return root_; }

 private:
  capnp::MallocMessageBuilder arena_;
  capnp::json::Value::Reader root_;
};

/// A client's JSON message, parsed. Throws ProtocolError on text that is not a JSON object with
/// a string "op".
class ClientMessage {
 public:
  explicit ClientMessage(std::string_view text);

  const std::string& op() const noexcept { return op_; }
  capnp::json::Value::Reader root() const { return document_.root(); }

 private:
  JsonDocument document_;
  std::string op_;
};

/// A connection graph (the spec's Connection Graph Update): who publishes and subscribes to each
/// topic, who provides each service, by id.
struct ConnectionGraph {
  std::map<std::string, std::set<std::string>> publishers;
  std::map<std::string, std::set<std::string>> subscribers;
  std::map<std::string, std::set<std::string>> providers;

  bool operator==(const ConnectionGraph&) const = default;
};

/// The update that turns `before` into `after` (the whole of `after` when `before` is empty).
std::string connection_graph_update(const ConnectionGraph& before, const ConnectionGraph& after);

/// The member `name` of a JSON object; none when absent (or null).
std::optional<capnp::json::Value::Reader> member(capnp::json::Value::Reader object,
                                                 std::string_view name);
/// The member as a list / a whole number in [0, 2^32) / a number / a string; ProtocolError
/// naming `what` and the member when it is absent or of another kind.
capnp::List<capnp::json::Value>::Reader array_member(capnp::json::Value::Reader object,
                                                     std::string_view name, std::string_view what);
std::uint32_t id_member(capnp::json::Value::Reader object, std::string_view name,
                        std::string_view what);
std::optional<double> optional_number_member(capnp::json::Value::Reader object,
                                             std::string_view name, std::string_view what);
std::string string_member(capnp::json::Value::Reader object, std::string_view name,
                          std::string_view what);
/// A list element that must be a whole number in [0, 2^32).
std::uint32_t id_value(capnp::json::Value::Reader value, std::string_view what);

}  // namespace horus::view
