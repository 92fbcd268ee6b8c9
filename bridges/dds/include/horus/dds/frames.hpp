// Coordinate frames over DDS as ROS 2 carries them (docs/dds-bridge.md "Frames"): the
// namespace's frame tree (horus/frames.hpp) to and from the topics rt/tf and rt/tf_static, each
// sample a tf2_msgs/msg/TFMessage, with tf2_ros's QoS so that ROS 2's listeners and broadcasters
// match: rt/tf reliable, volatile, keep-last 100; rt/tf_static reliable and transient local (a
// late joiner gets the static set), written as one sample holding every static transform.
//
// The export follows the tree through a horus::TransformFeed; the import sets the transforms DDS
// writers send (set_transform, set_static_transform), which makes the bridge their authority. A
// frame the bridge imported is never exported (no loop through a second bridge or a ROS 2
// relay), and a frame another live process (or this one) is the authority of is not imported.
// Refused and undecodable samples are said once per writer and reason (DropReport) and counted.
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "horus/bridge/forwarder.hpp"
#include "horus/dds/endpoints.hpp"

namespace horus::dds_bridge {

/// The DDS topics frames cross on, as a ROS 2 node names /tf and /tf_static.
inline constexpr const char* kTfTopic = "rt/tf";
inline constexpr const char* kTfStaticTopic = "rt/tf_static";
/// Their ROS 2 type, and its DDS type name (rmw_cyclonedds's).
inline constexpr const char* kTfMessageType = "tf2_msgs/msg/TFMessage";
inline constexpr const char* kTfMessageDdsType = "tf2_msgs::msg::dds_::TFMessage_";

class ImportedFrames;

/// The frames one bridge carries, each way on a thread of its own (a bridge::Forwarder).
class FrameRelay {
 public:
  /// `exports`, `imports`: globs on child frame names (either may be empty); `namespace_name`:
  /// whose tree (empty: HORUS_NAMESPACE). The export opens the tree once it exists (its creator
  /// fixes its history duration); the import opens, or creates, it on the first sample.
  /// `typed_writers_only` as Reader's; `drop_cap` as DropReport's. Throws std::runtime_error
  /// when DDS refuses an endpoint.
  FrameRelay(const std::vector<std::string>& exports, const std::vector<std::string>& imports,
             const std::string& namespace_name, const std::shared_ptr<Participant>& participant,
             bool typed_writers_only, std::size_t drop_cap);
  ~FrameRelay();
  FrameRelay(const FrameRelay&) = delete;
  FrameRelay& operator=(const FrameRelay&) = delete;

  /// Why a direction's thread ended on its own (a bug of the bridge), or empty.
  std::string broken() const;

 private:
  std::shared_ptr<ImportedFrames> imported_;
  // The import first: its rt/tf_static reader takes what transient-local writers kept before
  // the export sends its first static set (frames a predecessor imported are not exported).
  std::unique_ptr<bridge::Forwarder> import_;
  std::unique_ptr<bridge::Forwarder> export_;
};

}  // namespace horus::dds_bridge
