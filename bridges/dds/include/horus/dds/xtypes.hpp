// A HORUS type on DDS: its DDS type name and the XTypes type information its endpoints announce,
// from the type description alone (no schema text is parsed). The IDL is the one `horus-gen
// generate --lang idl` writes (generator/horus_gen/lang/idl.py: ROS 2's naming, `@final`
// structs, helper typedefs, a PoolBlock field as `sequence<uint8> data`), spelled here again for
// what the type information depends on (modules, structs, members, typedefs; not constants or
// comments); Cyclone's `idlc` turns it into the TypeInformation and TypeMapping, once per type, at
// discovery (never per message).
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "horus/dds/endpoints.hpp"
#include "horus/type_description.hpp"

namespace horus::dds_bridge {

/// `pkg::msg::dds_::Name_`, as idlc registers it from the IDL (and ROS 2 names it).
std::string dds_type_name(const TypeDescription& description, const MessageType& type);

/// The IDL of every type of `description`, in one text (enums first, then the messages in the
/// description's order, dependencies before users).
std::string idl_of(const TypeDescription& description);

/// The DDS type of `type` with the type information idlc makes of its IDL. Throws
/// std::runtime_error when idlc cannot run or refuses the IDL (naming the type and why).
TypeOnWire type_on_wire(const TypeDescription& description, const MessageType& type);

/// One of ROS 2's messages as IDL under rmw_cyclonedds's DDS names (bridges/dds/ros2_idl/, built
/// into the library): its path ("geometry_msgs/msg/Twist.idl", what the others #include) and
/// text.
struct Ros2IdlFile {
  std::string_view path;
  std::string_view text;
};
std::span<const Ros2IdlFile> ros2_idl_files() noexcept;

/// The DDS type of ROS 2's message `ros2_type` ("geometry_msgs/msg/Twist": a twin's) with the
/// type information idlc makes of its IDL. Throws std::runtime_error as type_on_wire() does.
TypeOnWire ros2_type_on_wire(std::string_view ros2_type);

}  // namespace horus::dds_bridge
