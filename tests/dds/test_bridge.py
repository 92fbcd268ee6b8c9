"""`horus bridge`: two HORUS namespaces that share no memory talk through Cyclone DDS alone (POD
topics through the bridge's C++ pumps, serialized ones through its Python threads), and a plain
idlc-built DDS program reads and writes HORUS topics through a bridge."""
from __future__ import annotations

import os
import subprocess

import pytest

from peer_scripts import RECEIVE_IN_ORDER
from processes import wait_line

HORUS = os.environ.get("HORUS_CLI", "")
COUNT = 40

# Rings and DDS histories deep enough for seconds of a stalled process: on a loaded machine a
# process may not run for that long, and the sequence check is about order and loss in the
# bridge, not about how far a Python process can fall behind a ring.
RING = "capacity = 512\n"
DEPTH = "1000"

# The i-th message of pods: a POD type with every kind of POD field (schemas/dds_test/pod.hmsg).
PODS = """
from dds_test import Gear, Pods, Wheel
def pods(i):
    return Pods(seq=i, on=i % 2 == 0, tiny=-(i % 100), half=-i, word=3 * i, delta=-(i << 20),
                ratio=i / 4, wide=i / 3, gear=Gear.Reverse, label=f"p{i}", full="full",
                after=i % 65536, direction=[i, 0.5, -1.0], grid=[[i, -i, 1], [2, 3, -4]],
                flags=[True, i % 2 == 1, False], names=["", f"{i % 1000}"],
                gears=[Gear.Drive, Gear.Park], wheel=Wheel(id=7, speed=-i),
                wheels=[Wheel(id=i % 65536, speed=i / 8), Wheel()], last=i % 256)
"""

# Publishes an increasing sequence on cmd_vel and pods (POD), kinds (serialized) and secret
# (never exported), 100 a second, until killed.
PUBLISHER = RING + PODS + """
import time, horus
from horus.msg import CmdVel
from dds_test import Kinds
topics = {name: horus.Topic(cls, name, capacity=capacity) for name, cls in
          (("cmd_vel", CmdVel), ("kinds", Kinds), ("pods", Pods), ("secret", CmdVel))}
print("ready", flush=True)
i = 0
while True:
    topics["cmd_vel"].send(CmdVel(stamp_nanos=i, linear=0.5 * i, angular=-1.0))
    topics["kinds"].send(Kinds(big=i, name=f"n{i}", values=[float(i)], maybe=None))
    topics["pods"].send(pods(i))
    topics["secret"].send(CmdVel(stamp_nanos=i))
    i += 1
    time.sleep(0.01)
"""

# Prints the first COUNT messages of each of the topics it is given: "<topic> <seq> ...".
SUBSCRIBER = RING + PODS + """
import sys, time, horus
from horus.msg import CmdVel
from dds_test import Kinds
count = int(sys.argv[1])
wanted = {"cmd_vel": (CmdVel, lambda m: (m.stamp_nanos, m.linear == 0.5 * m.stamp_nanos)),
          "kinds": (Kinds, lambda m: (m.big, m.name == f"n{m.big}" and m.values == [m.big])),
          "pods": (Pods, lambda m: (m.seq, m == pods(m.seq)))}
""" + RECEIVE_IN_ORDER


def python_env(world, generated) -> dict:
    path = os.pathsep.join([str(generated / "python"), os.environ.get("PYTHONPATH", "")])
    return world.env(PYTHONPATH=path)


def bridge(children, world, generated, domain: int, *patterns: str):
    process = children.start([HORUS, "bridge", "--domain", str(domain), "--depth", DEPTH, *patterns],
                             python_env(world, generated))
    wait_line(process, "bridge on DDS domain")
    return process


def sequences(process) -> dict[str, list[int]]:
    out, errors = process.communicate(timeout=60)
    assert process.returncode == 0, errors
    return {line.split()[0]: [int(n) for n in line.split()[1:]] for line in out.splitlines()
            if line != "ready"}


def assert_in_order(name: str, seen: list[int]) -> None:
    assert len(seen) == COUNT, f"{name}: {seen}"
    expected = list(range(seen[0], seen[0] + COUNT))
    assert seen == expected, f"{name}: expected {expected}, got {seen} (-1: altered content)"


