"""horus.FrameTree across real processes and languages: a C++ process (frames_peer.cpp) and a
Python process each set frames of a small robot (map -> odom -> base_link -> lidar, camera; lidar
static, the others at 100 Hz), and this process, a third, looks chains up at past times and checks
the interpolated values against a planar hand computation. Then each error class, the helpers and
the units (integer-ns stamps, float-second durations)."""
from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import numpy
import pytest

import horus

PERIOD_NS = 10_000_000  # 100 Hz
COUNT = 60
FRAMES_PEER = os.path.join(os.environ.get("HORUS_BUILD_DIR", ""), "tests", "python", "runtime",
                           "horus_py_frames_peer")

# What the writers set, as planar poses (x, y, z, yaw) of entry k; frames_peer.cpp sets map <- odom
# and base_link <- lidar, PYTHON_WRITER the others.
def odom_in_map(k: float):
    return (0.1 * k, 0.0, 0.0, 0.01 * k)


def base_in_odom(k: float):
    return (0.0, 0.05 * k, 0.0, 0.02 * k)


def camera_in_base(k: float):
    return (0.1, 0.0, 0.3, 0.03 * k)


LIDAR_IN_BASE = (0.2, 0.0, 0.1, math.pi / 2)

PYTHON_WRITER = f"""
import math, sys, time
import horus
start, count, period = int(sys.argv[1]), int(sys.argv[2]), {PERIOD_NS}
def yaw(a): return (0.0, 0.0, math.sin(a / 2), math.cos(a / 2))
tree = horus.FrameTree()
first = time.monotonic()
for k in range(count):
    time.sleep(max(0.0, first + k * period / 1e9 - time.monotonic()))
    stamp = start + k * period
    tree.set_transform("odom", "base_link", (0.0, 0.05 * k, 0.0), yaw(0.02 * k), stamp)
    tree.set_transform("base_link", "camera", (0.1, 0.0, 0.3), yaw(0.03 * k), stamp)
    if k == 0:
        print("ready", flush=True)
print("done", flush=True)
sys.stdin.read()
"""


@pytest.fixture(autouse=True)
def frame_tree_removed(namespace):
    """The test namespace's frame tree, removed afterwards (it outlives its processes)."""
    yield
    horus.remove_frame_tree(namespace)


def compose(a, b):
    """Planar poses (x, y, z, yaw): `a` after `b`, by hand."""
    ax, ay, az, ayaw = a
    bx, by, bz, byaw = b
    c, s = math.cos(ayaw), math.sin(ayaw)
    return (ax + c * bx - s * by, ay + s * bx + c * by, az + bz, ayaw + byaw)


def inverse(a):
    x, y, z, yaw = a
    c, s = math.cos(yaw), math.sin(yaw)
    return (-(c * x + s * y), -(-s * x + c * y), -z, -yaw)


def assert_planar(transform: horus.Transform, expected, what: str) -> None:
    (x, y, z), (qx, qy, qz, qw) = transform
    got_yaw = 2 * math.atan2(qz, qw)
    assert abs(qx) + abs(qy) < 1e-9, f"{what}: a rotation about z only, got {transform.rotation}"
    turn = math.remainder(got_yaw - expected[3], 2 * math.pi)
    assert (x, y, z) == pytest.approx(expected[:3], abs=1e-9) and abs(turn) < 1e-9, \
        f"{what}: expected {expected}, got translation {(x, y, z)}, yaw {got_yaw}"


