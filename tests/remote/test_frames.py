"""A robot's coordinate frames on a laptop across `horus remote`, under the policy's `read` and
`write` of "@frames/CHILD": `connect --import-frames` sets the robot's frames the laptop may read
in the laptop's tree (dynamic ones with the robot's stamps, so a lookup at a past time there
interpolates to the robot's own answer; static ones), and `--export-frames` has the robot set the
laptop's frames it may write, its serving process their authority there. A frame outside the
policy never arrives, a write outside it is refused naming the policy, no frame goes back where
it came from, and a new connection brings the static set again."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import HORUS, SCHEMA, connect, free_port, serve
from processes import wait_line, wait_until

# The robot: base_link moving in odom at 100 Hz, lidar bolted to it (moved once argv[1]
# exists), and a frame no policy line lets the laptop read.
ROBOT = """
import math, os, sys, time
import horus
tree = horus.FrameTree()
tree.set_static_transform("base_link", "lidar", (0.2, 0.0, 0.1),
                          (0.0, 0.0, math.sin(0.25), math.cos(0.25)))
moved = False
start = time.monotonic()
print("ready", flush=True)
while True:
    t = time.monotonic() - start
    stamp = horus.timestamp_now()
    tree.set_transform("odom", "base_link", (0.5 * t, 0.1 * t, 0.0),
                       (0.0, 0.0, math.sin(0.15 * t), math.cos(0.15 * t)), stamp)
    tree.set_transform("odom", "secret", (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), stamp)
    if not moved and os.path.exists(sys.argv[1]):
        tree.set_static_transform("base_link", "lidar", (0.3, 0.0, 0.1))
        moved = True
    time.sleep(0.01)
"""

# The laptop: a goal it moves at 100 Hz (the robot lets it write it) and a marker (it does not).
LAPTOP = """
import math, time
import horus
tree = horus.FrameTree()
tree.set_static_transform("map", "marker", (5.0, 0.0, 0.0))
start = time.monotonic()
print("ready", flush=True)
while True:
    t = time.monotonic() - start
    tree.set_transform("map", "goal", (1.0 + t, 2.0 - t, 0.0),
                       (0.0, 0.0, math.sin(0.2 * t), math.cos(0.2 * t)))
    time.sleep(0.01)
"""

# One look at a world's tree: its frames, and lookups (target, source, times) by key.
QUERY = """
import json, sys
import horus
tree = horus.FrameTree()
asked = json.loads(sys.argv[1])
out = {"frames": {f.name: {"parent": f.parent, "static": f.is_static, "pid": f.authority_pid,
                           "oldest": f.oldest, "latest": f.latest} for f in tree.frames()}}
for key, (target, source, times) in asked.items():
    out[key] = [[list(part) for part in tree.lookup(target, source, t)]
                if tree.can_lookup(target, source, t) else tree.why_not(target, source, t)
                for t in times]
