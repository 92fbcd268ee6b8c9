"""`horus bridge --ros2-types`: standard types cross as their ROS 2 twins (CmdVel as
geometry_msgs/msg/Twist, Imu as sensor_msgs/msg/Imu, LaserScan as sensor_msgs/msg/LaserScan),
read and written by a plain Cyclone DDS
program built with idlc from ROS 2's messages as IDL (bridges/dds/ros2_idl/, dds_peer.c), and
between two bridges; a topic the option names whose type has no twin is refused in one line."""
from __future__ import annotations

import ast
import math

import pytest
from processes import wait_line
from test_bridge import COUNT, PUBLISHER, assert_in_order, bridge, python_env

# Holds `name` open with `type` and prints the first message as a dict of numbers, strings,
# lists and such dicts (for ast.literal_eval).
HOLDER = """
import sys, horus, importlib
package, _, short = sys.argv[2].rpartition(".")
cls = getattr(importlib.import_module(package), short)
topic = horus.Topic(cls, sys.argv[1])
print("ready", flush=True)
def plain(value):
    if hasattr(value, "__horus__"):
        return {name: plain(getattr(value, name)) for name in type(value).__horus__.fields}
    return value.tolist() if hasattr(value, "tolist") else value
print(plain(topic.recv(timeout=60)), flush=True)
"""

# Publishes one known Imu on `imu` twice a second until killed.
IMU_PUBLISHER = """
import time, horus
from horus.msg import Imu
topic = horus.Topic(Imu, "imu")
print("ready", flush=True)
while True:
    topic.send(Imu(orientation=[0, 0, 0.6, 0.8], orientation_covariance=[1, 0, 0, 0, 2, 0, 0, 0, 3],
                   angular_velocity=[0.1, -0.2, 0.3], angular_velocity_covariance=[-1] + [0] * 8,
                   linear_acceleration=[0, 0, 9.81],
                   linear_acceleration_covariance=[0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5],
                   timestamp_ns=12_000_000_345))
    time.sleep(0.5)
"""

# The Imu above as dds_peer prints it (and writes it, with frame_id "imu_link").
IMU_FIELDS = ("orientation=0,0,0.6,0.8 orientation_covariance=1,0,0,0,2,0,0,0,3 "
              "angular_velocity=0.1,-0.2,0.3 angular_velocity_covariance=-1,0,0,0,0,0,0,0,0 "
              "linear_acceleration=0,0,9.81 "
              "linear_acceleration_covariance=0.5,0,0,0,0.5,0,0,0,0.5")


