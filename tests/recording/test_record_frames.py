"""Coordinate frames in recordings: a process (Python, or C++: frames_writer.cpp) sets map -> odom
-> base_link at 100 Hz and a static lidar while `horus record -a` records; a replay into another
namespace (`horus record replay`) sets the recorded transforms again with their stamps, and
lookups at past times there answer what the original tree answered; `info` lists the two frame
channels, and the Foxglove export's frame channels, read by PyPI `mcap`, validate against
Foxglove's own FrameTransform schema. A scheduler's session records the tree too, naming each
frame's authority, and its deterministic replay sets the other process's frames from the
recording while its node sets its own."""
from __future__ import annotations

import json
import math
import os
import signal
import sys

import jsonschema
import pytest
from mcap.reader import make_reader

import horus
from horus import Node, Scheduler

from conftest import check_file
from test_record import foxglove_schemas, run_horus

HORUS = os.environ.get("HORUS_CLI", "")
CPP_WRITER = os.environ.get("HORUS_FRAMES_WRITER", "")
FRAMES, STATIC = "/horus/frames", "/horus/frames_static"
UPDATES = 150  # 1.5 s at 100 Hz
CHAINS = [("map", "lidar"), ("map", "base_link"), ("odom", "lidar"), ("lidar", "map")]

# Sets the static lidar, says "ready", waits for a line on stdin (the recorder is following the
# tree by then), then moves the robot at 100 Hz: odom drifts in the map, base_link turns in odom.
WRITER = f"""
import math, sys, time
import horus
tree = horus.FrameTree()
tree.set_static_transform("base_link", "lidar", (0.2, 0.0, 0.1),
                          (0, 0, math.sin(0.2), math.cos(0.2)))
print("ready", flush=True)
sys.stdin.readline()
start = time.monotonic()
for i in range({UPDATES}):
    stamp = horus.timestamp_now()
    a = i * 0.01
    tree.set_transform("map", "odom", (1.0 + 0.1 * a, 0.5 * a, 0.0),
                       (0, 0, math.sin(a / 8), math.cos(a / 8)), stamp)
    tree.set_transform("odom", "base_link", (a, 0.2 * a * a, 0.0),
                       (0, 0, math.sin(a / 2), math.cos(a / 2)), stamp)
    time.sleep(max(0.0, start + (i + 1) * 0.01 - time.monotonic()))
print("done", flush=True)
"""


def answers(tree: horus.FrameTree, times: list[int]) -> list[tuple]:
    """Each chain looked up at each time: (chain, time, translation, rotation)."""
    found = []
    for target, source in CHAINS:
        for at in times:
            t = tree.lookup(target, source, at)
            found.append(((target, source), at, tuple(t.translation), tuple(t.rotation)))
    return found


def start_writer(children, language: str):
    if language == "c++":
        assert CPP_WRITER, "HORUS_FRAMES_WRITER names frames_writer; run this suite through ctest"
        return children.start([CPP_WRITER, str(UPDATES)], keep_stdin=True)
    return children.start([sys.executable, "-c", WRITER], keep_stdin=True)


