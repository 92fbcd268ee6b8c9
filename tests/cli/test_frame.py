"""`horus frame list|tree|echo|hz` against a live Python process setting a small robot's frames
(map -> odom -> base_link -> lidar, lidar static, the others at 100 Hz), as text and as --json."""
from __future__ import annotations

import json
import os

import pytest
from conftest import run_horus, wait_ready

# The transforms are the same at every stamp, so that echo's answer is known: base_link in the
# map is (1, 2, 0) turned a quarter about z, the lidar 0.2 ahead of it and 0.1 up.
ROBOT = """
import math, time
import horus
tree = horus.FrameTree()
tree.set_static_transform("base_link", "lidar", (0.2, 0.0, 0.1))
quarter = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))
next_at = time.monotonic()
for k in range(10**6):
    stamp = horus.timestamp_now()
    tree.set_transform("map", "odom", (1.0, 0.0, 0.0), stamp=stamp)
    tree.set_transform("odom", "base_link", (0.0, 2.0, 0.0), quarter, stamp)
    if k == 1:
        print("ready", flush=True)
    next_at += 0.01
    time.sleep(max(0.0, next_at - time.monotonic()))
"""


@pytest.fixture
def robot(children):
    process = children.python(ROBOT)
    wait_ready(process)
    return process


def test_list_shows_parent_authority_static_or_rate_and_age(robot):
    result = run_horus("frame", "list")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].split() == ["FRAME", "PARENT", "AUTHORITY", "STATIC/RATE", "AGE"]
    rows = {line.split()[0]: line.split() for line in lines[1:]}
    assert set(rows) == {"map", "odom", "base_link", "lidar"}
    assert rows["lidar"][1:5] == ["base_link", str(robot.pid), "python3", "static"]
    assert rows["odom"][1:4] == ["map", str(robot.pid), "python3"] and rows["odom"][5] == "Hz"
    assert rows["map"][1:4] == ["-", "-", "root"]

    listing = json.loads(run_horus("frame", "list", "--json").stdout)
    frames = {row["name"]: row for row in listing}
    odom = frames["odom"]
    assert (odom["parent"], odom["static"], odom["authority_pid"]) == ("map", False, robot.pid)
    assert 20 < odom["rate_hz"] < 200, odom
    assert 0 <= odom["age_s"] < 5 and odom["updates"] >= 2
    assert frames["lidar"]["static"] and frames["lidar"]["rate_hz"] is None
    assert frames["map"]["parent"] is None and frames["map"]["authority_pid"] is None


def test_tree_as_text_nested_json_and_dot(robot):
    text = run_horus("frame", "tree").stdout.splitlines()
    assert [line.split()[0] for line in text] == ["map", "odom", "base_link", "lidar"]
    assert text[3].startswith("      lidar") and "static" in text[3]

    (root,) = json.loads(run_horus("frame", "tree", "--json").stdout)
    assert root["name"] == "map"
    (odom,) = root["children"]
    (base,) = odom["children"]
    assert (odom["name"], base["name"], [c["name"] for c in base["children"]]) == \
        ("odom", "base_link", ["lidar"])
    assert '"base_link" -> "lidar" [style=dashed]' in run_horus("frame", "tree", "--dot").stdout


def test_echo_prints_the_transform_at_the_latest_common_time(robot):
    result = run_horus("frame", "echo", "map", "lidar", "--once")
    assert result.returncode == 0, result.stderr
    assert "map <- lidar" in result.stdout
    assert "translation: [1.000000, 2.200000, 0.100000]" in result.stdout
    assert "rotation (roll, pitch, yaw deg): [0.000, 0.000, 90.000]" in result.stdout

    result = run_horus("frame", "echo", "map", "lidar", "--count", "3", "--rate", "20", "--json")
    answers = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(answers) == 3
    assert answers[0]["translation"] == pytest.approx([1.0, 2.2, 0.1])
    assert answers[0]["rpy_deg"] == pytest.approx([0, 0, 90])
    assert (answers[0]["target"], answers[0]["source"]) == ("map", "lidar")
    assert answers[2]["stamp_ns"] > answers[0]["stamp_ns"]


def test_hz_measures_each_dynamic_frame(robot):
    result = run_horus("frame", "hz", "--once", "--window", "0.5", "--json")
    assert result.returncode == 0, result.stderr
    window = json.loads(result.stdout)
    assert set(window["frames"]) == {"odom", "base_link"}
    assert 20 < window["frames"]["odom"]["rate_hz"] < 200, window

    text = run_horus("frame", "hz", "base_link", "--once", "--window", "0.3").stdout
    assert text.startswith("base_link: ") and " Hz (" in text
    static = run_horus("frame", "hz", "lidar", "--once")
    assert static.returncode == 1 and "frame 'lidar' is static" in static.stderr


def test_unknown_frames_say_the_closest_names(robot):
    result = run_horus("frame", "echo", "map", "lidr", "--once")
    assert result.returncode == 1
    assert result.stderr.strip().endswith("no frame 'lidr' in namespace "
                                          f"'{os.environ['HORUS_NAMESPACE']}'; did you mean "
                                          "'lidar'?")
    assert "did you mean 'odom'?" in run_horus("frame", "hz", "odm", "--once").stderr


def test_a_namespace_without_frames_is_looked_at_without_making_a_tree(namespace):
    listing = run_horus("frame", "list", "--json")
    assert listing.returncode == 0 and json.loads(listing.stdout) == []
    assert run_horus("frame", "tree").stdout.strip() == f"no frames in namespace '{namespace}'"
    echo = run_horus("frame", "echo", "map", "odom", "--once")
    assert echo.returncode == 1 and "has no frame tree" in echo.stderr
    assert not os.path.exists(os.path.join(os.environ["HORUS_SHM_DIR"], "@frames", namespace))


def test_namespace_option_reads_another_namespace(children):
    other = f"{os.environ['HORUS_NAMESPACE']}_other"
    process = children.python(ROBOT, {**os.environ, "HORUS_NAMESPACE": other})
    wait_ready(process)
    assert json.loads(run_horus("frame", "list", "--json").stdout) == []
    listing = json.loads(run_horus("frame", "list", "--namespace", other, "--json").stdout)
    assert {row["name"] for row in listing} == {"map", "odom", "base_link", "lidar"}


def test_shm_list_shows_the_tree_and_clean_keeps_it_until_nobody_has_it_open(robot, namespace):
    tree_path = os.path.join(os.environ["HORUS_SHM_DIR"], "@frames", namespace)
    rows = {row["name"]: row for row in json.loads(run_horus("shm", "list", "--json").stdout)}
    assert rows["@frames"]["path"] == tree_path
    assert rows["@frames"]["in_use"] and 0 < rows["@frames"]["size"] < 1 << 20, rows["@frames"]
    assert run_horus("shm", "clean").returncode == 0
    assert os.path.exists(tree_path), "the robot has it open"

    robot.kill()
    robot.wait()
    rows = {row["name"]: row for row in json.loads(run_horus("shm", "list", "--json").stdout)}
    assert not rows["@frames"]["in_use"]
    assert run_horus("shm", "clean").returncode == 0
    assert not os.path.exists(tree_path)
    assert "@frames" not in {row["name"] for row in
                             json.loads(run_horus("shm", "list", "--json").stdout)}
