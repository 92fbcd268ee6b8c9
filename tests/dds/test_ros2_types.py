"""The ROS 2 twins' C++ conversions (bridges/dds, horus/dds/ros2_twins.hpp, through
horus._core.dds.TwinCodec): each gives back what it was given (the fields both types have; the
rest as docs/dds-bridge.md's table says), in the byte layout of the ROS 2 message."""
from __future__ import annotations

import math
import struct
from types import SimpleNamespace

import pytest
from horus._core import dds
from horus.msg import (CmdVel, Imu, LaserScan, Odometry, Point3, Pose2D, Pose3D, PoseStamped,
                       Quaternion, Twist)

TWINS = [SimpleNamespace(horus=horus, ros2=ros2, dds_type=dds_type)
         for horus, ros2, dds_type in dds.ros2_twins()]


def twin_of(horus_type: str):
    return next((twin for twin in TWINS if twin.horus == horus_type), None)


def twins_of_dds_type(dds_type: str) -> list:
    return [twin for twin in TWINS if twin.dds_type == dds_type]


class TwinCodec:
    """Messages of the generated class `cls` through the C++ conversion of `twin`."""

    def __init__(self, twin, cls) -> None:
        self.cls, self.codec = cls, dds.TwinCodec(twin.horus)

    def encode(self, message) -> bytes:
        return self.codec.encode(message.to_bytes())

    def decode(self, data):
        return self.cls.from_bytes(self.codec.decode(bytes(data)))


STAMP = 1_700_000_000_123_456_789


def round_trip(message):
    codec = TwinCodec(twin_of(type(message).__horus__.name), type(message))
    return codec.decode(codec.encode(message))


def fields(message) -> dict:
    return {name: getattr(getattr(message, name), "tolist", lambda: getattr(message, name))()
            for name in type(message).__horus__.fields}


def test_every_twin_has_the_dds_name_rmw_gives_its_ros2_type():
    assert {twin.horus: twin.dds_type for twin in TWINS} == {
        "horus.msg.CmdVel": "geometry_msgs::msg::dds_::Twist_",
        "horus.msg.Twist": "geometry_msgs::msg::dds_::Twist_",
        "horus.msg.Imu": "sensor_msgs::msg::dds_::Imu_",
        "horus.msg.LaserScan": "sensor_msgs::msg::dds_::LaserScan_",
        "horus.msg.Odometry": "nav_msgs::msg::dds_::Odometry_",
        "horus.msg.PoseStamped": "geometry_msgs::msg::dds_::PoseStamped_"}
    # A plain ROS 2 Twist becomes a CmdVel unless its writer or the local topic says otherwise.
    assert [t.horus for t in twins_of_dds_type("geometry_msgs::msg::dds_::Twist_")] == [
        "horus.msg.CmdVel", "horus.msg.Twist"]
    assert twin_of("horus.msg.BatteryState") is None


def test_cmd_vel_is_a_twist_of_linear_x_and_angular_z():
    cdr = TwinCodec(twin_of("horus.msg.CmdVel"), CmdVel).encode(
        CmdVel(stamp_nanos=5, linear=1.5, angular=-0.25))
    assert cdr == b"\0\x01\0\0" + struct.pack("<6d", 1.5, 0, 0, 0, 0, -0.25)
    back = round_trip(CmdVel(stamp_nanos=5, linear=1.5, angular=-0.25))
    assert (back.linear, back.angular) == (1.5, -0.25)
    assert back.stamp_nanos > 5  # Twist has no stamp: the time it arrived


def test_twist_keeps_all_six_rates():
    back = fields(round_trip(Twist(linear=[1, 2, 3], angular=[-4, 5, -6], timestamp_ns=9)))
    assert (back["linear"], back["angular"]) == ([1, 2, 3], [-4, 5, -6])