@pytest.fixture(params=["python"])
def recorded(request, namespace, children, tmp_path):
    """The recording of the writer's run (the writer in the language the parameter names), and
    the original tree's answers at past times (taken before anything is replayed)."""
    out = tmp_path / "frames.mcap"
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_record)"
    writer = start_writer(children, request.param)
    assert writer.stdout.readline().strip() == "ready", writer.stderr.read()
    recorder = children.start([HORUS, "record", "-a", "-o", str(out)])
    # Said once the recorder runs, having opened the tree that exists by then.
    assert "recording to" in recorder.stderr.readline()
    writer.stdin.write("go\n")
    writer.stdin.flush()
    assert writer.stdout.readline().strip() == "done", writer.stderr.read()
    writer.wait(timeout=10)
    recorder.send_signal(signal.SIGINT)
    recorder.communicate(timeout=30)
    assert recorder.returncode == 0
    original = horus.FrameTree(namespace)
    stamps = [entry.stamp for entry in original.history("base_link")]
    assert len(stamps) == UPDATES
    # Between entries (interpolated), on entries, away from both ends.
    times = [(stamps[i] + stamps[i + 1]) // 2 for i in range(5, UPDATES - 5, 9)]
    times += [stamps[i] + (stamps[i + 1] - stamps[i]) // 3 for i in range(3, UPDATES - 3, 13)]
    times += stamps[10:UPDATES:20]
    return out, times, answers(original, times)


@pytest.mark.parametrize("recorded", ["python", "c++"], indirect=True)
def test_a_replay_answers_the_lookups_the_recorded_tree_answered(namespace, recorded):
    out, times, expected = recorded
    check_file(str(out))
    replay_namespace = namespace + "_replay"
    replayed = run_horus("--namespace", replay_namespace, "record", "replay", str(out))
    assert replayed.returncode == 0, replayed.stderr
    assert f"set {2 * UPDATES + 1} transforms in the frame tree" in replayed.stdout
    tree = horus.FrameTree(replay_namespace)
    frames = {f.name: f for f in tree.frames()}
    assert frames["lidar"].parent == "base_link" and frames["lidar"].is_static
    assert frames["odom"].parent == "map" and frames["base_link"].parent == "odom"
    got = answers(tree, times)
    assert len(got) == len(expected) == len(CHAINS) * len(times)
    for (chain, at, translation, rotation), (_, _, want_t, want_r) in zip(got, expected):
        assert translation == pytest.approx(want_t, abs=1e-12), (chain, at)
        assert rotation == pytest.approx(want_r, abs=1e-12), (chain, at)
    # Interpolated: a time between two entries is answered neither by one nor by the other.
    mid = times[0]
    history = tree.history("base_link")
    before = max((e for e in history if e.stamp < mid), key=lambda e: e.stamp)
    assert tree.lookup("odom", "base_link", mid).translation[0] != pytest.approx(
        before.transform.translation[0], abs=1e-9)


def test_info_lists_the_frame_channels_and_the_export_gives_foxglove_frame_transforms(
        recorded, tmp_path):
    out, _, _ = recorded
    info = run_horus("record", "info", str(out), "--json")
    assert info.returncode == 0, info.stderr
    topics = {t["topic"]: t for t in json.loads(info.stdout)["topics"]}
    assert topics[FRAMES]["type"] == topics[STATIC]["type"] == "foxglove.FrameTransform"
    assert topics[FRAMES]["encoding"] == topics[STATIC]["encoding"] == "json"
    assert topics[FRAMES]["messages"] == 2 * UPDATES and topics[STATIC]["messages"] == 1
    assert topics[FRAMES]["lost"] == 0

    foxglove = tmp_path / "foxglove.mcap"
    exported = run_horus("record", "export", str(out), "--foxglove", str(foxglove))
    assert exported.returncode == 0, exported.stderr
    schema = foxglove_schemas()["foxglove.FrameTransform"]
    children: dict[str, set] = {FRAMES: set(), STATIC: set()}
    counts = {FRAMES: 0, STATIC: 0}
    with open(foxglove, "rb") as stream:
        for written, channel, message in make_reader(stream, validate_crcs=True).iter_messages(
                topics=[FRAMES, STATIC]):
            assert written.name == "foxglove.FrameTransform" and written.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            value = json.loads(message.data)
            jsonschema.validate(value, schema)
            stamp = value["timestamp"]["sec"] * 10**9 + value["timestamp"]["nsec"]
            assert stamp <= message.log_time  # recorded after it was set
            children[channel.topic].add((value["parent_frame_id"], value["child_frame_id"]))
            counts[channel.topic] += 1
            if channel.topic == STATIC:
                assert value["translation"] == {"x": 0.2, "y": 0.0, "z": 0.1}
                assert value["rotation"] == pytest.approx(
                    {"x": 0, "y": 0, "z": math.sin(0.2), "w": math.cos(0.2)}, abs=1e-15)
    assert counts == {FRAMES: 2 * UPDATES, STATIC: 1}
    assert children == {FRAMES: {("map", "odom"), ("odom", "base_link")},
                        STATIC: {("base_link", "lidar")}}


def test_a_deterministic_replay_sets_other_processes_frames_and_leaves_its_nodes_their_own(
        namespace, children):
    writer = children.start([sys.executable, "-c", WRITER], keep_stdin=True)
    assert writer.stdout.readline().strip() == "ready", writer.stderr.read()
    tree = horus.FrameTree()

    def arm(x: float) -> Node:
        return Node(name="arm", rate=50,
                    tick=lambda node: tree.set_transform("base_link", "tool", (x, 0.0, 0.3)))
    live = Scheduler(recording=True)
    live.add(arm(0.1))
    writer.stdin.write("go\n")
    writer.stdin.flush()
    live.tick_for(1.0)
    assert writer.stdout.readline().strip() == "done", writer.stderr.read()
    [path] = live.stop_recording()
    # The recording names each frame's authority: the tool is this process's own.
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        authorities = {m.name: m.metadata for m in reader.iter_metadata()}["horus.frames"]
        stamps = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=[FRAMES])]
    assert authorities["authority.tool"] == str(os.getpid())
    assert authorities["authority.odom"] == authorities["authority.base_link"] == str(writer.pid)
    stamps = [r["timestamp"]["sec"] * 10**9 + r["timestamp"]["nsec"] for r in stamps
              if r["child_frame_id"] == "base_link"]
    assert len(stamps) > 50
    times = [(stamps[i] + stamps[i + 1]) // 2 for i in range(2, len(stamps) - 2, 7)]
    expected = answers(horus.FrameTree(), times)
    horus.remove_frame_tree()
    # The replay's arm puts its tool elsewhere: its entries are its own, not the recorded ones.
    tree = horus.FrameTree()
    again = Scheduler(deterministic=True, replay=path)
    again.add(arm(0.5))
    again.tick_for(3.0)  # simulated: past the last recorded cycle
    again.stop()
    got = answers(tree, times)
    for (chain, at, translation, rotation), (_, _, want_t, want_r) in zip(got, expected):
        assert translation == pytest.approx(want_t, abs=1e-12), (chain, at)
        assert rotation == pytest.approx(want_r, abs=1e-12), (chain, at)
    assert {e.transform.translation[0] for e in tree.history("tool")} == {0.5}
    assert {f.name: f.is_static for f in tree.frames()}["lidar"]
