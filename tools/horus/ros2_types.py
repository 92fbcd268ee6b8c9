"""ROS 2's twins of HORUS standard types: the message a ROS 2 node has for the same thing, in the
layout its .msg defines, for `horus bridge --ros2-types` (docs/dds-bridge.md "ROS 2 types").

    twin = twin_of("horus.msg.CmdVel")        # None for a type without one
    twin.dds_type                             # "geometry_msgs::msg::dds_::Twist_"
    codec = TwinCodec(twin, CmdVel)           # the bridge's codec: encode(message) -> CDR,
    message = codec.decode(cdr)               #   decode(CDR) -> message (ValueError)

Each twin maps the fields the two types share and fills the rest with documented defaults
(docs/dds-bridge.md has the table): ROS 2's Header stamp is HORUS's timestamp in nanoseconds,
split into sec and nanosec; a HORUS type without a frame sends frame_id "", and a ROS 2 field
HORUS has no room for is dropped on the way in.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

from dds_cdr import CdrReader, CdrWriter

__all__ = ["Twin", "TwinCodec", "TWINS", "twin_of", "twins_of_dds_type"]

_NANOS = 1_000_000_000


@dataclass(frozen=True)
class Twin:
    horus: str  # the HORUS type, "horus.msg.CmdVel"
    ros2: str  # the ROS 2 type, "geometry_msgs/msg/Twist"
    write: Callable[[CdrWriter, object], None]
    read: Callable[[CdrReader, object], None]  # fills a default HORUS message

    @property
    def dds_type(self) -> str:
        """The DDS type name ROS 2's rmw gives the twin: geometry_msgs::msg::dds_::Twist_."""
        package, folder, name = self.ros2.split("/")
        return f"{package}::{folder}::dds_::{name}_"


class TwinCodec:
    """Messages of the generated class `cls` to their twin's CDR and back."""

    def __init__(self, twin: Twin, cls) -> None:
        self.twin, self.cls = twin, cls

    def encode(self, message) -> bytes:
        writer = CdrWriter()
        self.twin.write(writer, message)
        return writer.sample()

    def decode(self, data):
        def read(reader: CdrReader):
            message = self.cls()
            self.twin.read(reader, message)
            return message

        return CdrReader.read_sample(data, self.twin.ros2, read)


# -- shared parts: std_msgs/Header, geometry_msgs' Vector3, Point, Quaternion -------------------