def start_writers(start: int):
    cpp = subprocess.Popen([FRAMES_PEER, str(start), str(COUNT)], stdin=subprocess.PIPE,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    python = subprocess.Popen([sys.executable, "-c", PYTHON_WRITER, str(start), str(COUNT)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    for process, what in ((cpp, "C++ writer"), (python, "Python writer")):
        line = process.stdout.readline().strip()
        if line != "ready":
            cpp.kill()
            python.kill()
            raise AssertionError(f"{what}: {line!r} {process.communicate()[1]}")
    return cpp, python


def stop(process: subprocess.Popen, what: str) -> None:
    assert process.stdout.readline().strip() == "done", f"{what} did not finish its entries"
    process.stdin.close()
    assert process.wait(timeout=10) == 0, f"{what} failed: {process.stderr.read()}"


def test_a_cpp_and_a_python_writer_and_a_third_process_looking_up_past_times():
    assert os.path.exists(FRAMES_PEER), f"{FRAMES_PEER} is built with the suite (ctest)"
    start = horus.timestamp_now()
    last = start + (COUNT - 1) * PERIOD_NS
    cpp, python = start_writers(start)
    try:
        tree = horus.FrameTree()
        # Sleeps until both writers reached their last entry (woken by writes, not polling).
        assert tree.wait_for("map", "camera", last, timeout=10.0), tree.why_not(
            "map", "camera", last)

        # Between entries 37 and 38 of every dynamic frame: linear translation, slerp rotation
        # (about one axis: the angle's mean), composed along the chain.
        k = 37.5
        between = start + int(k * PERIOD_NS)
        base_in_map = compose(odom_in_map(k), base_in_odom(k))
        assert_planar(tree.lookup("map", "lidar", between), compose(base_in_map, LIDAR_IN_BASE),
                      "map <- lidar between entries")
        assert_planar(tree.lookup("map", "camera", between),
                      compose(base_in_map, camera_in_base(k)), "map <- camera between entries")
        # Up to base_link and down again: the C++ writer's static lidar, the Python one's camera.
        assert_planar(tree.lookup("lidar", "camera", between),
                      compose(inverse(LIDAR_IN_BASE), camera_in_base(k)), "lidar <- camera")
        assert_planar(tree.lookup("odom", "map", between), inverse(odom_in_map(k)), "odom <- map")
        # At an entry's own stamp, and a quarter of the way between two.
        for k in (20, 12.25):
            stamp = start + int(k * PERIOD_NS)
            expected = compose(compose(odom_in_map(k), base_in_odom(k)), camera_in_base(k))
            assert_planar(tree.lookup("map", "camera", stamp), expected, f"map <- camera at {k}")

        # Without a time: the latest every frame of the chain has.
        stamped = tree.lookup_stamped("map", "lidar")
        assert (stamped.parent, stamped.child, stamped.stamp) == ("map", "lidar", last)

        # A point cloud in the lidar frame, into the map (vectorised) against the hand values.
        cloud = numpy.array([[1.0, 0.0, 0.0], [0.0, 2.0, -1.0], [3.0, -1.0, 0.5]])
        lidar_in_map = compose(base_in_map, LIDAR_IN_BASE)
        mapped = horus.transform_point(tree.lookup("map", "lidar", between), cloud)
        x, y, z, yaw = lidar_in_map
        c, s = math.cos(yaw), math.sin(yaw)
        expected = numpy.array([[x + c * px - s * py, y + s * px + c * py, z + pz]
                                for px, py, pz in cloud])
        assert mapped.shape == (3, 3) and numpy.allclose(mapped, expected, atol=1e-9), mapped

        # Each child has one authority: the writers' own frames are refused to this process,
        # naming the writer.
        for parent, child, writer in (("map", "odom", cpp), ("base_link", "camera", python)):
            with pytest.raises(horus.FrameAuthorityError) as refused:
                tree.set_transform(parent, child, (0, 0, 0), stamp=last + PERIOD_NS)
            assert refused.value.pid == writer.pid and str(writer.pid) in str(refused.value)
    except BaseException:
        cpp.kill()
        python.kill()
        raise
    stop(cpp, "the C++ writer")
    stop(python, "the Python writer")

    # The writers are gone: their dynamic history stays answerable, their frames can be taken
    # over, and `frames()` says who set what.
    frames = {frame.name: frame for frame in tree.frames()}
    assert frames["lidar"].is_static and frames["lidar"].authority_pid == cpp.pid
    assert frames["camera"].authority_pid == python.pid and not frames["camera"].authority_alive
    assert frames["odom"].updates == COUNT and frames["odom"].latest == last
    assert frames["map"].parent is None and frames["odom"].parent == "map"
    assert_planar(tree.lookup("map", "lidar", between), compose(base_in_map, LIDAR_IN_BASE),
                  "map <- lidar after the writers ended")
    tree.set_transform("map", "odom", (0, 0, 0), stamp=last + PERIOD_NS)
    assert "camera" in tree.as_text() and '"base_link" -> "lidar"' in tree.as_dot()


def planar_transform(x, y, z, yaw) -> horus.Transform:
    return horus.Transform((x, y, z), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))


def test_each_error_kind_is_its_own_frame_error():
    tree = horus.FrameTree(history=1.0)
    start = horus.timestamp_now()
    tree.set_transform("map", "odom", (0, 0, 0), stamp=start)
    tree.set_transform("map", "odom", (1, 0, 0), stamp=start + PERIOD_NS)
    tree.set_static_transform("odom", "base_link", (0, 0, 0.5))
    tree.set_static_transform("world", "marker", (1, 2, 3))
    assert tree.history_duration == pytest.approx(1.0)

    with pytest.raises(horus.ExtrapolationError) as past:
        tree.lookup("map", "base_link", start - 2_000_000_000)
    assert (past.value.frame, past.value.into_past) == ("odom", True)
    assert past.value.by == pytest.approx(2.0, abs=1e-6)
    with pytest.raises(horus.ExtrapolationError) as future:
        tree.lookup("map", "base_link", start + 3 * PERIOD_NS)
    assert not future.value.into_past and future.value.by == pytest.approx(0.02, abs=1e-9)

    with pytest.raises(horus.UnknownFrameError) as unknown:
        tree.lookup("map", "base_lnk")
    assert unknown.value.frame == "base_lnk" and "base_link" in unknown.value.closest
    with pytest.raises(horus.DisconnectedFramesError):
        tree.lookup("map", "marker")
    time.sleep(0.05)
    with pytest.raises(horus.StaleFrameError) as stale:
        tree.lookup("map", "base_link", max_age=0.01)
    assert stale.value.frame == "odom" and stale.value.by > 0

    with pytest.raises(horus.InvalidTransformError):
        tree.set_transform("map", "odom", (math.nan, 0, 0), stamp=start + 2 * PERIOD_NS)
    with pytest.raises(horus.InvalidTransformError):
        tree.set_static_transform("odom", "base_link", (0, 0, 0), (0, 0, 0, 2))
    with pytest.raises(horus.FrameCycleError):
        tree.set_static_transform("base_link", "map", (0, 0, 0))
    with pytest.raises(horus.FrameCapacityError):
        for index in range(300):
            tree.set_static_transform("world", f"pin_{index}", (index, 0, 0))

    # Each is a FrameError, itself a HorusError; can_lookup / why_not never raise.
    for kind in (horus.ExtrapolationError, horus.UnknownFrameError, horus.DisconnectedFramesError,
                 horus.StaleFrameError, horus.InvalidTransformError, horus.FrameCycleError,
                 horus.FrameAuthorityError, horus.FrameCapacityError):
        assert issubclass(kind, horus.FrameError) and issubclass(kind, horus.HorusError)
    assert not tree.can_lookup("map", "marker")
    assert "base_lnk" in tree.why_not("map", "base_lnk")
    assert tree.can_lookup("map", "base_link") and tree.why_not("map", "base_link") is None
    began = time.monotonic()
    assert not tree.wait_for("map", "nowhere", timeout=0.05)
    assert time.monotonic() - began < 2


def test_stamps_are_integer_nanoseconds_and_transforms_three_and_four_numbers():
    tree = horus.FrameTree()
    with pytest.raises(TypeError, match="integer nanoseconds.*seconds"):
        tree.set_transform("map", "odom", (0, 0, 0), stamp=1.5)
    with pytest.raises(TypeError, match="integer nanoseconds"):
        tree.lookup("map", "odom", time=2.0)
    with pytest.raises(ValueError, match="translation must be 3 numbers"):
        tree.set_static_transform("map", "odom", (0, 0))
    with pytest.raises(ValueError, match="rotation must be 4 numbers"):
        tree.set_static_transform("map", "odom", (0, 0, 0), (0, 0, 1))
    with pytest.raises(ValueError, match="history"):
        horus.FrameTree(history=0)
    # numpy arrays and numpy integer stamps are taken as they are.
    stamp = numpy.int64(horus.timestamp_now())
    tree.set_transform("map", "odom", numpy.array([1.0, 2.0, 3.0]), numpy.array([0, 0, 0, 1.0]),
                       stamp)
    assert tree.lookup_stamped("map", "odom", stamp).stamp == int(stamp)
    assert tree.lookup("map", "odom", int(stamp)).translation == (1.0, 2.0, 3.0)


def test_helpers_points_vectors_poses_and_clouds():
    transform = planar_transform(1.0, 2.0, 3.0, math.pi / 2)
    assert horus.transform_point(transform, (1, 0, 0)) == pytest.approx((1.0, 3.0, 3.0))
    assert horus.transform_vector(transform, (1, 0, 0)) == pytest.approx((0.0, 1.0, 0.0))
    pose = horus.transform_pose(transform, planar_transform(1, 0, 0, math.pi / 2))
    assert_planar(pose, (1.0, 3.0, 3.0, math.pi), "a pose")
    assert_planar(transform.compose(transform.inverse()), (0, 0, 0, 0), "t after its inverse")
    assert_planar(planar_transform(0, 0, 0, 0).interpolate(planar_transform(2, 0, 0, 1.0), 0.25),
                  (0.5, 0, 0, 0.25), "a quarter of the way")
    assert numpy.allclose(transform.as_matrix() @ [1, 0, 0, 1], [1.0, 3.0, 3.0, 1.0])

    cloud = numpy.random.default_rng(7).normal(size=(1000, 3)).astype(numpy.float32)
    points = horus.transform_point(transform, cloud)
    vectors = horus.transform_vector(transform, cloud)
    assert points.shape == (1000, 3) and points.dtype == numpy.float64
    assert numpy.allclose(points - vectors, [1.0, 2.0, 3.0])
    assert numpy.allclose(points[:, 0], 1.0 - cloud[:, 1], atol=1e-6)
    assert horus.transform_point(transform, numpy.zeros((0, 3))).shape == (0, 3)
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        horus.transform_point(transform, numpy.zeros((4, 2)))
