// Services across DDS (docs/dds-bridge.md, "Services"): a service S crosses as ROS 2's pair of
// DDS topics, requests on rq/SRequest (type <pkg>::dds_::S_Request_) and replies on rr/SReply
// (<pkg>::dds_::S_Response_). As rmw_cyclonedds does, each sample starts (after the 4-byte
// encapsulation) with a request header of two 8-byte fields, the caller's id (u64) and the call's
// sequence number (i64), then the message's CDR body; a reply repeats its request's header. The
// raw CDR endpoints give no sample identity to write, so the header is in the data. A call the
// exporting side could not answer (the server's failure, no server, a timeout there) is replied
// with the sequence number negated and a CDR string "<Kind>: <text>" (ServiceError::to_string)
// instead of the response (a ROS 2 client ignores it, and times out); the importing side fails
// its caller with that kind.
//
// Exporting: a local service's live server answers calls from DDS through a RawServiceClient on
// the worker of a bridge::LocalServiceCaller (bridges/core), which writes each reply.
// Importing: a service an exporting bridge offers on DDS (its reply writer's user data names the
// service and both payload types, with their descriptions) gets a RawServiceServer here that
// relays each call to DDS.
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "horus/bridge/topic_policy.hpp"
#include "horus/dds/endpoints.hpp"
#include "horus/dds/user_data.hpp"
#include "horus/dds_bridge.hpp"

namespace horus::dds_bridge {

using dds::TypeLookup;

/// The type a carried description (TypeInfo<T>::description, a Python class's) is of; throws
/// horus::TypeDescriptionError for bytes that are no carried description of a message.
TypeIdentity described_type(std::string description);

/// The service half of a DdsBridge: exported and imported services by pattern, each on a thread
/// of its own; scan() (the bridge's thread, every half second) starts and ends them.
class ServiceRelays {
 public:
  ServiceRelays(std::vector<std::string> exports, std::vector<std::string> imports,
                std::chrono::duration<double> call_timeout, std::string namespace_name,
                std::shared_ptr<Participant> participant, Qos qos, TypeLookup lookup);
  /// Stops every relay; imported services are withdrawn (local callers get NoServer).
  ~ServiceRelays();
  ServiceRelays(const ServiceRelays&) = delete;
  ServiceRelays& operator=(const ServiceRelays&) = delete;

  void scan();

 private:
  class Exported;
  class Imported;

  void scan_exports();
  void scan_imports();
  void export_service(const std::string& name, const std::string& request_type,
                      const std::string& response_type, std::uint64_t fingerprint);
  void import_service(const std::string& name, const Publication& publication);

  bridge::TopicPolicy policy_;  // export_services and import_services
  std::chrono::duration<double> call_timeout_;
  std::string namespace_;
  std::shared_ptr<Participant> participant_;
  Qos qos_;
  TypeLookup lookup_;
  std::map<std::string, std::unique_ptr<Exported>> exported_;
  std::map<std::string, std::unique_ptr<Imported>> imported_;
  std::set<std::string> refused_;
};

}  // namespace horus::dds_bridge
