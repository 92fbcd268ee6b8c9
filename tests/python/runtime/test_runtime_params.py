"""Parameters of Python nodes (horus.Node.declare_param, node.params, on_param_change) and the
tools' view of them (horus.Params, param_nodes, load_params, dump_params), against the C++ store:
writes from this process and from another, the node's callback between ticks (never during one)."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest
import yaml

import horus

from .conftest import python_child

ROOT = Path(__file__).resolve().parents[3]


class Motor(horus.Node):
    """A node with one parameter of each kind, recording what on_param_change sees."""

    def __init__(self, name: str = "motor") -> None:
        super().__init__(name=name, rate=200)
        self.max_speed = self.declare_param("max_speed", 1.0, min=0.0, max=2.0, unit="m/s",
                                            doc="Top speed the planner may command.")
        self.declare_param("profile", "eco", choices=["eco", "sport", "track"])
        self.declare_param("gains", [1.0, 0.5, 0.0])
        self.declare_param("wheels", 4, type="u8", read_only=True)
        self.declare_param("enabled", True)
        self.ticks = 0
        self.in_tick = False
        self.changes: list[tuple] = []
        self.started = threading.Event()

    def tick(self) -> None:
        self.in_tick = True
        self.ticks += 1
        time.sleep(0.0005)  # a tick long enough for a change arriving during it to wait
        self.in_tick = False
        self.started.set()

    def on_param_change(self, change: horus.ParamChange):
        self.changes.append((change.name, change.value, change.source, self.in_tick,
                             self.params.max_speed))
        if change.name == "profile" and change.value == "track":
            return horus.ParamVerdict.refuse("track mode needs the cage closed")
        return None


@pytest.fixture
def running():
    """Runs nodes in a scheduler on a thread of this process until the test ends."""
    scheds = []

    def start(*nodes, **config):
        sched = horus.Scheduler(tick_rate=200, **config)
        for node in nodes:
            sched.add(node)
        thread = threading.Thread(target=sched.run, daemon=True)
        thread.start()
        scheds.append((sched, thread))
        for node in nodes:
            assert node.started.wait(10), f"node {node.name} never ticked"
        return sched

    yield start
    for sched, thread in scheds:
        sched.stop()
        thread.join(10)


def test_declared_parameters_read_their_defaults_before_any_scheduler():
    node = Motor()
    assert node.params.max_speed == 1.0
    assert node.params.profile == "eco"
    assert node.params.gains == [1.0, 0.5, 0.0]
    assert node.params.wheels == 4
    assert node.params.enabled is True
    assert list(node.params) == ["max_speed", "profile", "gains", "wheels", "enabled"]
    assert node.params.version("max_speed") == 0
    assert node.max_speed.spelling == "f64"
    assert node.params["gains"] == [1.0, 0.5, 0.0]


def test_types_are_inferred_or_given():
    node = horus.Node(name="typed", tick=lambda n: None)
    assert node.declare_param("flag", False).spelling == "bool"
    assert node.declare_param("count", 3).spelling == "i64"
    assert node.declare_param("ratio", 0.5).spelling == "f64"
    assert node.declare_param("label", "x").spelling == "String"
    assert node.declare_param("offsets", [0.0, 1.0, 2.0]).spelling == "[f64; 3]"
    assert node.declare_param("gain", 2, type="f32").spelling == "f32"
    assert node.params.gain == 2.0


@pytest.mark.parametrize("name, default, options, fragment", [
    ("Bad-Name", 1.0, {}, "Bad-Name"),
    ("speed", 3.0, {"min": 0.0, "max": 2.0}, "speed"),
    ("profile", "race", {"choices": ["eco", "sport"]}, "profile"),
    ("label", "x" * 300, {}, "label"),
])
def test_a_bad_declaration_is_refused_where_it_is_made(name, default, options, fragment):
    node = horus.Node(name="bad", tick=lambda n: None)
    with pytest.raises(horus.ParamError, match=fragment):
        node.declare_param(name, default, **options)


def test_a_duplicate_or_an_untyped_declaration_is_refused():
    node = horus.Node(name="twice", tick=lambda n: None)
    node.declare_param("speed", 1.0)
    with pytest.raises(horus.ParamError, match="twice"):
        node.declare_param("speed", 2.0)
    with pytest.raises(TypeError, match="type="):
        node.declare_param("anything", object())
    with pytest.raises(horus.ParamError, match="unknown type 'f128'"):
        node.declare_param("wide", 1.0, type="f128")


def test_parameters_cannot_be_assigned_only_written_through_the_node():
    node = Motor()
    with pytest.raises(AttributeError, match="written through their node"):
        node.params.max_speed = 3.0
    with pytest.raises(AttributeError, match="did you mean 'max_speed'"):
        node.params.max_sped


def test_a_set_reaches_the_callback_once_between_ticks(running, namespace):
    node = Motor()
    running(node)
    assert horus.param_nodes() == ["motor"]
    with horus.Params("motor") as params:
        assert params.owner_alive
        before = params.get("max_speed")
        assert (before.value, before.version) == (1.0, 1)
        result = params.set("max_speed", 1.5)
        assert result == horus.ParamSetResult(True, "", 2)
        assert params.get("max_speed").value == 1.5
    assert node.params.max_speed == 1.5
    assert node.params.version("max_speed") == 2
    assert len(node.changes) == 1
    name, value, _source, in_tick, seen_before = node.changes[0]
    assert (name, value) == ("max_speed", 1.5)
    assert not in_tick, "on_param_change ran during a tick"
    assert seen_before == 1.0, "the value changed before the node accepted it"
    # Writes landing during ticks and between them alike: none runs inside a tick.
    with horus.Params("motor") as params:
        for i in range(40):
            assert params.set("max_speed", 0.5 + i / 40).accepted
            time.sleep(0.0003 * (i % 7))
    assert len(node.changes) == 41
    assert not any(in_tick for _n, _v, _s, in_tick, _seen in node.changes)


def test_a_refused_write_changes_nothing_and_says_why(running):
    node = Motor()
    running(node)
    with horus.Params("motor") as params:
        vetoed = params.set("profile", "track")
        assert not vetoed.accepted
        assert "track mode needs the cage closed" in vetoed.reason
        out_of_range = params.set("max_speed", 7.0)
        assert not out_of_range.accepted and out_of_range.reason
        info = params.get("profile")
        assert (info.value, info.version) == ("eco", 1)
        info = params.get("max_speed")
        assert (info.value, info.version) == (1.0, 1)
        assert params.set("profile", "sport").accepted
    assert node.params.profile == "sport"
    # The range is the declaration's: the node never saw the out-of-range value.
    assert [c[:2] for c in node.changes] == [("profile", "track"), ("profile", "sport")]


def test_another_process_writes_and_reads_the_node_parameters(running):
    node = Motor()
    running(node)
    writer = python_child(textwrap.dedent("""
        import horus
        with horus.Params("motor") as params:
            result = params.set("gains", [2.0, 0.25, 0.125], source="tuner")
            print(result.accepted, params.get("gains").value, params.owner_pid)
    """))
    out, err = writer.communicate(timeout=30)
    assert writer.returncode == 0, err
    assert out.split() == ["True", "[2.0,", "0.25,", "0.125]", str(os.getpid())]
    assert node.params.gains == [2.0, 0.25, 0.125]
    assert node.changes[-1][:3] == ("gains", [2.0, 0.25, 0.125], "tuner")


def test_a_callback_given_as_keyword_and_one_that_raises(running):
    seen = []

    def on_change(node, change):
        seen.append((node.name, change.name, change.value))
        if change.value > 10:
            raise RuntimeError("the encoder cannot go that fast")

    node = horus.Node(name="keyword", rate=200, tick=lambda n: n.started.set(),
                      on_param_change=on_change)
    node.started = threading.Event()
    node.declare_param("limit", 1)
    running(node)
    with horus.Params("keyword") as params:
        assert params.set("limit", 5).accepted
        failed = params.set("limit", 50)
        assert not failed.accepted
        assert "the encoder cannot go that fast" in failed.reason
        assert (params.get("limit").value, params.get("limit").version) == (5, 2)
    assert seen == [("keyword", "limit", 5), ("keyword", "limit", 50)]


def test_watch_wakes_on_a_change(running):
    node = Motor()
    running(node)
    with horus.Params("motor") as params:
        assert params.watch(timeout=0.05) == []
        writer = threading.Timer(0.1, lambda: horus.Params("motor").set("enabled", False))
        writer.start()
        changed = params.watch(timeout=10)
        writer.join()
    assert [(info.name, info.value, info.version) for info in changed] == [("enabled", False, 2)]


def test_an_enum_parameter_reads_as_its_generated_class_and_travels_by_name(running):
    from horus.msg import GoalStatus

    node = horus.Node(name="goals", rate=200, tick=lambda n: n.started.set())
    node.started = threading.Event()
    declared = node.declare_param("status", GoalStatus.Active)
    assert (declared.spelling, declared.enum_class) == ("horus.msg.GoalStatus", GoalStatus)
    assert node.params.status is GoalStatus.Active
    running(node)
    with horus.Params("goals") as params:
        info = params.get("status")
        assert (info.type, info.value) == ("horus.msg.GoalStatus", "Active")
        assert "Succeeded" in info.enumerators
        assert params.set("status", "Succeeded").accepted
        assert params.set("status", GoalStatus.Aborted).accepted
        refused = params.set("status", "Exploded")
        assert not refused.accepted and "'Exploded' is no enumerator" in refused.reason
    assert node.params.status is GoalStatus.Aborted


def test_dump_and_load_round_trip_and_scheduler_params_file(running, tmp_path):
    node = Motor()
    running(node)
    dumped = yaml.safe_load(horus.dump_params())
    assert dumped == {"motor": {"max_speed": 1.0, "profile": "eco", "gains": [1.0, 0.5, 0.0],
                                "wheels": 4, "enabled": True}}
    dumped["motor"]["profile"] = "sport"
    del dumped["motor"]["wheels"]  # read-only: written at a start only
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(dumped))
    results = horus.load_params(path)
    assert all(result.accepted for result in results), results
    assert node.params.profile == "sport"

    bad = tmp_path / "bad.yaml"
    bad.write_text("motor:\n  max_speed: 9.0\n")
    with pytest.raises(horus.ParamError, match="bad.yaml:2"):
        horus.load_params(bad)
    assert node.params.max_speed == 1.0


def test_a_scheduler_starts_its_nodes_with_a_parameter_file(running, tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text("second:\n  max_speed: 0.5\n  profile: sport\n")
    node = Motor("second")
    running(node, params=path)
    assert node.params.max_speed == 0.5
    assert node.params.profile == "sport"


def test_a_parameter_file_with_a_mistake_stops_the_start(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text("third:\n  max_speed: 5.0\n")
    sched = horus.Scheduler(tick_rate=100, params=path)
    sched.add(Motor("third"))
    with pytest.raises(horus.HorusError, match="robot.yaml:2"):
        sched.tick_once()


def test_params_of_a_node_without_a_store_say_so():
    with pytest.raises(horus.ParamError, match="nowhere"):
        horus.Params("nowhere")


def test_a_node_generated_from_an_hnode_declares_its_params_block(running, tmp_path):
    schemas = ROOT / "tests" / "schemas"
    files = sorted(str(p) for p in (schemas / "test_msgs").iterdir()
                   if p.suffix in (".hmsg", ".hsrv"))
    files += [str(schemas / "other_pkg" / "stamp.hmsg"),
              str(schemas / "test_nodes" / "param_node.hnode")]
    generated = subprocess.run(
        [sys.executable, str(ROOT / "generator" / "horus-gen"), "generate", "--lang", "python",
         "--out", str(tmp_path), "-I", str(schemas), *files], capture_output=True, text=True)
    assert generated.returncode == 0, generated.stderr
    sys.path.insert(0, str(tmp_path / "python"))
    try:
        from test_msgs import Mode
        from test_nodes import ParamNodeBase

        class Driver(ParamNodeBase):
            def __init__(self):
                super().__init__()
                self.started = threading.Event()

            def tick(self):
                self.started.set()

        node = Driver()
        assert (node.params.max_speed, node.params.mode, node.params.mask) == (
            1.0, Mode.Run, [True, False])
        running(node)
        with horus.Params("param_node") as params:
            described = params.get("max_speed")
            assert (described.type, described.min, described.max, described.unit, described.doc) \
                == ("f64", 0.0, 2.0, "m/s", "Top speed the planner may command.")
            assert params.get("mode").choices == ["Idle", "Run"]
            assert params.set("mode", "Idle").accepted
            assert params.set("gain", 0.25).accepted
            assert not params.set("offset", 11).accepted
        assert (node.params.mode, node.params.gain, node.params.offset) == (Mode.Idle, 0.25, 0)
    finally:
        sys.path.remove(str(tmp_path / "python"))
        for name in [m for m in sys.modules if m.split(".")[0] in ("test_msgs", "test_nodes",
                                                                     "other_pkg")]:
            del sys.modules[name]


def test_a_declaration_after_the_scheduler_took_the_node_is_refused():
    node = Motor("late")
    sched = horus.Scheduler(tick_rate=100)
    sched.add(node)
    with pytest.raises(horus.ParamError, match="declare parameters in __init__"):
        node.declare_param("afterthought", 1.0)
    with pytest.raises(ValueError, match="says why"):
        horus.ParamVerdict.refuse("")
