"""Python node classes generated from .hnode files (tests/schemas/test_nodes): horus.Node
subclasses with the declared name, settings, data and parameters (node.params), typed topic
handles (self.<member>), and the same topics as the C++ base classes generated from the same files."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import horus

ROOT = Path(__file__).resolve().parents[3]
SCHEMAS = ROOT / "tests" / "schemas"


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """test_msgs (with the other_pkg it uses) and test_nodes generated for Python, imported."""
    out = tmp_path_factory.mktemp("hnode")
    files = sorted(str(p) for p in (SCHEMAS / "test_msgs").iterdir() if p.suffix in (".hmsg", ".hsrv"))
    files += [str(SCHEMAS / "other_pkg" / "stamp.hmsg")]
    files += sorted(str(p) for p in (SCHEMAS / "test_nodes").iterdir() if p.suffix == ".hnode")
    result = subprocess.run(["/usr/bin/python3", str(ROOT / "generator" / "horus-gen"), "generate", "--lang",
                             "python", "--out", str(out), "-I", str(SCHEMAS), *files], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    sys.path.insert(0, str(out / "python"))
    try:
        import test_msgs
        import test_nodes
        yield test_msgs, test_nodes
    finally:
        sys.path.remove(str(out / "python"))


def test_the_class_carries_the_declared_name_settings_and_topics(generated):
    test_msgs, test_nodes = generated

    class Tracker(test_nodes.TrackerBase):
        def tick(self):
            pass

    tracker = Tracker()
    assert isinstance(tracker, horus.Node)
    assert tracker.name == "tracker"
    assert (tracker.order, tracker.rate) == (5, 250.0)
    assert (tracker.budget, tracker.deadline, tracker.watchdog) == (0.001, 0.0025, 0.1)
    assert (tracker.on_miss, tracker.failure_policy) == ("skip", "skip")
    assert (tracker.priority, tracker.core) == (10, 0)
    assert tracker.subs == {"tracker.pose": test_msgs.Pose2, "samples": test_msgs.Serialized}
    assert tracker.pubs == {"tracker.last": test_msgs.Point2}
    assert tracker.topic_capacities == {"tracker.pose": 16}
    listener = test_nodes.ListenerBase()
    assert listener.on == "pair.pose" and listener.rate is None
    assert test_nodes.PlannerBase().compute is True
    assert test_nodes.PlannerBase().name == "Planner"
    # Keywords override what the file declares.
    assert test_nodes.TalkerBase(rate=50.0, name="talker2").rate == 50.0


def test_a_params_block_declares_each_parameter_at_its_default(generated):
    test_msgs, test_nodes = generated
    node = test_nodes.ParamNodeBase()
    assert list(node.params) == ["max_speed", "gain", "offset", "wheel_count", "enabled", "profile", "mode",
                                 "gains", "mask", "ticks"]
    assert (node.params.max_speed, node.params.gain, node.params.offset) == (1.0, 0.5, 0)
    assert (node.params.wheel_count, node.params.enabled, node.params.profile) == (4, True, "eco")
    assert node.params.mode == test_msgs.Mode.Run
    assert node.params.gains == [1.0, 0.5, 0.0] and node.params.mask == [True, False]
    assert node.params.ticks == 0


def test_data_members_start_at_their_declared_defaults(generated):
    test_msgs, test_nodes = generated
    tracker = test_nodes.TrackerBase()
    assert tracker.gain == 0.5
    assert tracker.mode is test_msgs.Mode.Run
    assert tracker.label == "tracker"
    assert tracker.history == [1.0, 2.0, 3.0]
    assert tracker.seen == [] and tracker.note is None and tracker.enabled is True
    assert tracker.last_pose == test_msgs.Pose2()
    assert tracker.where_is is None  # a server member: set by serve_where_is()
    talker = test_nodes.TalkerBase()
    assert (talker.step, talker.sent) == (0.25, 0)
    # Each instance owns its mutable data.
    other = test_nodes.TrackerBase()
    tracker.seen.append(test_msgs.Point2(x=1.0))
    assert other.seen == []


def test_typed_handles_carry_the_declared_messages_between_nodes(generated):
    test_msgs, test_nodes = generated

    class Talker(test_nodes.TalkerBase):
        def tick(self):
            self.sent += 1
            self.pose.send(test_msgs.Pose2(position=test_msgs.Point2(x=self.step * self.sent)))

    class Listener(test_nodes.ListenerBase):
        def __init__(self):
            super().__init__()
            self.xs = []

        def tick(self):
            while (pose := self.pose.try_recv()) is not None:
                self.received += 1
                self.xs.append(pose.position.x)
                self.echo.send(pose.position)

    listener, talker = Listener(), Talker()
    # The listener opens "pair.pose" first: created with its declared #[capacity = 8].
    assert listener.pose.capacity == 8
    sched = horus.Scheduler(deterministic=True, tick_rate=200.0)
    sched.add(talker).add(listener)
    for _ in range(4):
        sched.tick_once()
    assert listener.received == 4
    assert listener.xs == [0.25, 0.5, 0.75, 1.0]
    assert isinstance(talker.pose, horus.Topic) and talker.pose.type is test_msgs.Pose2
    nodes = {n["name"]: n for n in sched.get_all_nodes()}
    assert nodes["listener"]["execution_class"] == "Event"


def test_a_python_node_and_a_cpp_program_declared_by_the_same_files_talk(generated):
    """The C++ talker of horus_node_pair (talker.hnode) feeds a Python node of listener.hnode."""
    test_msgs, test_nodes = generated
    program = os.environ.get("HORUS_NODE_PAIR")
    assert program, "HORUS_NODE_PAIR names tests/generated's horus_node_pair; run through ctest"

    class Listener(test_nodes.ListenerBase):
        def __init__(self):
            super().__init__(name="py_listener")
            self.xs = []

        def tick(self):
            while (pose := self.pose.try_recv()) is not None:
                self.xs.append(pose.position.x)

    listener = Listener()
    sched = horus.Scheduler(tick_rate=200.0)
    sched.add(listener)
    sched.tick_once()  # opens the topics first: the C++ talker's poses from now on reach it
    cpp = subprocess.Popen([program], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True)
    try:
        assert cpp.stdout.readline().strip() == "ready", cpp.stderr.read()
        # Until poses arrived (a loaded machine may take a while): this waits, it measures nothing.
        for _ in range(100):
            sched.tick_for(0.2)
            if len(listener.xs) >= 3:
                break
    finally:
        cpp.communicate(input="", timeout=30)
    assert cpp.returncode == 0
    assert len(listener.xs) >= 3
    # The C++ talker sends step * n: 0.25, 0.5, ... in order.
    assert all(x > 0 and (x / 0.25).is_integer() for x in listener.xs)
    assert listener.xs == sorted(listener.xs)


def test_a_server_started_in_init_answers_another_nodes_client_member(generated):
    """tracker.hnode's Tracker serves where_is (serve_where_is() in init()); the Reporter's
    generated client member where_is calls it, as tests/generated does in C++."""
    test_msgs, test_nodes = generated
    GetRobotPose = test_msgs.GetRobotPose

    class Tracker(test_nodes.TrackerBase):
        def init(self):
            self.serve_where_is(lambda request: GetRobotPose.Response(
                x=self.gain * 4.0 if request.robot_name == "agv" else -1.0))

        def shutdown(self):
            self.where_is.stop()

        def tick(self):
            pass

    class Reporter(test_nodes.ReporterBase):
        def tick(self):
            pass

    tracker, reporter = Tracker(), Reporter()
    with horus.Scheduler(deterministic=True, tick_rate=100.0) as sched:
        sched.add(tracker).add(reporter)
        assert tracker.where_is is None
        sched.tick_once()  # init(): the tracker starts serving
        assert isinstance(tracker.where_is, horus.ServiceServer)
        assert isinstance(reporter.where_is, horus.ServiceClient)
        assert reporter.where_is.call(GetRobotPose.Request(robot_name="agv"), timeout=5.0).x == 2.0
        assert reporter.where_is.call(GetRobotPose.Request(robot_name="other"), timeout=5.0).x == -1.0
        assert tracker.where_is.requests == 2
        reporter.where_is.close()
