"""The namespace's coordinate frames in the live view, as Foxglove's 3D panel takes them: a
process of its own sets map -> odom -> base_link at 100 Hz and two static frames under base_link
(lidar, base_footprint); Foxglove's own client (client_check.mjs) subscribes to "/horus/frames"
and "/horus/frames_static" and each message must validate against Foxglove's FrameTransform JSON
Schema (npm @foxglove/schemas, the fixture foxglove_schemas) and carry the values set. The tree
appears after the view started (its rescan advertises the channels); a subscriber that joins
long after the static frames were set still gets them all; a peer whose policy reads only
"@frames/base_*" gets no other frame, and one whose policy names no frame is not advertised the
frames channels."""
from __future__ import annotations

import concurrent.futures
import json
import math
import os
import pathlib
import sys
import time

import jsonschema
import pytest
from conftest import VIEW, run_node_client
from processes import wait_line, wait_until

# Set by tests/view/CMakeLists.txt: Foxglove's schemas, {"foxglove.FrameTransform": {...}, ...}.
FOXGLOVE_SCHEMAS = os.environ.get("HORUS_FOXGLOVE_SCHEMAS", "")
FRAMES, STATIC_FRAMES = "/horus/frames", "/horus/frames_static"
TOKENS = {"alice": "alice-0123456789abcdef", "bob": "bob-0123456789abcdef00"}

# The frames' writer: statics once, then both dynamic frames every 10 ms, base_link's step k at
# x = 0.01 k turned 0.001 k rad about +Z (a value the test can tell came from a whole step).
WRITER = r"""
import math, sys, time
import horus
tree = horus.FrameTree()
tree.set_static_transform("base_link", "lidar", (0.2, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0))
tree.set_static_transform("base_link", "base_footprint", (0.0, 0.0, -0.05))
step = 0
while True:
    angle = 0.001 * step
    tree.set_transform("map", "odom", (1.0, 2.0, 0.0))
    tree.set_transform("odom", "base_link", (0.01 * step, 0.0, 0.0),
                       (0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2)))
    if step == 0:
        print("ready", flush=True)
    step += 1
    time.sleep(0.01)
"""


@pytest.fixture(scope="module")
def frame_transform_schema() -> dict:
    assert FOXGLOVE_SCHEMAS, ("HORUS_FOXGLOVE_SCHEMAS names Foxglove's schemas; run this suite "
                              "through ctest (pytest_view_frames)")
    return json.loads(pathlib.Path(FOXGLOVE_SCHEMAS).read_text())["foxglove.FrameTransform"]


@pytest.fixture
def frame_writer(namespace, children):
    process = children.start([sys.executable, "-c", WRITER], dict(os.environ))
    wait_line(process, "ready")
    return process


def view_subscriptions(view_server) -> int:
    """The subscriptions of the view's clients, from its status file."""
    folder = pathlib.Path(os.environ["XDG_RUNTIME_DIR"]) / "horus-view"
    count = 0
    for status in folder.glob(f"*.{view_server.process.pid}.json"):
        try:
            served = json.loads(status.read_text())
        except json.JSONDecodeError:
            continue  # being rewritten
        count += sum(len(client["subscriptions"]) for client in served["clients"])
    return count


def check_values(transform: dict) -> None:
    """`transform` carries the values the writer set for its frame."""
    translation, rotation = transform["translation"], transform["rotation"]
    child = transform["child_frame_id"]
    if child == "odom":
        assert transform["parent_frame_id"] == "map", transform
        assert translation == {"x": 1.0, "y": 2.0, "z": 0.0}, transform
        assert rotation == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, transform
    elif child == "base_link":
        assert transform["parent_frame_id"] == "odom", transform
        step = round(translation["x"] / 0.01)
        assert translation["x"] == pytest.approx(0.01 * step, abs=1e-12), transform
        angle = 0.001 * step
        assert rotation["z"] == pytest.approx(math.sin(angle / 2), abs=1e-9), transform
        assert rotation["w"] == pytest.approx(math.cos(angle / 2), abs=1e-9), transform
    elif child == "lidar":
        assert transform["parent_frame_id"] == "base_link", transform
        assert translation == {"x": 0.2, "y": 0.0, "z": 0.1}, transform
        assert rotation == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}, transform
    elif child == "base_footprint":
        assert transform["parent_frame_id"] == "base_link", transform
        assert translation == {"x": 0.0, "y": 0.0, "z": -0.05}, transform
    else:
        raise AssertionError(f"a frame nobody set: {transform}")
    assert transform["timestamp"]["sec"] > 1_600_000_000 or child in ("lidar", "base_footprint")


