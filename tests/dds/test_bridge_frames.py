"""`horus bridge --export-frames/--import-frames/--frames`: a namespace's frame tree crosses DDS
as ROS 2's /tf and /tf_static (tf2_msgs/msg/TFMessage), read and written by a plain Cyclone DDS
program built with idlc from ROS 2's messages as IDL (dds_peer.c); frames the bridge imported
never go back out, a frame another process is the authority of is not imported, and bad samples
are one line each while the bridge carries on."""
from __future__ import annotations

import json
import math
import os
import signal
import struct
import sys
import time

from processes import wait_line
from test_bridge import HORUS, python_env

NS = 1_000_000_000
NETWORK_PEER = os.environ.get("HORUS_DDS_NETWORK_PEER", "")

# Sets a small robot's frames in its namespace: base_link -> lidar static, then map -> odom and
# odom -> base_link at 100 Hz with stamps BASE + i * 10 ms (odom at (i, 0, 0) cm, base_link at
# (0, i, 7) cm turned i mrad about z), until killed; a line "camera" on stdin adds base_link ->
# camera, static too. argv: BASE; "only-base-link" sets base_link alone.
ROBOT = """
import math, sys, threading, time, horus
base, only_base_link = int(sys.argv[1]), "only-base-link" in sys.argv
tree = horus.FrameTree()
tree.set_static_transform("base_link", "lidar", (0.2, 0, 0.1))
def camera():
    for line in sys.stdin:
        if line.strip() == "camera":
            tree.set_static_transform("base_link", "camera", (0.1, 0, 0.3), (0, 0, 0.6, 0.8))
            print("camera set", flush=True)
threading.Thread(target=camera, daemon=True).start()
print("ready", flush=True)
i = 0
while True:
    stamp = base + i * 10_000_000
    if not only_base_link:
        tree.set_transform("map", "odom", (i / 100, 0, 0), stamp=stamp)
    tree.set_transform("odom", "base_link", (0, i / 100, 0.07),
                       (0, 0, math.sin(i / 2000), math.cos(i / 2000)), stamp)
    i += 1
    time.sleep(0.01)
"""

# Prints, as JSON, the lookups a test asks (argv: a JSON list of [target, source, time|null]) once
# the first can be answered; each answer [translation, rotation, stamp] or the error's text. Also
# each frame's parent, whether static and its authority's pid.
LOOKUPS = """
import json, sys, horus
asked = json.loads(sys.argv[1])
tree = horus.FrameTree()
if not tree.wait_for(asked[0][0], asked[0][1], asked[0][2], timeout=20):
    print(json.dumps({"error": tree.why_not(asked[0][0], asked[0][1], asked[0][2])}), flush=True)
    sys.exit(1)
answers = []
for target, source, time in asked:
    try:
        found = tree.lookup_stamped(target, source, time)
        answers.append([list(found.transform.translation), list(found.transform.rotation),
                        found.stamp])
    except horus.FrameError as error:
        answers.append(str(error))
frames = {f.name: [f.parent, f.is_static, f.authority_pid] for f in tree.frames()}
print(json.dumps({"answers": answers, "frames": frames}), flush=True)
"""


def frames_bridge(children, world, generated, domain: int, *options: str):
    process = children.start([HORUS, "bridge", "--domain", str(domain), *options],
                             python_env(world, generated))
    wait_line(process, "bridge on DDS domain")
    return process


def robot(children, world, generated, base: int, *argv: str):
    process = children.start([sys.executable, "-c", ROBOT, str(base), *argv],
                             python_env(world, generated), keep_stdin=True)
    wait_line(process, "ready")
    return process


def tf_lines(peer, *read: str) -> list[tuple[int, str, str, int, list[float], list[float]]]:
    """dds_peer read-tf's lines (`read`: those the test read already, "ready" left out):
    (sample, parent, child, stamp ns, translation, rotation) each."""
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    rows = []
    for line in [*read, *out.splitlines()]:
        if line == "ready":
            continue
        sample, parent, child, sec, nanosec, translation, rotation = line.split()
        rows.append((int(sample), parent, child, int(sec) * NS + int(nanosec),
                     [float(v) for v in translation.split(",")],
                     [float(v) for v in rotation.split(",")]))
    return rows


