// horus::Network: topics, services and coordinate frames across hosts over Cyclone DDS from a
// scheduler, as `horus bridge` carries them (docs/dds-bridge.md); the C++ twin of Python's
// horus.Network.
//
//   horus::Scheduler sched{horus::SchedulerConfig{}.network(
//       {.export_ = {"cmd_*", "odom"}, .import_ = {"map"}, .domain = 7})};
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "horus/scheduler_companion.hpp"

namespace horus {

/// The options of `horus bridge`, named and ordered as horus.Network's keywords. Nothing crosses
/// that no pattern names (shell-style globs). The scheduler validates them when it is made and
/// runs the DDS bridge with them on threads of its own process, which takes linking horus::dds
/// (docs/dds-bridge.md, "From C++").
/// (Every field has an initializer, `{}` included, so that designated initializers may leave any
/// out without -Wmissing-field-initializers.)
struct Network {
  std::vector<std::string> export_{};  // local topics written to DDS (`export` is a C++ keyword)
  std::vector<std::string> import_{};  // DDS topics rt/a/b published into local topics a.b
  int domain = 0;                      // the DDS domain id, 0..232; both sides use the same one
  bool reliable = true;                // false: best-effort DDS endpoints
  int depth = 100;                     // the DDS history of each writer and reader, at least 1
  std::vector<std::string> transient_local{};  // latched topics (a late reader gets the last one)
  /// Topics that should carry a message at least this often (the first matching pattern counts);
  /// each half second in which one missed it is a line on stderr.
  std::vector<std::pair<std::string, std::chrono::milliseconds>> deadlines{};
  std::vector<std::string> export_services{};  // local services served on DDS
  std::vector<std::string> import_services{};  // services a bridge elsewhere exports
  /// How long an exported service's local server has to answer a call from DDS (then Timeout).
  std::chrono::duration<double> service_timeout{10.0};
  std::vector<std::string> ros2_types{};  // topics that cross as their standard type's ROS 2 twin
  /// Import from DDS writers that announce no XTypes type information (ROS 2 nodes), whose type
  /// DDS cannot check; else they are refused.
  bool accept_untyped_writers = false;
  /// Child frames of the namespace's frame tree written to DDS as ROS 2's /tf and /tf_static
  /// (tf2_msgs/msg/TFMessage), and those read from there into the tree (globs on child names).
  std::vector<std::string> export_frames{};
  std::vector<std::string> import_frames{};
  /// Local actions served to ROS 2 action clients on DDS (rq/A/_action/send_goalRequest, ...;
  /// docs/dds-bridge.md "Actions").
  std::vector<std::string> export_actions{};
  /// ROS 2 action servers on DDS offered to local action clients (docs/dds-bridge.md "Actions").
  std::vector<std::string> import_actions{};
};

namespace detail {

/// Throws horus::Error naming the first field of `network` the bridge would refuse.
void check_network(const Network& network);

/// Checks `network` and starts it; throws horus::Error when it is invalid, or when the program
/// was not linked with horus::dds.
std::unique_ptr<SchedulerCompanion> start_network(
    const Network& network, const std::string& namespace_name,
    std::function<void(const std::string&)> on_failure);

}  // namespace detail

}  // namespace horus
