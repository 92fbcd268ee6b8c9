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
//
// Actions (docs/dds-bridge.md, "Actions"): a local action server's A.send_goal, A.cancel_goal,
// A.get_result, A.feedback and A.status (runtime/src/action/README.md) served to ROS 2 action
// clients as ROS 2 names and shapes them: rq/A/_action/send_goalRequest and the rest, with
// <pkg>::dds_::A_SendGoal_Request_ ..., action_msgs' CancelGoal and GoalStatusArray. One thread
// per action calls the local services with RawServiceClients and keeps the goals' states for the
// status array. Imported the other way: a ROS 2 action server on DDS (its send_goal reply writer
// discovered) gets RawServiceServers of the three services and the three topics here, one thread
// per action relaying each call to DDS, asking ROS 2's get_result for each accepted goal (whose
// answer, when the goal ends, becomes A.result and the last A.status), and following its feedback
// and GoalStatusArray.
#pragma once

#include <array>
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
#include "horus/service_registry.hpp"

namespace horus::dds_bridge {

using dds::TypeLookup;

/// The type a carried description (TypeInfo<T>::description, a Python class's) is of; throws
/// horus::TypeDescriptionError for bytes that are no carried description of a message.
TypeIdentity described_type(std::string description);

/// The service half of a DdsBridge: exported and imported services by pattern, each on a thread
/// of its own; scan() (the bridge's thread, every half second) starts and ends them.
class ServiceRelays {
 public:
  /// `export_actions`: patterns of local actions served to ROS 2 action clients;
  /// `import_actions`: of ROS 2 action servers on DDS served to local action clients.
  ServiceRelays(std::vector<std::string> exports, std::vector<std::string> imports,
                std::vector<std::string> export_actions, std::vector<std::string> import_actions,
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
  struct ActionParts;
  class ExportedAction;
  class ImportedAction;

  void scan_exports();
  void scan_imports();
  void scan_action_imports(const std::vector<Publication>& publications);
  void import_action(const std::string& name, const std::string& response_type);
  void export_service(const std::string& name, const std::string& request_type,
                      const std::string& response_type, std::uint64_t fingerprint);
  void import_service(const std::string& name, const Publication& publication);
  /// The request and response types of a local service (empty while they cannot be known yet).
  std::optional<std::pair<TypeIdentity, TypeIdentity>> service_types(
      const std::string& name, const std::string& request_type, const std::string& response_type);
  void scan_actions(const std::vector<ServiceInfo>& services);
  /// Fills `parts`' payload types from the type names of send_goal, cancel_goal and get_result
  /// (request and response each); false while they cannot be known yet.
  bool action_service_types(const std::string& name, const std::array<std::string, 6>& types,
                            ActionParts& parts);
  std::optional<TypeIdentity> topic_type(const std::string& topic, const std::string& type);
  void export_action(const std::string& name, const ServiceInfo& send_goal,
                     const ServiceInfo& cancel_goal, const ServiceInfo& get_result);

  bridge::TopicPolicy policy_;  // export_services and import_services
  bool exporting_actions_;
  bool importing_actions_;
  bridge::TopicPolicy action_policy_;  // export_actions and import_actions
  std::chrono::duration<double> call_timeout_;
  std::string namespace_;
  std::shared_ptr<Participant> participant_;
  Qos qos_;
  TypeLookup lookup_;
  std::map<std::string, std::unique_ptr<Exported>> exported_;
  std::map<std::string, std::unique_ptr<Imported>> imported_;
  std::map<std::string, std::unique_ptr<ExportedAction>> exported_actions_;
  std::map<std::string, std::unique_ptr<ImportedAction>> imported_actions_;
  std::set<std::string> refused_;
  std::set<std::string> refused_actions_;
};

}  // namespace horus::dds_bridge