def lookups(children, world, generated, asked: list) -> dict:
    checker = children.python(LOOKUPS, python_env(world, generated), json.dumps(asked))
    out, errors = checker.communicate(timeout=60)
    assert checker.returncode == 0, (out, errors)
    return json.loads(out)


def close(a, b, tolerance=1e-9) -> bool:
    return all(math.isclose(x, y, abs_tol=tolerance) for x, y in zip(a, b, strict=True))


def now_base() -> int:
    return time.time_ns() // NS * NS


def test_frames_go_out_as_tf_and_tf_static_to_a_plain_cyclone_reader(
        dds_domain, worlds, children, generated, dds_peer):
    world = worlds[0]
    base = now_base()
    writer = robot(children, world, generated, base)
    exporter = frames_bridge(children, world, generated, dds_domain, "--export-frames", "*")
    assert wait_line(exporter, "exporting frames") == (
        "exporting frames '*' as rt/tf, rt/tf_static (tf2_msgs::msg::dds_::TFMessage_)")
    dynamic = children.start([dds_peer, "read-tf", str(dds_domain), "60"])
    statics = children.start([dds_peer, "read-tf-static", str(dds_domain), "3"])
    wait_line(dynamic, "ready")
    first_static = wait_line(statics, "1 ")
    writer.stdin.write("camera\n")
    writer.stdin.flush()
    wait_line(writer, "camera set")

    rows = tf_lines(dynamic)
    by_child: dict[str, list[int]] = {"odom": [], "base_link": []}
    for _, parent, child, stamp, translation, rotation in rows:
        i = (stamp - base) // 10_000_000
        assert (stamp - base) % 10_000_000 == 0, rows
        if child == "odom":
            assert parent == "map" and close(translation, [i / 100, 0, 0]), rows
            assert close(rotation, [0, 0, 0, 1]), rows
        else:
            assert (parent, child) == ("odom", "base_link"), rows
            assert close(translation, [0, i / 100, 0.07]), rows
            assert close(rotation, [0, 0, math.sin(i / 2000), math.cos(i / 2000)]), rows
        by_child[child].append(stamp)
    for child, stamps in by_child.items():  # each entry once, oldest first
        assert stamps and stamps == sorted(set(stamps)), (child, stamps)
        assert (stamps[-1] - stamps[0]) // 10_000_000 == len(stamps) - 1, (child, stamps)

    # The static set is one sample each time it changes: lidar, then lidar and camera.
    rows = tf_lines(statics, first_static)
    assert [(s, p, c) for s, p, c, *_ in rows] == [
        (1, "base_link", "lidar"), (2, "base_link", "lidar"), (2, "base_link", "camera")], rows
    assert close(rows[2][4], [0.1, 0, 0.3]) and close(rows[2][5], [0, 0, 0.6, 0.8]), rows
    # A late joiner gets the whole set from the transient-local writer.
    late = children.start([dds_peer, "read-tf-static", str(dds_domain), "2"])
    rows = tf_lines(late)
    assert sorted((s, c) for s, _, c, *_ in rows) == [(1, "camera"), (1, "lidar")], rows
    assert exporter.poll() is None


