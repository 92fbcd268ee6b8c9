"""Names and encodings at the edge of `horus bridge`: HORUS's dotted topic names (`motor.cmd`)
cross as ROS 2 namespaces (rt/motor/cmd) both ways, POD and serialized, between two namespaces
and with a plain DDS program; a name with no counterpart on the other side is refused in one
line while the others cross; a DDS writer that writes XCDR2 is refused in one line naming it,
and nothing of it reaches the local topic."""
from __future__ import annotations

import pytest

from peer_scripts import RECEIVE_IN_ORDER
from processes import Output, wait_line
from test_bridge import (COUNT, HOLDER, PODS, RING, assert_in_order, bridge, python_env,
                         sequences)

# Publishes an increasing sequence on motor.cmd (CmdVel, POD), emergency.stop (Pods, POD) and
# camera.rgb (Kinds, serialized), 100 a second, until killed.
PUBLISHER = RING + PODS + """
import time, horus
from horus.msg import CmdVel
from dds_test import Kinds
topics = {name: horus.Topic(cls, name, capacity=capacity) for name, cls in
          (("motor.cmd", CmdVel), ("emergency.stop", Pods), ("camera.rgb", Kinds))}
print("ready", flush=True)
i = 0
while True:
    topics["motor.cmd"].send(CmdVel(stamp_nanos=i, linear=0.5 * i, angular=-1.0))
    topics["emergency.stop"].send(pods(i))
    topics["camera.rgb"].send(Kinds(big=i, name=f"n{i}", values=[float(i)], maybe=None))
    i += 1
    time.sleep(0.01)
"""

SUBSCRIBER = RING + PODS + """
import sys, time, horus
from horus.msg import CmdVel
from dds_test import Kinds
count = int(sys.argv[1])
wanted = {"motor.cmd": (CmdVel, lambda m: (m.stamp_nanos, m.linear == 0.5 * m.stamp_nanos)),
          "emergency.stop": (Pods, lambda m: (m.seq, m == pods(m.seq))),
          "camera.rgb": (Kinds, lambda m: (m.big, m.name == f"n{m.big}" and m.values == [m.big]))}
""" + RECEIVE_IN_ORDER

# Holds `name` open as a CmdVel and publishes a sequence on it, 100 a second, until killed.
SEQUENCE = """
import sys, time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, sys.argv[1])
print("ready", flush=True)
i = 0
while True:
    topic.send(CmdVel(stamp_nanos=i, linear=0.5 * i, angular=-1.0))
    i += 1
    time.sleep(0.01)
"""


@pytest.mark.parametrize("direction", ["a_to_b", "b_to_a"])
def test_dotted_topics_cross_as_ros2_namespaces_in_order(direction, dds_domain, worlds, children,
                                                         generated, kinds_class):
    source, target = worlds if direction == "a_to_b" else reversed(worlds)
    subscriber = children.python(SUBSCRIBER, python_env(target, generated), str(COUNT),
                                 "motor.cmd", "emergency.stop", "camera.rgb")
    wait_line(subscriber, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "motor.*",
                      "--import", "emergency.*", "--import", "camera.*")
    exporter = bridge(children, source, generated, dds_domain, "--export", "motor.*",
                      "--export", "emergency.stop", "--export", "camera.rgb")

    got = sequences(subscriber)
    for name in ("motor.cmd", "emergency.stop", "camera.rgb"):
        assert_in_order(name, got[name])
    exported = {wait_line(exporter, "exporting") for _ in range(3)}
    assert exported == {
        "exporting 'motor.cmd' (horus.msg.CmdVel) as rt/motor/cmd (horus::msg::dds_::CmdVel_)",
        "exporting 'emergency.stop' (dds_test.Pods) as rt/emergency/stop (dds_test::dds_::Pods_)",
        "exporting 'camera.rgb' (dds_test.Kinds) as rt/camera/rgb (dds_test::dds_::Kinds_)"}
    imported = {wait_line(importer, "importing") for _ in range(3)}
    assert imported == {
        "importing rt/motor/cmd (horus::msg::dds_::CmdVel_) as 'motor.cmd' (horus.msg.CmdVel)",
        "importing rt/emergency/stop (dds_test::dds_::Pods_) as 'emergency.stop' (dds_test.Pods)",
        "importing rt/camera/rgb (dds_test::dds_::Kinds_) as 'camera.rgb' (dds_test.Kinds)"}


