// horus::dds::DdsBridge: the DDS bridge (docs/dds-bridge.md) inside a process: local topics of a
// HORUS namespace to Eclipse Cyclone DDS and back, on threads of its own, with the options of
// `horus bridge` (horus::Network). What a C++ scheduler runs for SchedulerConfig::network() when
// the program links horus::dds.
//
// It says nothing when it starts (its user does: `horus bridge`'s line, or the scheduler's
// runner's). Every half second it looks for local topics an export pattern names and for DDS
// publications
// an import pattern names, and carries each on a thread of its own (a pump: CDR from the type
// description, no schema text parsed). It says on stdout each topic it carries and on
// stderr each it refuses, and carries the others. A carried topic's failures are lines and
// retries; a bug of the bridge (a pump that throws) stops it: `on_failure` gets the reason.
//
// Services cross too (horus/dds/services.hpp), topics ros2_types names as their standard
// type's ROS 2 twin (horus/dds/ros2_twins.hpp), and the namespace's coordinate frames as ROS 2's
// /tf and /tf_static (horus/dds/frames.hpp).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "horus/network.hpp"
#include "horus/raw_topic.hpp"

namespace horus::dds {

/// A generated message type by its HORUS name, when the process knows it (Python's bridge looks
/// on the Python path): how an exporting bridge learns a service's response type before any
/// local client called the service (until then no reply topic holds it).
using TypeLookup = std::function<std::optional<TypeIdentity>(const std::string& type_name)>;

class DdsBridge {
 public:
  /// Starts the bridge on `options` (valid: detail::check_network) for `namespace_name` (empty:
  /// HORUS_NAMESPACE); throws horus::Error when it cannot (no DDS participant, an option it does
  /// not carry yet). `on_failure` runs once, on the bridge's thread, if the bridge stops on its
  /// own (a bug of its own, said on stderr); it may not destroy the bridge. `find_type`:
  /// generated message types by name, for an exported service whose response type no reply
  /// topic shows yet (none: such a service is exported once a local call made one).
  DdsBridge(Network options, std::string namespace_name,
            std::function<void(const std::string&)> on_failure, TypeLookup find_type = {});
  /// Stops it (stop()).
  ~DdsBridge();
  DdsBridge(const DdsBridge&) = delete;
  DdsBridge& operator=(const DdsBridge&) = delete;

  /// Stops every carried topic and the bridge's thread, deletes its DDS entities (peers see its
  /// writers go) and returns once all are gone. Idempotent.
  void stop();

 private:
  class Running;
  std::unique_ptr<Running> running_;
};

/// Makes SchedulerConfig::network() run a DdsBridge. Linking horus::dds does it (a source of the
/// target's own registers it when the program starts); a program can call it too.
void enable_network_bridge() noexcept;

}  // namespace horus::dds
