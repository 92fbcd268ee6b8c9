// The HORUS identity an exporting bridge's DDS writer carries in its user data, so a bridge on
// another host can create the local topic without knowing the type beforehand: a JSON object
// {"type": NAME, "fingerprint": 16 HEX DIGITS, "schema": TEXT, "description": HEX}, the type
// description's bytes in hex (Python's bridge writes and reads the same).
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "horus/bridge/identity.hpp"
#include "horus/raw_topic.hpp"

namespace horus::dds_bridge {

struct WriterIdentity {
  bridge::TopicIdentity topic;
  std::string description;  // the type description's bytes (empty: the writer sent none)
};

/// The user data of a writer of `identity`.
std::string identity_user_data(const WriterIdentity& identity);

/// The identity in a writer's user data; nothing when it carries none (empty: a plain DDS
/// program's writer). Throws std::invalid_argument for user data of another shape.
std::optional<WriterIdentity> parse_identity_user_data(std::string_view user_data);

/// What an exporting bridge's service reply writer carries in its user data: a flat JSON object
/// of the service's name and fingerprint and, for its request and response, the payload type's
/// name, fingerprint (16 hex digits), schema text and description (hex), under keys prefixed
/// "request_" and "response_".
struct ServiceIdentity {
  std::string service;
  std::uint64_t fingerprint = 0;
  TypeIdentity request;
  TypeIdentity response;
};

std::string service_user_data(const ServiceIdentity& identity);
/// Throws std::invalid_argument for user data of another shape (horus::TypeDescriptionError for
/// a description that does not decode).
ServiceIdentity parse_service_user_data(std::string_view user_data);

}  // namespace horus::dds_bridge
