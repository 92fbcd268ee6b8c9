// HORUS topic names on DDS and back (docs/dds-bridge.md "Topic names"): ROS 2's prefix `rt/`,
// each '.' a '/' (`arm.state` is rt/arm/state). A name with no counterpart is refused, never
// mapped onto another: a HORUS '-' (DDS has no character left for it), a DDS '.' (rt/arm.state
// and rt/arm/state would be one local topic), a DDS name that is no HORUS name.
#pragma once

#include <string>
#include <string_view>

namespace horus::dds_bridge {

/// ROS 2's prefix of topic names on DDS.
inline constexpr std::string_view kTopicPrefix = "rt/";

/// The DDS topic of local topic `name`; throws std::invalid_argument (why, without the name)
/// for a name DDS cannot hold.
std::string dds_topic_name(std::string_view name);

/// The local topic of a DDS topic rt/...; throws std::invalid_argument (why) for one with no
/// HORUS counterpart.
std::string horus_topic_name(std::string_view dds_name);

/// The HORUS name a DDS topic rt/... stands for, as patterns match it, without checking it.
std::string dotted(std::string_view dds_name);

}  // namespace horus::dds_bridge