def test_a_plain_dds_program_reads_a_dotted_topic_as_a_ros2_namespace(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    publisher = children.python(SEQUENCE, python_env(source, generated), "arm.state")
    wait_line(publisher, "ready")
    peer = children.start([dds_peer, "read-cmdvel", str(dds_domain), str(COUNT),
                           "--topic", "rt/arm/state"])
    wait_line(peer, "ready")
    bridge(children, source, generated, dds_domain, "--export", "arm.*")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0, errors
    samples = [dict(field.split("=") for field in line.split()) for line in out.splitlines()]
    assert_in_order("rt/arm/state", [int(sample["stamp_nanos"]) for sample in samples])
    assert all(float(s["linear"]) == 0.5 * int(s["stamp_nanos"]) for s in samples), out


def test_a_plain_dds_program_writes_a_ros2_namespace_into_a_dotted_topic(
        dds_domain, worlds, children, generated, dds_peer):
    target = worlds[1]
    holder = children.python(HOLDER, python_env(target, generated), "arm.state",
                             "dds_test.Kinds")
    wait_line(holder, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "arm.*")
    peer = children.start([dds_peer, "write-kinds", str(dds_domain), "--topic", "rt/arm/state"])
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0, errors
    assert "'name': 'from C'" in out and "'big': -9000000000" in out, out
    assert wait_line(importer, "importing") == (
        "importing rt/arm/state (dds_test::dds_::Kinds_) as 'arm.state' (dds_test.Kinds)")
    peer.communicate(timeout=30)
    assert peer.returncode == 0


def test_a_name_dds_cannot_hold_is_refused_in_one_line_and_the_others_cross(
        dds_domain, worlds, children, generated, dds_peer):
    source = worlds[0]
    for name in ("arm-1", "arm.state"):
        wait_line(children.python(SEQUENCE, python_env(source, generated), name), "ready")
    peer = children.start([dds_peer, "read-cmdvel", str(dds_domain), "1",
                           "--topic", "rt/arm/state"])
    wait_line(peer, "ready")
    exporter = bridge(children, source, generated, dds_domain, "--export", "arm*")
    said = Output(exporter.stderr)
    assert said.wait_for("arm-1") == (
        "horus bridge: cannot export topic 'arm-1': DDS topic names cannot hold its '-' (DDS and "
        "ROS 2 allow letters, digits, '_' and '/' only, and '_' and '/' already stand for "
        "HORUS's '_' and '.')")
    assert wait_line(exporter, "exporting").startswith(
        "exporting 'arm.state' (horus.msg.CmdVel) as rt/arm/state")
    out, errors = peer.communicate(timeout=60)
    assert peer.returncode == 0 and out.startswith("stamp_nanos="), errors
    assert said.lines == [said.wait_for("arm-1")], said.lines

def test_an_xcdr2_writer_is_refused_naming_it_and_none_of_its_samples_arrive(
        dds_domain, worlds, children, generated, dds_peer):
    target = worlds[1]
    holder = children.python(HOLDER, python_env(target, generated), "kinds", "dds_test.Kinds")
    wait_line(holder, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "kinds")
    said = Output(importer.stderr)
    # Its one sample says "from C in XCDR2"; the XCDR1 writer's after it says "from C".
    children.start([dds_peer, "write-kinds", str(dds_domain), "--xcdr2"])
    line = said.wait_for("XCDR2")
    assert line.startswith("horus bridge: cannot import topic 'kinds' from DDS writer "), line
    assert line.endswith(": it writes XCDR2, the bridge reads XCDR1 only (DDS does not match "
                         "them)"), line
    peer = children.start([dds_peer, "write-kinds", str(dds_domain)])
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0, errors
    assert "'name': 'from C'" in out and "'big': -9000000000" in out, out
    peer.communicate(timeout=30)
    assert peer.returncode == 0
    assert said.lines == [line], said.lines
