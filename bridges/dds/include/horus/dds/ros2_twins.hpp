// ROS 2's twins of HORUS standard types (docs/dds-bridge.md "ROS 2 types"): the message a ROS 2
// node has for the same thing, in the layout its .msg defines. Each twin maps the fields the two
// types share and fills the rest with documented defaults: ROS 2's Header stamp is HORUS's
// timestamp in nanoseconds split into sec and nanosec; a HORUS type without a frame sends
// frame_id ""; a ROS 2 field HORUS has no room for is dropped on the way in.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "horus/dds/conversion.hpp"
#include "horus/frames.hpp"
#include "horus/raw_topic.hpp"

namespace horus::dds_bridge {

struct Ros2Twin {
  std::string_view horus;  // "horus.msg.CmdVel"
  std::string_view ros2;   // "geometry_msgs/msg/Twist"

  /// The DDS type name ROS 2's rmw gives the twin: geometry_msgs::msg::dds_::Twist_.
  std::string dds_type() const;
};

/// Every twin; the first twin of a ROS 2 type is what a DDS topic of it becomes when nothing
/// else says (no HORUS identity from another bridge, no local topic of a type of its own).
std::span<const Ros2Twin> ros2_twins() noexcept;
/// The twin of a HORUS type, or nullptr.
const Ros2Twin* ros2_twin_of(std::string_view horus_type) noexcept;

/// The standard type of a twin (its TypeInfo's identity and description): what a ROS 2 node's
/// topic becomes locally when nothing else says.
TypeIdentity twin_type_identity(const Ros2Twin& twin);

/// The messages of `twin.horus` (a POD standard type: its exact bytes) to the twin's XCDR1
/// samples and back. to_local() says why a sample does not decode as the twin ("a CDR sample
/// does not decode as sensor_msgs/msg/LaserScan: a scan of 361 ranges does not fit HORUS's 360").
std::unique_ptr<Conversion> twin_conversion(const Ros2Twin& twin);

/// Transforms as one tf2_msgs/msg/TFMessage XCDR1 sample (what ROS 2's /tf and /tf_static
/// carry): each a geometry_msgs/msg/TransformStamped, header.frame_id the parent, the stamp in
/// ns split into sec and nanosec.
void tf_message_to_cdr(std::span<const StampedTransform> transforms,
                       std::vector<std::byte>& sample);
/// A TFMessage sample's transforms, each frame id without the one leading '/' tf2 allows; empty,
/// or why the sample does not decode (`transforms` then empty).
std::string tf_message_from_cdr(std::span<const std::byte> sample,
                                std::vector<StampedTransform>& transforms);

}  // namespace horus::dds_bridge