def test_a_ros2_node_reads_cmd_vel_as_geometry_msgs_twist(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    peer = children.start([dds_peer, "read-twist", str(dds_domain), str(COUNT)])
    wait_line(peer, "ready")
    exporter = bridge(children, source, generated, dds_domain, "--export", "cmd_vel",
                      "--ros2-types", "cmd_*")
    assert wait_line(exporter, "exporting") == (
        "exporting 'cmd_vel' (horus.msg.CmdVel) as rt/cmd_vel (geometry_msgs::msg::dds_::Twist_)")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    # CmdVel(linear=0.5 i, angular=-1): linear.x and angular.z, the rest 0.
    fields = [dict(field.split("=") for field in line.split()) for line in out.splitlines()]
    assert all(f["angular"] == "0,0,-1" for f in fields), out
    linear = [f["linear"].split(",") for f in fields]
    assert all(rest == ["0", "0"] for _, *rest in linear), out
    assert_in_order("rt/cmd_vel", [round(float(x) * 2) for x, *_ in linear])


def written_by_ros2_peer(children, world, generated, dds_peer, dds_domain, write: str,
                         topic: str, type_name: str, ros2_types: str,
                         local_topic_first: bool = True) -> dict:
    """The message a HORUS reader of `topic` in `world` gets when dds_peer's `write` mode writes
    its ROS 2 message, imported by a bridge with --ros2-types; `local_topic_first=False` starts
    the bridge before the reader opens the topic (the bridge makes it)."""
    def importing_bridge():
        bridge(children, world, generated, dds_domain, "--import", topic,
               "--ros2-types", ros2_types)

    if not local_topic_first:
        importing_bridge()
    reader = children.python(HOLDER, python_env(world, generated), topic, type_name)
    wait_line(reader, "ready")
    if local_topic_first:
        importing_bridge()
    peer = children.start([dds_peer, write, str(dds_domain)])
    out, errors = reader.communicate(timeout=60)
    assert reader.returncode == 0, errors
    peer.communicate(timeout=30)
    assert peer.returncode == 0
    return ast.literal_eval(out)


def test_a_ros2_node_writes_geometry_msgs_twist_into_cmd_vel(
        dds_domain, worlds, children, generated, dds_peer):
    message = written_by_ros2_peer(children, worlds[1], generated, dds_peer, dds_domain,
                                   "write-twist", "cmd_vel", "horus.msg.CmdVel", "*")
    # Twist(linear (1.5, 0.25, 0), angular (0, 0, -0.75)): y and the roll and pitch rates have no
    # place in CmdVel; the stamp is the time it arrived.
    assert (message["linear"], message["angular"]) == (1.5, -0.75), message
    assert message["stamp_nanos"] > 0, message


def test_a_ros2_node_reads_imu_as_sensor_msgs_imu(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    publisher = children.python(IMU_PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    peer = children.start([dds_peer, "read-imu", str(dds_domain), "1"])
    wait_line(peer, "ready")
    bridge(children, source, generated, dds_domain, "--export", "imu", "--ros2-types", "imu")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    assert out.strip() == f"sec=12 nanosec=345 frame_id= {IMU_FIELDS}", out


def test_a_ros2_node_writes_sensor_msgs_imu_into_imu(
        dds_domain, worlds, children, generated, dds_peer):
    # No local topic: the bridge makes `imu` of the twin's HORUS type, horus.msg.Imu.
    message = written_by_ros2_peer(children, worlds[1], generated, dds_peer, dds_domain,
                                   "write-imu", "imu", "horus.msg.Imu", "imu",
                                   local_topic_first=False)
    # Every field as written; the frame "imu_link" has no place in HORUS's Imu.
    assert message == {
        "orientation": [0, 0, 0.6, 0.8], "orientation_covariance": [1, 0, 0, 0, 2, 0, 0, 0, 3],
        "angular_velocity": [0.1, -0.2, 0.3], "angular_velocity_covariance": [-1] + [0] * 8,
        "linear_acceleration": [0, 0, 9.81],
        "linear_acceleration_covariance": [0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5],
        "timestamp_ns": 12_000_000_345}, message


# Publishes one known LaserScan on `scan` twice a second until killed.
SCAN_PUBLISHER = """
import time, horus
from horus.msg import LaserScan
topic = horus.Topic(LaserScan, "scan")
print("ready", flush=True)
while True:
    topic.send(LaserScan(ranges=[i % 4 for i in range(360)], angle_min=-1, angle_max=1,
                         angle_increment=0.5, time_increment=0.25, scan_time=0.125, range_min=0.5,
                         range_max=2, timestamp_ns=7_000_000_001))
    time.sleep(0.5)
"""


def test_a_ros2_node_reads_laser_scan_as_sensor_msgs_laser_scan(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    publisher = children.python(SCAN_PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    peer = children.start([dds_peer, "read-scan", str(dds_domain), "1"])
    wait_line(peer, "ready")
    bridge(children, source, generated, dds_domain, "--export", "scan", "--ros2-types", "scan")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    ranges = ",".join(str(i % 4) for i in range(360))
    assert out.strip() == ("sec=7 nanosec=1 frame_id= angles=-1,1,0.5 times=0.25,0.125 "
                           f"range=0.5,2 ranges={ranges} intensities="), out


def test_a_ros2_node_writes_a_shorter_laser_scan_into_scan(
        dds_domain, worlds, children, generated, dds_peer):
    scan = written_by_ros2_peer(children, worlds[1], generated, dds_peer, dds_domain,
                                "write-scan", "scan", "horus.msg.LaserScan", "scan")
    # 100 ranges 0.25 apart, then 260 zeros (no reading); the intensities and frame dropped.
    out = repr(scan)
    assert scan.pop("time_increment") == pytest.approx(0.001), out  # 0.001 as a float32
    assert scan == {
        "ranges": [0.25 * i for i in range(100)] + [0.0] * 260, "angle_min": -1.5,
        "angle_max": 1.5, "range_min": 0.5, "range_max": 20.0, "angle_increment": 0.03125,
        "scan_time": 0.125, "timestamp_ns": 3_000_000_500}, out


def test_two_bridges_carry_cmd_vel_as_twist_between_namespaces(
        dds_domain, worlds, children, generated):
    source, target = worlds
    holder = children.python(HOLDER, python_env(target, generated), "cmd_vel", "horus.msg.CmdVel")
    wait_line(holder, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "*",
                      "--ros2-types", "cmd_vel")
    bridge(children, source, generated, dds_domain, "--export", "cmd_vel",
           "--ros2-types", "cmd_vel")
    assert wait_line(importer, "importing") == (
        "importing rt/cmd_vel (geometry_msgs::msg::dds_::Twist_) as 'cmd_vel' (horus.msg.CmdVel)")
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0, errors
    message = ast.literal_eval(out)
    assert message["linear"] == 0.5 * round(message["linear"] * 2) and message["angular"] == -1.0


def test_a_type_without_a_ros2_twin_is_refused_naming_it(
        dds_domain, worlds, children, generated):
    source = worlds[0]
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    exporter = bridge(children, source, generated, dds_domain, "--export", "kinds",
                      "--ros2-types", "*")
    line = exporter.stderr.readline()
    assert line.startswith("horus bridge: cannot export topic 'kinds': --ros2-types names it, "
                           "but dds_test.Kinds has no ROS 2 twin (those with one: "
                           "horus.msg.CmdVel, "), line


# Publishes one known Odometry on `odom` and PoseStamped on `pose` twice a second until killed.
ODOMETRY_PUBLISHER = """
import time, horus
from horus.msg import Odometry, Point3, Pose2D, Pose3D, PoseStamped, Quaternion, Twist
odometry, pose = horus.Topic(Odometry, "odom"), horus.Topic(PoseStamped, "pose")
print("ready", flush=True)
while True:
    odometry.send(Odometry(pose=Pose2D(x=1, y=-2, theta=0.5), twist=Twist(linear=[0.5, 0, 0],
                           angular=[0, 0, 0.125]), pose_covariance=[1, 2, 3] + [0] * 33,
                           twist_covariance=[0] * 35 + [9], frame_id="odom",
                           child_frame_id="base_link", timestamp_ns=4_000_000_006))
    pose.send(PoseStamped(pose=Pose3D(position=Point3(x=1, y=2, z=3),
                                      orientation=Quaternion(x=0, y=0, z=0.6, w=0.8)),
                          frame_id="map", timestamp_ns=8_000_000_009))
    time.sleep(0.5)
"""

ODOMETRY_COVARIANCES = ("pose_covariance=1,2,3" + ",0" * 33 + " twist=0.5,0,0,0,0,0.125 "
                        "twist_covariance=" + "0," * 35 + "9")


def test_a_ros2_node_reads_odometry_and_pose_stamped(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    publisher = children.python(ODOMETRY_PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    readers = {kind: children.start([dds_peer, f"read-{kind}", str(dds_domain), "1"])
               for kind in ("odom", "pose")}
    for reader in readers.values():
        wait_line(reader, "ready")
    bridge(children, source, generated, dds_domain, "--export", "odom", "--export", "pose",
           "--ros2-types", "*")
    said = {}
    for kind, reader in readers.items():
        said[kind], errors = reader.communicate(timeout=60)
        assert reader.returncode == 0, errors
    # The planar pose: z 0, the yaw 0.5 as a quaternion about z.
    yaw_z, yaw_w = "%g" % math.sin(0.25), "%g" % math.cos(0.25)
    assert said["odom"].strip() == (
        "sec=4 nanosec=6 frame_id=odom child_frame_id=base_link position=1,-2,0 "
        f"orientation=0,0,{yaw_z},{yaw_w} {ODOMETRY_COVARIANCES}"), said
    assert said["pose"].strip() == (
        "sec=8 nanosec=9 frame_id=map position=1,2,3 orientation=0,0,0.6,0.8"), said


def test_a_ros2_node_writes_odometry_and_pose_stamped(
        dds_domain, worlds, children, generated, dds_peer):
    target = worlds[1]
    holders = {kind: children.python(HOLDER, python_env(target, generated), kind, type_name)
               for kind, type_name in (("odom", "horus.msg.Odometry"),
                                       ("pose", "horus.msg.PoseStamped"))}
    for holder in holders.values():
        wait_line(holder, "ready")
    bridge(children, target, generated, dds_domain, "--import", "odom", "--import", "pose",
           "--ros2-types", "*")
    peers = [children.start([dds_peer, f"write-{kind}", str(dds_domain)]) for kind in holders]
    got = {}
    for kind, holder in holders.items():
        out, errors = holder.communicate(timeout=60)
        assert holder.returncode == 0, errors
        got[kind] = ast.literal_eval(out)
    odometry = got["odom"]
    # The peer's orientation is a yaw of 0.5 with a roll of 0.1, and z 0.25: HORUS keeps the yaw.
    assert odometry["pose"]["theta"] == pytest.approx(0.5), odometry
    assert odometry["timestamp_ns"] == 4_000_000_006 and odometry["frame_id"] == "odom"
    assert odometry["child_frame_id"] == "base_link", odometry
    assert odometry["pose_covariance"] == [1, 2, 3] + [0] * 33, odometry
    assert odometry["twist_covariance"] == [0] * 35 + [9], odometry
    assert odometry["twist"] == {"linear": [0.5, 0, 0], "angular": [0, 0, 0.125],
                                 "timestamp_ns": 4_000_000_006}, odometry
    assert (odometry["pose"]["x"], odometry["pose"]["y"]) == (1, -2), odometry
    assert got["pose"] == {"pose": {"position": {"x": 1, "y": 2, "z": 3},
                                    "orientation": {"x": 0, "y": 0, "z": 0.6, "w": 0.8},
                                    "timestamp_ns": 8_000_000_009},
                           "frame_id": "map", "timestamp_ns": 8_000_000_009}, got
    for peer in peers:
        peer.communicate(timeout=30)
        assert peer.returncode == 0


def test_a_ros2_twin_without_the_option_is_refused_naming_the_option(
        dds_domain, worlds, children, generated, dds_peer):
    target = worlds[1]
    holder = children.python(HOLDER, python_env(target, generated), "cmd_vel", "horus.msg.CmdVel")
    wait_line(holder, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "cmd_vel")
    children.start([dds_peer, "write-twist", str(dds_domain)])
    line = importer.stderr.readline()
    assert line == ("horus bridge: cannot import topic 'cmd_vel': the local topic has type "
                    "horus.msg.CmdVel (horus::msg::dds_::CmdVel_ on DDS), DDS carries "
                    "geometry_msgs::msg::dds_::Twist_ (its ROS 2 twin: --ros2-types 'cmd_vel' "
                    "carries it)\n"), line
    assert holder.poll() is None  # nothing reached the local topic