def _write_header(out: CdrWriter, nanos: int, frame_id: str = "") -> None:
    out.number("i", nanos // _NANOS)  # builtin_interfaces/Time: int32 sec, uint32 nanosec
    out.number("I", nanos % _NANOS)
    out.string(frame_id)


def _read_header(reader: CdrReader) -> tuple[int, str]:
    """(stamp in nanoseconds, frame_id); a stamp before 1970 counts as 0."""
    sec, nanosec = reader.number("i"), reader.number("I")
    return max(0, sec * _NANOS + nanosec), reader.string()


def _yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def _yaw(x: float, y: float, z: float, w: float) -> float:
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _fits(what: str, value: str, capacity: int) -> str:
    if len(value.encode()) > capacity:
        raise ValueError(f"{what} {value!r} is longer than HORUS's string<{capacity}>")
    return value


# -- geometry_msgs/Twist <- CmdVel (planar: linear.x, angular.z), Twist (3D) ---------------------

def _write_cmd_vel(out: CdrWriter, message) -> None:
    out.numbers("d", (message.linear, 0.0, 0.0, 0.0, 0.0, message.angular))


def _read_cmd_vel(reader: CdrReader, message) -> None:
    linear_x, _, _, _, _, angular_z = reader.numbers("d", 6)
    message.linear, message.angular = linear_x, angular_z
    message.stamp_nanos = time.time_ns()  # Twist has no stamp: the time it arrived


def _write_twist(out: CdrWriter, message) -> None:
    out.numbers("d", (*message.linear, *message.angular))


def _read_twist(reader: CdrReader, message) -> None:
    values = reader.numbers("d", 6)
    message.linear, message.angular = list(values[:3]), list(values[3:])
    message.timestamp_ns = time.time_ns()


# -- sensor_msgs/Imu <- Imu (same fields; no frame) ---------------------------------------------

def _write_imu(out: CdrWriter, message) -> None:
    _write_header(out, message.timestamp_ns)
    out.numbers("d", message.orientation)
    out.numbers("d", message.orientation_covariance)
    out.numbers("d", message.angular_velocity)
    out.numbers("d", message.angular_velocity_covariance)
    out.numbers("d", message.linear_acceleration)
    out.numbers("d", message.linear_acceleration_covariance)


def _read_imu(reader: CdrReader, message) -> None:
    message.timestamp_ns, _ = _read_header(reader)
    for name, count in (("orientation", 4), ("orientation_covariance", 9),
                        ("angular_velocity", 3), ("angular_velocity_covariance", 9),
                        ("linear_acceleration", 3), ("linear_acceleration_covariance", 9)):
        setattr(message, name, list(reader.numbers("d", count)))


# -- sensor_msgs/LaserScan <- LaserScan (360 ranges; no intensities, no frame) -------------------

_SCAN_FIELDS = ("angle_min", "angle_max", "angle_increment", "time_increment", "scan_time",
                "range_min", "range_max")


def _write_laser_scan(out: CdrWriter, message) -> None:
    _write_header(out, message.timestamp_ns)
    out.numbers("f", [getattr(message, name) for name in _SCAN_FIELDS])
    out.number("I", len(message.ranges))
    out.numbers("f", message.ranges)
    out.number("I", 0)  # intensities


def _read_laser_scan(reader: CdrReader, message) -> None:
    message.timestamp_ns, _ = _read_header(reader)
    for name, value in zip(_SCAN_FIELDS, reader.numbers("f", len(_SCAN_FIELDS))):
        setattr(message, name, value)
    ranges = reader.numbers("f", reader.count())
    room = len(message.ranges)
    if len(ranges) > room:
        raise ValueError(f"a scan of {len(ranges)} ranges does not fit HORUS's {room}")
    message.ranges = list(ranges) + [0.0] * (room - len(ranges))  # 0: no reading
    reader.numbers("f", reader.count())  # intensities: HORUS has none


# -- nav_msgs/Odometry <- Odometry (planar pose: z 0, orientation a yaw) -------------------------

def _write_odometry(out: CdrWriter, message) -> None:
    _write_header(out, message.timestamp_ns, message.frame_id)
    out.string(message.child_frame_id)
    pose = message.pose
    out.numbers("d", (pose.x, pose.y, 0.0, *_yaw_quaternion(pose.theta)))
    out.numbers("d", message.pose_covariance)
    _write_twist(out, message.twist)
    out.numbers("d", message.twist_covariance)


def _read_odometry(reader: CdrReader, message) -> None:
    stamp, frame_id = _read_header(reader)
    message.timestamp_ns = message.pose.timestamp_ns = message.twist.timestamp_ns = stamp
    message.frame_id = _fits("frame_id", frame_id, 32)
    message.child_frame_id = _fits("child_frame_id", reader.string(), 32)
    x, y, _z, *orientation = reader.numbers("d", 7)
    message.pose.x, message.pose.y, message.pose.theta = x, y, _yaw(*orientation)
    message.pose_covariance = list(reader.numbers("d", 36))
    values = reader.numbers("d", 6)
    message.twist.linear, message.twist.angular = list(values[:3]), list(values[3:])
    message.twist_covariance = list(reader.numbers("d", 36))


# -- geometry_msgs/PoseStamped <- PoseStamped (same fields) --------------------------------------

def _write_pose_stamped(out: CdrWriter, message) -> None:
    _write_header(out, message.timestamp_ns, message.frame_id)
    position, orientation = message.pose.position, message.pose.orientation
    out.numbers("d", (position.x, position.y, position.z, orientation.x, orientation.y,
                      orientation.z, orientation.w))


def _read_pose_stamped(reader: CdrReader, message) -> None:
    stamp, frame_id = _read_header(reader)
    message.timestamp_ns = message.pose.timestamp_ns = stamp
    message.frame_id = _fits("frame_id", frame_id, 32)
    position, orientation = message.pose.position, message.pose.orientation
    (position.x, position.y, position.z, orientation.x, orientation.y, orientation.z,
     orientation.w) = reader.numbers("d", 7)


# The first twin of a ROS 2 type is what a DDS topic of it becomes when nothing else says (no
# HORUS identity from another bridge, no local topic of a type of its own).
TWINS = [
    Twin("horus.msg.CmdVel", "geometry_msgs/msg/Twist", _write_cmd_vel, _read_cmd_vel),
    Twin("horus.msg.Twist", "geometry_msgs/msg/Twist", _write_twist, _read_twist),
    Twin("horus.msg.Imu", "sensor_msgs/msg/Imu", _write_imu, _read_imu),
    Twin("horus.msg.LaserScan", "sensor_msgs/msg/LaserScan", _write_laser_scan, _read_laser_scan),
    Twin("horus.msg.Odometry", "nav_msgs/msg/Odometry", _write_odometry, _read_odometry),
    Twin("horus.msg.PoseStamped", "geometry_msgs/msg/PoseStamped", _write_pose_stamped,
         _read_pose_stamped),
]


def twin_of(horus_type: str) -> Twin | None:
    return next((twin for twin in TWINS if twin.horus == horus_type), None)


def twins_of_dds_type(dds_type: str) -> list[Twin]:
    return [twin for twin in TWINS if twin.dds_type == dds_type]