def received(run: dict, topic: str, schema: dict) -> list[dict]:
    """The FrameTransforms of `topic` the client decoded, each valid by Foxglove's schema and
    carrying the values set."""
    messages = run["messages"][topic]
    assert (messages["schemaName"], messages["encoding"]) == ("foxglove.FrameTransform", "json")
    for transform in messages["decoded"]:
        jsonschema.validate(transform, schema)
        check_values(transform)
    return messages["decoded"]


def test_frames_reach_foxglove_as_frame_transforms(view_server, frame_writer,
                                                   frame_transform_schema):
    # The tree appeared after the view started: its rescan advertised the channels.
    runs = run_node_client(view_server.url, {
        "topics": [FRAMES, STATIC_FRAMES], "subscribe": {FRAMES: 60, STATIC_FRAMES: 2}})["runs"]
    (run,) = runs.values()
    assert "error" not in run, run
    channels = {c["topic"]: c for c in run["channels"]}
    assert channels[FRAMES]["schemaEncoding"] == "jsonschema"
    dynamic = received(run, FRAMES, frame_transform_schema)
    assert {t["child_frame_id"] for t in dynamic} == {"odom", "base_link"}
    steps = [round(t["translation"]["x"] / 0.01) for t in dynamic
             if t["child_frame_id"] == "base_link"]
    assert len(set(steps)) > 5, steps  # the frame moves as it is set, not one value again
    statics = received(run, STATIC_FRAMES, frame_transform_schema)
    assert {t["child_frame_id"] for t in statics} == {"lidar", "base_footprint"}


def test_a_late_subscriber_gets_the_static_set(view_server, frame_writer, frame_transform_schema):
    # The statics were set once, before a first client that stays subscribed: the view's feed
    # of the tree has given them already when the second client joins.
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        first = pool.submit(run_node_client, view_server.url, {
            "topics": [FRAMES, STATIC_FRAMES],
            "measure": {"topics": [FRAMES, STATIC_FRAMES], "warmup_s": 0, "seconds": 3}})
        wait_until(lambda: view_subscriptions(view_server) == 2, "the first client's subscriptions")
        time.sleep(0.5)
        (late,) = run_node_client(view_server.url, {
            "topics": [STATIC_FRAMES], "subscribe": {STATIC_FRAMES: 2}})["runs"].values()
        (keeper,) = first.result()["runs"].values()
    assert "error" not in late, late
    assert "error" not in keeper, keeper
    assert keeper["measured"][STATIC_FRAMES]["count"] <= 2, keeper["measured"]
    statics = received(late, STATIC_FRAMES, frame_transform_schema)
    assert sorted(t["child_frame_id"] for t in statics) == ["base_footprint", "lidar"]


def test_a_policy_limits_the_frames_a_peer_sees(namespace, children, frame_writer, tmp_path,
                                                 frame_transform_schema):
    tokens = tmp_path / "tokens"
    tokens.write_text("".join(f"{peer} {token}\n" for peer, token in TOKENS.items()))
    tokens.chmod(0o600)
    process = children.start([
        VIEW, "serve", "--namespace", namespace, "--listen", "127.0.0.1", "--port", "0",
        "--allow", "alice read @frames/base_*", "--allow", "bob read cmd_*",
        "--tokens", str(tokens)], dict(os.environ))
    url = wait_line(process, "ready ws://").split(" ", 1)[1]
    # Waits for a second static frame that never comes: the one alice may read is all she gets.
    (run,) = run_node_client(f"{url}?token={TOKENS['alice']}", {
        "topics": [FRAMES, STATIC_FRAMES], "subscribe": {FRAMES: 40, STATIC_FRAMES: 2},
        "timeout_ms": 3000})["runs"].values()
    assert STATIC_FRAMES in run.get("error", ""), run
    dynamic = received(run, FRAMES, frame_transform_schema)
    assert len(dynamic) == 40
    assert {t["child_frame_id"] for t in dynamic} == {"base_link"}
    statics = received(run, STATIC_FRAMES, frame_transform_schema)
    assert [t["child_frame_id"] for t in statics] == ["base_footprint"]

    (bob,) = run_node_client(f"{url}?token={TOKENS['bob']}", {
        "topics": [FRAMES], "timeout_ms": 2000})["runs"].values()
    assert "advertisement of /horus/frames" in bob.get("error", ""), bob
