"""The Python helpers of the standard messages (schemas/horus/msg/mixins/*.py), checked against
tests/golden/msg_helpers_cases.json: the same table tests/unit/msg_helpers_test.cpp checks the
C++ helpers against, so both languages are held to the same values.

The horus.msg package is generated into a temporary folder by horus-gen, as the build does."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CASES = json.loads((ROOT / "tests" / "golden" / "msg_helpers_cases.json").read_text())
F64 = 1e-9
F32 = 1e-6


def num(value) -> float:
    """A number of the table: the strings "nan", "inf", "-inf" stand for what JSON cannot write."""
    return float(value) if not isinstance(value, str) else {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}[value]


def near(actual, expected, tolerance) -> bool:
    expected = num(expected)
    actual = float(actual)
    if math.isnan(expected):
        return math.isnan(actual)
    if math.isinf(expected):
        return actual == expected
    return math.isfinite(actual) and abs(actual - expected) <= tolerance * max(1.0, abs(expected))


def pose(msg, v):
    return msg.Pose2D.new(num(v[0]), num(v[1]), num(v[2]))


def vec(msg, v):
    return msg.Vector3.new(*(num(x) for x in v))


# ---- geometry -------------------------------------------------------------------------------

def test_cmd_vel_factories(msg):
    c = CASES["cmd_vel_with_timestamp"][0]
    cmd = msg.CmdVel.with_timestamp(c["linear"], c["angular"], c["stamp"])
    assert (cmd.linear, cmd.angular, cmd.stamp_nanos) == (1.0, 0.5, 123456789)
    assert msg.CmdVel.zero() == msg.CmdVel()
    assert msg.CmdVel.new(1.0, 0.5).stamp_nanos == 0


def test_twist_factories_and_validity(msg):
    c = CASES["twist_new_2d"][0]
    t = msg.Twist.new_2d(c["linear_x"], c["angular_z"])
    assert list(t.linear) == c["linear"] and list(t.angular) == c["angular"]
    assert msg.Twist.stop() == msg.Twist()
    for row in CASES["twist_is_valid"]:
        assert msg.Twist.new([num(v) for v in row["linear"]], [num(v) for v in row["angular"]]).is_valid() == row["expect"]


def test_pose2d_normalize_angle_wraps_into_minus_pi_pi(msg):
    for row in CASES["pose2d_normalize_angle"]:
        p = msg.Pose2D.new(1.0, 2.0, num(row["theta"]))
        p.normalize_angle()
        assert near(p.theta, row["expect"], F64), f"theta {row['theta']}: got {p.theta}"
        if math.isfinite(p.theta):
            assert abs(p.theta) <= math.pi
        assert p.x == 1.0


def test_pose2d_distance_and_validity(msg):
    for row in CASES["pose2d_distance_to"]:
        assert near(pose(msg, row["a"]).distance_to(pose(msg, row["b"])), row["expect"], F64)
    for row in CASES["pose2d_is_valid"]:
        assert pose(msg, row["pose"]).is_valid() == row["expect"]
    assert msg.Pose2D.origin() == msg.Pose2D()


def test_point3_and_vector3(msg):
    for row in CASES["point3_distance_to"]:
        a, b = msg.Point3.new(*row["a"]), msg.Point3.new(*row["b"])
        assert near(a.distance_to(b), row["expect"], F64)
    for row in CASES["vector3_ops"]:
        a, b = vec(msg, row["a"]), vec(msg, row["b"])
        assert near(a.magnitude(), row["magnitude"], F64)
        assert near(a.dot(b), row["dot"], F64)
        c, n = a.cross(b), a.normalized()
        assert all(near(x, e, F64) for x, e in zip((c.x, c.y, c.z), row["cross"]))
        assert all(near(x, e, F64) for x, e in zip((n.x, n.y, n.z), row["normalized"]))


def test_quaternion_from_euler_and_normalize(msg):
    assert msg.Quaternion() == msg.Quaternion.identity(), "a default Quaternion is the identity"
    for row in CASES["quaternion_from_euler"]:
        q = msg.Quaternion.from_euler(*row["rpy"])
        assert all(near(x, e, F64) for x, e in zip((q.x, q.y, q.z, q.w), row["expect"]))
    for row in CASES["quaternion_normalize"]:
        q = msg.Quaternion.new(*(num(v) for v in row["q"]))
        q.normalize()
        assert all(near(x, e, F64) for x, e in zip((q.x, q.y, q.z, q.w), row["expect"]))


def test_transform_stamped(msg):
    identity = msg.TransformStamped.identity()
    assert identity.is_valid() and identity.rotation[3] == 1.0
    for row in CASES["transform_from_pose_2d"]:
        p = pose(msg, row["pose"])
        p.timestamp_ns = row["stamp"]
        tf = msg.TransformStamped.from_pose_2d(p)
        assert all(near(x, e, F64) for x, e in zip(tf.translation, row["translation"]))
        assert all(near(x, e, F64) for x, e in zip(tf.rotation, row["rotation"]))
        assert tf.timestamp_ns == p.timestamp_ns
        p3 = msg.Pose3D.from_pose_2d(p)
        assert near(p3.orientation.z, row["rotation"][2], F64) and near(p3.position.x, row["translation"][0], F64)
    for row in CASES["transform_normalize_rotation"]:
        tf = msg.TransformStamped.new([1.0, 2.0, 3.0], [num(v) for v in row["rotation"]])
        assert tf.is_valid() == row["valid_before"]
        tf.normalize_rotation()
        assert all(near(x, e, F64) for x, e in zip(tf.rotation, row["expect"]))
        assert tf.is_valid() == row["valid_after"], "a zero quaternion stays invalid"


# ---- sensors --------------------------------------------------------------------------------

def test_laser_scan_including_empty_scan(msg):
    for row in CASES["laser_scan"]:
        scan = msg.LaserScan()
        for index, value in row["ranges"].items():
            scan.ranges[int(index)] = num(value)
        for index, expected in row["angle_at"]:
            assert near(scan.angle_at(index), expected, F32), f"index {index}"
        for index, expected in row["is_range_valid"]:
            assert scan.is_range_valid(index) == expected, f"index {index}"
        assert scan.valid_count() == row["valid_count"]
        if row["min_range"] is None:
            assert scan.min_range() is None, "an empty scan has no closest reading"
        else:
            assert scan.min_range() == row["min_range"]


def test_imu_orientation(msg):
    row = CASES["imu_orientation"][0]
    imu = msg.Imu.new()
    assert imu.has_orientation() == row["has_before"]
    imu.set_orientation_from_euler(*row["rpy"])
    assert imu.has_orientation() == row["has_after"]
    assert all(near(x, e, F64) for x, e in zip(imu.orientation, row["orientation"]))
    for r in CASES["imu_is_valid"]:
        m = msg.Imu.new()
        m.angular_velocity = [num(v) for v in r["angular_velocity"]]
        m.linear_acceleration = [num(v) for v in r["linear_acceleration"]]
        assert m.is_valid() == r["expect"]


def test_odometry_frames_and_update(msg):
    odom = msg.Odometry.new()
    odom.set_frames("odom", "base_link")
    assert (odom.frame_id, odom.child_frame_id) == ("odom", "base_link")
    with pytest.raises(ValueError, match="at most 32 bytes"):
        odom.set_frames("f" * 33, "base_link")
    assert odom.frame_id == "odom", "a failed set_frames changes nothing"
    p = msg.Pose2D.new(1.0, 2.0, 0.5)
    p.timestamp_ns = 10
    t = msg.Twist.new_2d(0.5, 0.2)
    t.timestamp_ns = 20
    odom.update(p, t)
    assert odom.pose == p and odom.twist == t and odom.timestamp_ns == 20
    assert odom.is_valid()


def test_range_constants_and_validity(msg):
    assert (msg.Range.ULTRASONIC, msg.Range.INFRARED) == (0, 1)
    for row in CASES["range_is_valid"]:
        assert msg.Range.new(row["sensor_type"], num(row["range"])).is_valid() == row["expect"], row["range"]


def test_battery_state(msg):
    for row in CASES["battery_state"]:
        b = msg.BatteryState.new(row["voltage"], row["percentage"])
        b.current = num(row["current"])
        b.charge = num(row["charge"])
        assert b.is_low(20.0) == row["is_low_20"]
        assert b.is_critical() == row["is_critical"]
        left = b.time_remaining()
        if row["time_remaining"] is None:
            assert left is None
        else:
            assert near(left, row["time_remaining"], F32)
    assert math.isnan(msg.BatteryState.new(12.0, 50.0).capacity), "unmeasured means unknown"


def test_nav_sat_fix(msg):
    for row in CASES["nav_sat_fix"]:
        a, b = msg.NavSatFix.from_coordinates(*row["a"]), msg.NavSatFix.from_coordinates(*row["b"])
        assert a.has_fix()
        assert a.is_valid() == row["valid_a"]
        assert near(a.distance_to(b), row["distance"], F64)


def test_joint_state_add_and_look_up(msg):
    js = msg.JointState()
    assert js.add_joint("shoulder", 0.5, 0.1, 2.0) and js.add_joint("elbow", -1.0, 0.0, 1.0)
    assert js.position_of("elbow") == -1.0 and js.position_of("wrist") is None
    with pytest.raises(ValueError):
        js.add_joint("j" * 40, 0, 0, 0)
    assert all(js.add_joint(f"j{i}", 0, 0, 0) for i in range(2, 16))
    assert not js.add_joint("one_too_many", 0, 0, 0)
    assert js.joint_count == 16


# ---- navigation -----------------------------------------------------------------------------

def test_goal_is_reached_across_the_angle_wrap(msg):
    for row in CASES["goal_is_reached"]:
        goal = msg.Goal.new(pose(msg, row["target"]), *row["tolerance"])
        assert goal.is_reached(pose(msg, row["current"])) == row["expect"], row["current"]
    g = msg.Goal.new(msg.Pose2D.new(5, 3, 0), 0.1, 0.05).with_timeout(30.0).with_priority(2)
    assert (g.timeout_seconds, g.priority) == (30.0, 2)
    assert msg.Goal.new(msg.Pose2D(), 0.1, 0.1).priority == 1


def test_goal_result_error_is_cut_at_a_character_boundary(msg):
    base = msg.GoalResult.new(7, msg.GoalStatus.Aborted)
    assert base.status == int(msg.GoalStatus.Aborted)
    for row in CASES["goal_result_with_error"]:
        assert base.with_error(row["message"]).error_message == row["expect"]


def test_waypoint_and_path(msg):
    wp = msg.Waypoint.new(msg.Pose2D.new(1, 2, 0)).with_velocity(msg.Twist.new_2d(0.5, 0.0))
    assert wp.velocity.linear[0] == 0.5
    stop = wp.with_stop()
    assert stop.stop_required == 1 and stop.velocity == msg.Twist.stop()
    assert wp.stop_required == 0, "builders return a copy"
    for row in CASES["path"]:
        path = msg.Path()
        for p in row["poses"]:
            assert path.add_waypoint(msg.Waypoint.new(pose(msg, p)))
        assert near(path.total_length, row["total_length"], F64)
        for current, expected in row["closest"]:
            assert path.closest_waypoint_index(pose(msg, current)) == expected
    full = msg.Path()
    assert all(full.add_waypoint(msg.Waypoint()) for _ in range(256))
    assert not full.add_waypoint(msg.Waypoint()) and full.waypoint_count == 256


def test_path_plan(msg):
    for row in CASES["path_plan"]:
        plan = msg.PathPlan()
        assert plan.is_empty()
        for w in row["waypoints"]:
            assert plan.add_waypoint(*w)
        for index, expected in row["lookups"]:
            got = plan.waypoint(index)
            assert got == (None if expected is None else tuple(float(v) for v in expected))


def test_occupancy_grid_including_out_of_grid_coordinates(msg):
    for row in CASES["occupancy_grid"]:
        grid = msg.OccupancyGrid.new(row["width"], row["height"], row["resolution"], pose(msg, row["origin"]))
        for x, y, expected in row["world_to_grid"]:
            cell = grid.world_to_grid(num(x), num(y))
            assert cell == (None if expected is None else tuple(expected)), f"({x}, {y})"
        for gx, gy, value, expected in row["set_occupancy"]:
            assert grid.set_occupancy(gx, gy, value) == expected
        for gx, gy, expected in row["occupancy"]:
            assert grid.occupancy(gx, gy) == expected
        for x, y, expected in row["is_free"]:
            assert grid.is_free(x, y) == expected
        for x, y, expected in row["is_occupied"]:
            assert grid.is_occupied(x, y) == expected


def test_cost_map_inflation(msg):
    row = CASES["cost_map"][0]
    grid = msg.OccupancyGrid.new(row["width"], row["height"], row["resolution"], pose(msg, row["origin"]))
    grid.data = [0] * (row["width"] * row["height"])
    for gx, gy, value in row["cells"]:
        assert grid.set_occupancy(gx, gy, value)
    costmap = msg.CostMap.from_occupancy_grid(grid, row["inflation_radius"])
    for x, y, expected in row["cost_default_scaling"]:
        assert costmap.cost(x, y) == expected, f"at ({x}, {y})"
    costmap.cost_scaling_factor = 2.0
    costmap.compute_costs()
    for x, y, expected in row["cost_scaling_2"]:
        assert costmap.cost(x, y) == expected, f"at ({x}, {y})"
    empty = msg.CostMap()
    assert empty.cost(0.0, 0.0) == empty.lethal_cost, "off an empty map is lethal"


# ---- vision, detection ----------------------------------------------------------------------

def test_stereo_depth_and_disparity(msg):
    for row in CASES["stereo_info"]:
        stereo = msg.StereoInfo(left_camera=msg.CameraInfo.new(640, 480, row["fx"], row["fx"], 320, 240),
                                baseline=row["baseline"])
        for disparity, expected in row["depth_from_disparity"]:
            assert near(stereo.depth_from_disparity(disparity), expected, F32), f"disparity {disparity}"
        for depth, expected in row["disparity_from_depth"]:
            assert near(stereo.disparity_from_depth(depth), expected, F32), f"depth {depth}"
    info = msg.CameraInfo.new(640, 480, 525.0, 520.0, 320.0, 240.0)
    assert info.focal_lengths() == (525.0, 520.0) and info.principal_point() == (320.0, 240.0)


def test_bounding_box_and_region_of_interest(msg):
    for row in CASES["bounding_box_2d"]:
        a = msg.BoundingBox2D(x=row["a"][0], y=row["a"][1], width=row["a"][2], height=row["a"][3])
        b = msg.BoundingBox2D(x=row["b"][0], y=row["b"][1], width=row["b"][2], height=row["b"][3])
        assert near(a.area(), row["area_a"], F32) and near(a.iou(b), row["iou"], F32)
    for row in CASES["region_of_interest"]:
        roi = msg.RegionOfInterest.new(*row["roi"])
        assert roi.area() == row["area"]
        for x, y, expected in row["contains"]:
            assert roi.contains(x, y) == expected, f"({x}, {y})"


# ---- time, audio, generic -------------------------------------------------------------------

def test_clock_and_time_reference(msg):
    c = CASES["clock"][0]
    a, b = msg.Clock.sim_time(c["a"], 2.0), msg.Clock.replay_time(c["b"], 0.5)
    assert (a.source, b.source) == (msg.Clock.SOURCE_SIM, msg.Clock.SOURCE_REPLAY)
    assert b.elapsed_since(a) == c["elapsed_b_since_a"]
    assert a.elapsed_since(b) == c["elapsed_a_since_b"], "never a wrapped value"
    assert not a.is_paused() and msg.Clock().sim_speed == 1.0
    for row in CASES["time_reference"]:
        ref = msg.TimeReference(offset_ns=row["offset_ns"])
        assert ref.correct_timestamp(row["local"]) == row["expect"], row["offset_ns"]


def test_audio_frame(msg):
    for row in CASES["audio_frame"]:
        frame = msg.AudioFrame(num_samples=row["num_samples"], sample_rate=row["sample_rate"], channels=row["channels"])
        assert frame.frame_count() == row["frame_count"]
        assert near(frame.duration_ms(), row["duration_ms"], F64)


def test_generic_message_enforces_the_limit_every_way_in_and_out(msg):
    for row in CASES["generic_message_limit"]:
        payload = b"\xc0" * row["payload_bytes"]
        if row["accepted"]:
            assert len(msg.GenericMessage.new(payload).data) == len(payload)
            assert msg.GenericMessage.with_metadata(payload, "meta").metadata == "meta"
        else:
            with pytest.raises(ValueError, match=f"payload of {len(payload)} bytes exceeds the 4096-byte maximum"):
                msg.GenericMessage.new(payload)
            with pytest.raises(ValueError, match="exceeds the 4096-byte maximum"):
                msg.GenericMessage.with_metadata(payload, "meta")
            with pytest.raises(ValueError, match="exceeds the 4096-byte maximum"):
                msg.GenericMessage(data=payload).to_value()
    with pytest.raises(ValueError, match="exceeds the 4096-byte maximum"):
        msg.GenericMessage.from_value("x" * 5000)


def test_generic_message_round_trips_values(msg):
    reading = {"humidity": 60.0, "temperature": 22.5}
    m = msg.GenericMessage.from_value(reading)
    assert m.metadata is None
    assert m.to_value() == reading
    with pytest.raises(ValueError, match="not a MessagePack value"):
        msg.GenericMessage.new(b"\x92\x01").to_value()
    tagged = msg.GenericMessage.with_metadata(m.data, "source=lidar")
    assert msg.GenericMessage.from_bytes(tagged.to_bytes()) == tagged


def test_concise_log_summaries(msg):
    rows = CASES["log_summary"]
    assert msg.CmdVel.new(1.0, 0.5).log_summary() == rows[0]["expect"]
    assert msg.CameraInfo.new(640, 480, 525, 525, 320, 240).log_summary() == rows[1]["expect"]
    assert msg.OccupancyGrid.new(200, 200, 0.05, msg.Pose2D()).log_summary() == rows[2]["expect"]
    assert msg.GenericMessage.from_value(42).log_summary() == rows[3]["expect"]