def test_frames_of_a_plain_cyclone_writer_land_in_the_tree(
        dds_domain, worlds, children, generated, dds_peer):
    world = worlds[0]
    statics = children.start([dds_peer, "write-tf-static", str(dds_domain)])
    wait_line(statics, "ready")
    importer = frames_bridge(children, world, generated, dds_domain, "--import-frames", "*")
    assert wait_line(importer, "importing frames") == (
        "importing frames '*' from rt/tf, rt/tf_static (tf2_msgs::msg::dds_::TFMessage_)")
    dynamic = children.start([dds_peer, "write-tf", str(dds_domain)])
    wait_line(dynamic, "ready")
    base = int(wait_line(dynamic, "base").split()[1]) * NS
    out, errors = dynamic.communicate(timeout=30)
    assert dynamic.returncode == 0, errors

    half = NS // 2
    found = lookups(children, world, generated, [
        ["map", "base_link", base + 2 * NS],
        ["map", "odom", base + 3 * half],  # between (1, 0, 0) and (2, 0, 0)
        ["odom", "base_link", base + half],  # between yaw 0 and 0.5: 0.25, (0, 1, 0)
        ["base_link", "camera", None],
        ["map", "lidar", base + NS],
    ])
    answers = found["answers"]
    # map <- base_link at BASE + 2 s: odom (2, 0, 0), base_link (0, 4, 0) turned 1 rad.
    assert close(answers[0][0], [2, 4, 0]), answers
    assert close(answers[0][1], [0, 0, math.sin(0.5), math.cos(0.5)]), answers
    assert answers[0][2] == base + 2 * NS, answers
    assert close(answers[1][0], [1.5, 0, 0]) and close(answers[1][1], [0, 0, 0, 1]), answers
    assert close(answers[2][0], [0, 1, 0]), answers
    assert close(answers[2][1], [0, 0, math.sin(0.125), math.cos(0.125)]), answers
    assert close(answers[3][0], [0.1, 0, 0.3]) and close(answers[3][1], [0, 0, 0.6, 0.8]), answers
    # map <- lidar at BASE + 1 s: odom (1, 0, 0), base_link (0, 2, 0) turned 0.5 rad, lidar
    # (0.2, 0, 0.1) on it.
    yaw = 0.5
    assert close(answers[4][0], [1 + 0.2 * math.cos(yaw), 2 + 0.2 * math.sin(yaw), 0.1]), answers
    frames = found["frames"]
    # Leading '/' stripped; the bridge is the authority of what it imported.
    assert frames["odom"] == ["map", False, importer.pid], frames
    assert frames["base_link"] == ["odom", False, importer.pid], frames
    assert frames["camera"] == ["base_link", True, importer.pid], frames
    assert frames["lidar"][:2] == ["base_link", True], frames
    assert importer.poll() is None


def test_a_restarted_bridge_takes_back_what_its_predecessor_imported_without_sending_it(
        dds_domain, worlds, children, generated, dds_peer):
    # The static frames a SIGKILLed bridge imported stay in the tree with a dead authority; its
    # successor takes them again from rt/tf_static's transient-local replay before its first
    # static set goes out, so it never sends them as its own.
    from horus._core import dds
    world = worlds[0]
    statics = children.start([dds_peer, "write-tf-static", str(dds_domain)])
    wait_line(statics, "ready")
    first = frames_bridge(children, world, generated, dds_domain, "--frames")
    assert lookups(children, world, generated, [["base_link", "camera", None]])["frames"][
        "camera"][2] == first.pid
    first.kill()
    first.wait()
    participant = dds.Participant(dds_domain)
    reader = dds.Reader(participant, "rt/tf_static", "tf2_msgs::msg::dds_::TFMessage_",
                        transient_local=True)
    second = frames_bridge(children, world, generated, dds_domain, "--frames")
    wait_line(second, "exporting frames")
    found = lookups(children, world, generated, [["base_link", "camera", None]])
    assert found["frames"]["camera"][2] == second.pid, found
    time.sleep(1.5)  # past the export's first static set
    samples = reader.take(0.5)
    assert samples, "the peer's sample, at least"
    # "/camera" (the peer's) has a length of 8 with its NUL; "camera" (a bridge's) 7.
    assert not [s for s in samples if b"\x07\x00\x00\x00camera\x00" in s], samples
    assert second.poll() is None


def test_imported_frames_never_go_back_and_a_local_authority_keeps_its_frame(
        dds_domain, worlds, children, generated, dds_peer):
    world = worlds[0]
    base = now_base()
    # Locally: odom -> base_link (and lidar). From DDS: map -> odom and odom -> base_link.
    writer = robot(children, world, generated, base, "only-base-link")
    both = children.start([HORUS, "bridge", "--domain", str(dds_domain), "--frames"],
                          python_env(world, generated))
    wait_line(both, "bridge on DDS domain")
    reader = children.start([dds_peer, "read-tf", str(dds_domain), "200"])
    wait_line(reader, "ready")
    peer = children.start([dds_peer, "write-tf", str(dds_domain), "2"])  # the bridge, reader
    peer_base = int(wait_line(peer, "base").split()[1]) * NS
    peer.communicate(timeout=30)
    assert peer.returncode == 0

    rows = tf_lines(reader)
    # The peer's own samples say "/odom"; the bridge's would say "odom": it never sends those.
    assert not [row for row in rows if row[2] == "odom"], rows
    local = [row for row in rows if row[2] == "base_link" and row[3] >= base
             and math.isclose(row[4][2], 0.07)]
    assert local, rows

    found = lookups(children, world, generated, [["map", "odom", peer_base + NS],
                                                 ["odom", "base_link", None]])
    assert close(found["answers"][0][0], [1, 0, 0]), found
    assert math.isclose(found["answers"][1][0][2], 0.07), found  # the local value
    assert found["frames"]["odom"][2] == both.pid
    assert found["frames"]["base_link"][2] == writer.pid

    both.terminate()
    errors = both.communicate(timeout=30)[1].splitlines()
    refused = [line for line in errors if "sets frame 'base_link'" in line]
    assert len(refused) == 1, errors
    assert f"whose authority here is pid {writer.pid}" in refused[0], refused
    assert both.returncode == 0, errors