def horus_in(world, generated, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([HORUS, *args], capture_output=True, text=True, timeout=30,
                          env=python_env(world, generated))


@pytest.mark.parametrize("direction", ["a_to_b", "b_to_a"])
def test_exported_topics_reach_the_other_namespace_in_order_and_nothing_else_does(
        direction, dds_domain, worlds, children, generated, kinds_class):
    source, target = worlds if direction == "a_to_b" else reversed(worlds)
    subscriber = children.python(SUBSCRIBER, python_env(target, generated), str(COUNT), "cmd_vel",
                                 "kinds", "pods")
    wait_line(subscriber, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    bridge(children, target, generated, dds_domain, "--import", "*")
    exporter = bridge(children, source, generated, dds_domain, "--export", "cmd_vel",
                      "--export", "kin*", "--export", "pods")

    got = sequences(subscriber)
    assert_in_order("cmd_vel", got["cmd_vel"])
    assert_in_order("kinds", got["kinds"])
    assert_in_order("pods", got["pods"])
    # secret was never exported: the target namespace has no such topic, DDS no such topic.
    listed = horus_in(target, generated, "topic", "list")
    assert listed.returncode == 0 and "secret" not in listed.stdout.split(), listed.stdout
    exporter.kill()
    out, _ = exporter.communicate()
    assert "exporting 'cmd_vel'" in out and "secret" not in out, out


def test_a_plain_dds_program_reads_a_horus_topic_through_the_bridge(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    peer = children.start([dds_peer, "read-cmdvel", str(dds_domain), str(COUNT)])
    wait_line(peer, "ready")
    bridge(children, source, generated, dds_domain, "--export", "cmd_vel")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    samples = [dict(field.split("=") for field in line.split()) for line in out.splitlines()]
    stamps = [int(sample["stamp_nanos"]) for sample in samples]
    assert_in_order("rt/cmd_vel", stamps)
    assert all(float(s["linear"]) == 0.5 * int(s["stamp_nanos"]) and s["angular"] == "-1"
               for s in samples), out


# Holds `name` open with `type` and prints the first message's fields as a dict, if one comes.
HOLDER = """
import sys, horus, importlib
package, _, short = sys.argv[2].rpartition(".")
cls = getattr(importlib.import_module(package), short)
topic = horus.Topic(cls, sys.argv[1])
print("ready", flush=True)
message = topic.recv(timeout=60)
print({name: getattr(message, name) for name in cls.__horus__.fields}, flush=True)
"""


def test_a_plain_dds_program_writes_into_a_local_topic_through_the_bridge(
        dds_domain, worlds, children, generated, dds_peer):
    target = worlds[1]
    holder = children.python(HOLDER, python_env(target, generated), "kinds", "dds_test.Kinds")
    wait_line(holder, "ready")
    # The C writer carries no HORUS identity: the local topic gives the type.
    bridge(children, target, generated, dds_domain, "--import", "kinds")
    peer = children.start([dds_peer, "write-kinds", str(dds_domain)])
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0, errors
    assert "'name': 'from C'" in out and "'big': -9000000000" in out, out
    peer.communicate(timeout=30)
    assert peer.returncode == 0


def test_a_remote_topic_of_another_type_is_refused_naming_both(
        dds_domain, worlds, children, generated):
    source, target = worlds
    holder = children.python(HOLDER, python_env(target, generated), "cmd_vel", "horus.msg.Twist")
    wait_line(holder, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "*")
    bridge(children, source, generated, dds_domain, "--export", "cmd_vel")
    line = importer.stderr.readline()
    assert "cannot import topic 'cmd_vel'" in line, line
    assert "horus.msg.Twist" in line and "horus.msg.CmdVel" in line, line
    assert holder.poll() is None  # nothing reached the local topic


def test_a_bridge_given_nothing_to_carry_is_a_usage_error(worlds, generated):
    result = horus_in(worlds[0], generated, "bridge", "--domain", "3")
    assert result.returncode == 2 and result.stderr.strip().splitlines() == [
        "horus: nothing to bridge: give --export and/or --import patterns (or --export-service, "
        "--import-service, --export-frames, --import-frames, --frames, --export-action, "
        "--import-action)"
    ], result.stderr