def test_imu_keeps_every_field_and_sends_an_empty_frame():
    imu = Imu(orientation=[0, 0, 0.6, 0.8], orientation_covariance=list(range(9)),
              angular_velocity=[0.1, -0.2, 0.3], angular_velocity_covariance=[-1] + [0] * 8,
              linear_acceleration=[0, 0, 9.81], linear_acceleration_covariance=[0.5] * 9,
              timestamp_ns=STAMP)
    assert fields(round_trip(imu)) == fields(imu)
    cdr = TwinCodec(twin_of("horus.msg.Imu"), Imu).encode(imu)
    # std_msgs/Header: stamp (int32 sec, uint32 nanosec), frame_id "" (length 1: the NUL).
    assert cdr[4:17] == struct.pack("<iII", 1_700_000_000, 123_456_789, 1) + b"\0"
    # The header's 13 bytes padded to 16 for the 37 doubles that follow.
    assert len(cdr) == 4 + 16 + 8 * (4 + 9 + 3 + 9 + 3 + 9)


def test_laser_scan_sends_its_ranges_and_pads_a_shorter_scan_with_invalid_readings():
    scan = LaserScan(ranges=[float(i % 7) for i in range(360)], angle_min=-1.5, angle_max=1.5,
                     range_min=0.25, range_max=12.0, angle_increment=0.5, time_increment=0.25,
                     scan_time=0.125, timestamp_ns=STAMP)
    assert fields(round_trip(scan)) == fields(scan)
    twin = twin_of("horus.msg.LaserScan")
    writer_of = TwinCodec(twin, LaserScan)

    def scan_of(count: int) -> bytes:
        short = LaserScan(timestamp_ns=STAMP)
        cdr = bytearray(writer_of.encode(short))
        ranges_at = 4 + 16 + 7 * 4  # encapsulation, header with "" as frame, seven floats
        assert struct.unpack_from("<I", cdr, ranges_at)[0] == 360
        return bytes(cdr[:ranges_at]) + struct.pack(f"<I{count}fI", count, *[2.5] * count, 0)

    back = writer_of.decode(scan_of(100))
    assert fields(back)["ranges"] == [2.5] * 100 + [0.0] * 260
    with pytest.raises(ValueError, match="a scan of 361 ranges does not fit HORUS's 360"):
        writer_of.decode(scan_of(361))


def test_odometry_sends_its_planar_pose_as_a_yaw_quaternion_and_reads_the_yaw_back():
    odometry = Odometry(pose=Pose2D(x=1, y=-2, theta=0.75, timestamp_ns=STAMP),
                        twist=Twist(linear=[0.5, 0, 0], angular=[0, 0, 0.1], timestamp_ns=STAMP),
                        pose_covariance=[float(i) for i in range(36)],
                        twist_covariance=[-float(i) for i in range(36)], frame_id="odom",
                        child_frame_id="base_link", timestamp_ns=STAMP)
    back = round_trip(odometry)
    assert math.isclose(back.pose.theta, 0.75)
    back.pose.theta = 0.75
    assert fields(back) == fields(odometry)
    # A ROS 2 frame longer than HORUS's string<32> does not fit: the sample is refused.
    codec = TwinCodec(twin_of("horus.msg.Odometry"), Odometry)
    cdr = codec.encode(Odometry(frame_id="o" * 32))
    longer = cdr.replace(struct.pack("<I", 33) + b"o" * 32 + b"\0",
                         struct.pack("<I", 41) + b"o" * 40 + b"\0")
    with pytest.raises(ValueError, match="frame_id 'o{40}' is longer than HORUS's string<32>"):
        codec.decode(longer)


def test_pose_stamped_keeps_every_field():
    pose = PoseStamped(pose=Pose3D(position=Point3(x=1, y=2, z=3),
                                   orientation=Quaternion(x=0, y=0, z=0.6, w=0.8),
                                   timestamp_ns=STAMP), frame_id="map", timestamp_ns=STAMP)
    assert fields(round_trip(pose)) == fields(pose)