def test_two_namespaces_bridging_every_frame_both_ways_do_not_echo(
        dds_domain, worlds, children, generated):
    # B imports A's frames and, having imported them, does not send them back: A's bridge never
    # sees its own frames come in (it would refuse them: the robot is their authority).
    source, target = worlds
    base = now_base()
    writer = robot(children, source, generated, base)
    a = frames_bridge(children, source, generated, dds_domain, "--frames")
    b = frames_bridge(children, target, generated, dds_domain, "--frames")
    found = lookups(children, target, generated, [["map", "lidar", None]])
    assert isinstance(found["answers"][0], list), found
    assert found["frames"]["odom"][2] == b.pid and found["frames"]["lidar"][2] == b.pid, found
    time.sleep(1.5)  # B's export settled and ran
    mine = lookups(children, source, generated, [["map", "lidar", None]])
    assert mine["frames"]["odom"][2] == writer.pid, mine
    for process in (a, b):
        process.terminate()
        _, errors = process.communicate(timeout=30)
        assert process.returncode == 0, errors
        assert "sets frame" not in errors, errors


def test_a_cpp_scheduler_carries_its_frames_in_process_and_refuses_its_own_from_dds(
        dds_domain, worlds, children, generated, dds_peer):
    # The scheduler's bridge runs in the process that is base_link's authority: it exports
    # base_link, and refuses the peer's base_link although no other process owns it.
    world = worlds[0]
    program = children.start([NETWORK_PEER, "frames", str(dds_domain)],
                             python_env(world, generated))
    wait_line(program, "exporting frames '*'")
    reader = children.start([dds_peer, "read-tf", str(dds_domain), "50"])
    wait_line(reader, "ready")
    peer = children.start([dds_peer, "write-tf", str(dds_domain), "2"])  # the bridge, reader
    peer_base = int(wait_line(peer, "base").split()[1]) * NS
    peer.communicate(timeout=30)
    assert peer.returncode == 0

    rows = tf_lines(reader)
    assert not [row for row in rows if row[2] == "odom"], rows  # imported: never sent back
    ours = [row for row in rows if row[2] == "base_link" and math.isclose(row[4][2], 7)]
    assert ours and all(row[1] == "odom" for row in ours), rows
    found = lookups(children, world, generated, [["map", "odom", peer_base + NS],
                                                 ["odom", "base_link", None]])
    assert close(found["answers"][0][0], [1, 0, 0]), found
    assert close(found["answers"][1][0], [0, 0, 7]), found
    program.send_signal(signal.SIGINT)
    _, errors = program.communicate(timeout=30)
    assert program.returncode == 0, errors
    refused = [line for line in errors.splitlines() if "sets frame 'base_link'" in line]
    assert len(refused) == 1 and f"pid {program.pid}" in refused[0], errors


# A Python scheduler whose node sets odom -> base_link at (0, 0, 5), its frames exported by the
# scheduler's own Network.
PYTHON_SCHEDULER = """
import sys, horus
tree = horus.FrameTree()
def tick(node):
    tree.set_transform("odom", "base_link", (0, 0, 5))
network = horus.Network(export_frames=["base_*"], import_frames=["*"], domain=int(sys.argv[1]))
horus.run(horus.Node(name="odometry", tick=tick, rate=100), network=network)
"""


def test_a_python_scheduler_exports_its_frames_through_its_network(
        dds_domain, worlds, children, generated, dds_peer):
    program = children.python(PYTHON_SCHEDULER, python_env(worlds[0], generated), str(dds_domain))
    assert "frames: exporting ['base_*'], importing ['*']" in wait_line(program,
                                                                        "bridge on DDS domain")
    reader = children.start([dds_peer, "read-tf", str(dds_domain), "5"])
    rows = tf_lines(reader)
    assert [(p, c, t) for _, p, c, _, t, _ in rows] == [("odom", "base_link", [0, 0, 5])] * 5