print(json.dumps(out))
"""


def query(world, **lookups) -> dict:
    result = subprocess.run([sys.executable, "-c", QUERY, json.dumps(lookups)], env=world.env(),
                            capture_output=True, text=True, timeout=30, check=True)
    return json.loads(result.stdout)


def frames(world) -> dict:
    return query(world)["frames"]


def spans(world, frame: str, seconds: float) -> bool:
    """Whether `frame` has dynamic entries over `seconds` in `world`."""
    info = frames(world).get(frame)
    return info is not None and info["latest"] - info["oldest"] >= seconds * 1e9


def streamed(world, stream: str) -> int:
    """Transforms `stream` sent, as `horus remote status` in `world` shows it (0: not listed)."""
    result = subprocess.run([HORUS, "--namespace", world.namespace, "remote", "status", "--json"],
                            env=world.env(), capture_output=True, text=True, timeout=30,
                            check=True)
    return sum(row["sent"] for row in json.loads(result.stdout) if row["stream"] == stream)


def assert_same(ours: list, theirs: list) -> None:
    assert all(not isinstance(answer, str) for answer in ours), ours
    for mine, other in zip(ours, theirs, strict=True):
        for part, other_part in zip(mine, other, strict=True):
            assert part == pytest.approx(other_part, abs=1e-9)


def test_frames_across_the_link(children, worlds, certs, tmp_path):
    robot, laptop = worlds
    moved = tmp_path / "moved"
    writer = children.python(ROBOT, robot.env(), str(moved))
    wait_line(writer, "ready")
    port = free_port()
    rules = ("laptop read @frames/base_link", "laptop read @frames/lidar",
             "laptop read @frames/goal", "laptop write @frames/goal")
    server, _ = serve(children, robot, certs, *rules, port=port)
    local = children.python(LAPTOP, laptop.env())
    wait_line(local, "ready")
    # Every pattern both ways: the policy and the never-back rule alone decide.
    link = connect(children, laptop, certs, port, "--import-frames", "*", "--export-frames", "*")

    # Refused with a line naming the policy; the robot's tree never has it.
    line = link.errors.wait_for("the robot refused frame marker")
    assert ("the robot's policy does not let peer 'laptop' write frame 'marker' (no 'write' rule "
            "of 'laptop' matches '@frames/marker')") in line

    wait_until(lambda: spans(laptop, "base_link", 1.0), "a second of base_link on the laptop")
    wait_until(lambda: spans(robot, "goal", 0.5), "the laptop's goal on the robot")

    # Looked up at past times between entries, the laptop answers as the robot does.
    here = frames(laptop)
    latest = here["base_link"]["latest"]
    times = [latest - 800_000_000 + k * 3_333_333 for k in range(6)]
    chains = {"chain": ["odom", "lidar", times], "moving": ["odom", "base_link", times],
              "bolted": ["base_link", "lidar", [None]]}
    on_laptop, on_robot = query(laptop, **chains), query(robot, **chains)
    for key in chains:
        assert_same(on_laptop[key], on_robot[key])
    assert here["lidar"]["static"] and not here["base_link"]["static"]
    assert here["lidar"]["pid"] == link.pid and here["base_link"]["pid"] == link.pid
    assert "secret" not in here
    # The laptop's own goal came not back: its writer is still its authority.
    assert here["goal"]["pid"] == local.pid

    # The laptop's goal on the robot, the serving process its authority there; the marker not.
    there = frames(robot)
    assert there["goal"]["pid"] == server.pid
    assert there["base_link"]["pid"] == writer.pid
    assert "marker" not in there
    goal_times = [there["goal"]["latest"] - 300_000_000 + k * 4_444_444 for k in range(4)]
    asked = {"goal": ["map", "goal", goal_times]}
    assert_same(query(robot, **asked)["goal"], query(laptop, **asked)["goal"])
    errors = link.errors.text()
    assert "cannot import frame" not in errors and "refused frame base_link" not in errors
    # Both streams in `horus remote status`.
    wait_until(lambda: streamed(robot, "frames to laptop") > 100, "the robot's frame stream")
    wait_until(lambda: streamed(laptop, "frames to the robot") > 50, "the laptop's frame stream")

    # The robot's serving process goes down; its lidar moves meanwhile; the new connection
    # brings the static set again, and the frames go on both ways.
    server.kill()
    server.wait()
    link.errors.wait_for("connection to")
    moved.touch()
    wait_until(lambda: query(robot, bolted=["base_link", "lidar", [None]])["bolted"][0][0][0]
               == 0.3, "the robot's lidar moved")
    stalled = frames(laptop)["base_link"]["latest"]
    server, _ = serve(children, robot, certs, *rules, port=port)
    wait_until(lambda: query(laptop, bolted=["base_link", "lidar", [None]])["bolted"][0][0][0]
               == pytest.approx(0.3), "the moved lidar on the laptop")
    wait_until(lambda: frames(laptop)["base_link"]["latest"] > stalled + 200_000_000,
               "base_link going on after the reconnect")
    # The goal goes on to the new serving process, and the old one's goal never comes back.
    wait_until(lambda: frames(robot)["goal"]["pid"] == server.pid, "the goal set again")
    assert "importing frame goal" not in link.errors.text()

    # A new connect process: what the last one set here (its writer gone) goes not to the robot.
    link.kill()
    link.wait()
    link = connect(children, laptop, certs, port, "--import-frames", "*", "--export-frames", "*")
    link.errors.wait_for("the robot refused frame marker")
    link.errors.wait_for("importing frame lidar")
    wait_until(lambda: frames(laptop)["base_link"]["pid"] == link.pid, "base_link taken over")
    errors = link.errors.text()
    assert "refused frame base_link" not in errors and "refused frame lidar" not in errors


# A peer of remote.capnp alone: the frames it is streamed for a second, then a write it has no
# rule for.
PEER = """
import asyncio, json, os, ssl, sys
import capnp
schema, port, certs = sys.argv[1], int(sys.argv[2]), sys.argv[3]
remote = capnp.load(schema, imports=[os.path.dirname(os.path.dirname(capnp.__file__))])
seen = {"dynamic": set(), "statics": []}

class FrameSink(remote.FrameSink.Server):
    async def transforms(self, dynamic, statics, staticsChanged, **kwargs):
        seen["dynamic"].update(t.child for t in dynamic)
        if staticsChanged:
            seen["statics"] = [[t.parent, t.child, t.translation.x] for t in statics]

async def main():
    tls = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=f"{certs}/ca.crt")
    tls.load_cert_chain(f"{certs}/attacker.crt", f"{certs}/attacker.key")
    stream = await capnp.AsyncIoStream.create_connection(host="127.0.0.1", port=port, ssl=tls,
                                                         server_hostname="robot")
    session = capnp.TwoPartyClient(stream).bootstrap().cast_as(remote.Session)
    streamed = await session.frames(patterns=["*"], sink=FrameSink())
    await asyncio.sleep(1.0)
    stats = await streamed.subscription.stats()
    write = session.setFrames_request()
    goal = write.init("dynamic", 1)[0]
    goal.parent, goal.child, goal.stamp = "map", "goal", 1
    goal.rotation.w = 1.0
    answer = await write.send()
    refusals = [[r.child, r.reason] for r in answer.refusals]
    print(json.dumps({"dynamic": sorted(seen["dynamic"]), "statics": seen["statics"],
                      "sent": stats.sent, "refusals": refusals}), flush=True)

asyncio.run(capnp.run(main()))
"""


def test_frames_for_a_client_of_the_schema(children, worlds, certs, tmp_path):
    robot, _ = worlds
    writer = children.python(ROBOT, robot.env(), str(tmp_path / "never"))
    wait_line(writer, "ready")
    _, port = serve(children, robot, certs, "attacker read @frames/base_link",
                    "attacker read @frames/lidar")
    peer = children.python(PEER, None, str(SCHEMA), str(port), str(certs))
    shown = json.loads(wait_line(peer, '{"dynamic"'))
    assert shown["dynamic"] == ["base_link"]
    assert shown["statics"] == [["base_link", "lidar", 0.2]]
    assert shown["sent"] > 50
    assert shown["refusals"] == [[
        "goal", "the robot's policy does not let peer 'attacker' write frame 'goal' (no 'write' "
        "rule of 'attacker' matches '@frames/goal')"]]
    assert "goal" not in frames(robot)