def tf_message(*transforms) -> bytes:
    """An XCDR1 little-endian tf2_msgs/msg/TFMessage of (parent, child, stamp ns, translation,
    rotation) tuples."""
    body = bytearray(struct.pack("<I", len(transforms)))

    def string(text: str) -> None:
        body.extend(b"\0" * (-len(body) % 4))
        data = text.encode() + b"\0"
        body.extend(struct.pack("<I", len(data)) + data)

    for parent, child, stamp, translation, rotation in transforms:
        body.extend(b"\0" * (-len(body) % 4))
        body.extend(struct.pack("<iI", stamp // NS, stamp % NS))
        string(parent)
        string(child)
        body.extend(b"\0" * (-len(body) % 8))
        body.extend(struct.pack("<7d", *translation, *rotation))
    return b"\0\1\0\0" + bytes(body)


# Writes the samples argv[2] names (a JSON list of hex strings) on rt/tf with no type
# information, as a writer of another DDS program might, once the bridge's reader matches.
RAW_WRITER = """
import json, sys, time
from horus._core import dds
participant = dds.Participant(int(sys.argv[1]))
writer = dds.Writer(participant, "rt/tf", "tf2_msgs::msg::dds_::TFMessage_")
while writer.matched() == 0:
    time.sleep(0.05)
for sample in json.loads(sys.argv[2]):
    writer.write(bytes.fromhex(sample))
time.sleep(1.0)
print("written", flush=True)
"""


def test_bad_samples_are_one_line_each_and_the_bridge_carries_on(
        dds_domain, worlds, children, generated):
    world = worlds[0]
    importer = children.start([HORUS, "bridge", "--domain", str(dds_domain), "--import-frames",
                               "*", "--accept-untyped-writers"], python_env(world, generated))
    wait_line(importer, "importing frames")
    stamp = now_base()
    good = tf_message(("map", "odom", stamp, (1, 2, 3), (0, 0, 0, 1)))
    nan = tf_message(("map", "nan_frame", stamp, (math.nan, 0, 0), (0, 0, 0, 1)))
    unnormalised = tf_message(("map", "tilted", stamp, (0, 0, 0), (0, 0, 0, 2)))
    truncated = good[:-20]
    samples = [truncated, nan, unnormalised] * 3 + [good]
    raw = children.python(RAW_WRITER, python_env(world, generated), str(dds_domain),
                          json.dumps([s.hex() for s in samples]))
    wait_line(raw, "written")
    found = lookups(children, world, generated, [["map", "odom", None]])
    assert close(found["answers"][0][0], [1, 2, 3]), found
    assert "nan_frame" not in found["frames"] and "tilted" not in found["frames"], found
    assert importer.poll() is None
    importer.terminate()
    errors = importer.communicate(timeout=30)[1].splitlines()
    undecoded = [line for line in errors if "does not decode" in line]
    refused = [line for line in errors if "which the frame tree refused" in line]
    assert len(undecoded) == 1 and "tf2_msgs/msg/TFMessage" in undecoded[0], errors
    assert len(refused) == 2, errors
    assert any("'nan_frame'" in line for line in refused), refused
    assert any("'tilted'" in line for line in refused), refused
    assert importer.returncode == 0, errors


def test_a_local_topic_named_tf_is_refused_while_frames_cross(
        dds_domain, worlds, children, generated):
    world = worlds[0]
    holder = children.python("""
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "tf")
print("ready", flush=True)
time.sleep(60)
""", python_env(world, generated))
    wait_line(holder, "ready")
    both = children.start([HORUS, "bridge", "--domain", str(dds_domain), "--frames", "--export",
                           "*"], python_env(world, generated))
    wait_line(both, "exporting frames")
    time.sleep(1.6)  # three scans: the refusal is said once
    both.terminate()
    out, errors = both.communicate(timeout=30)
    refused = [line for line in errors.splitlines() if "cannot export topic 'tf'" in line]
    assert refused == ["horus bridge: cannot export topic 'tf': rt/tf carries the frames "
                       "(--export-frames, --import-frames)"], errors
    assert "exporting 'tf'" not in out
