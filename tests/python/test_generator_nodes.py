"""horus-gen on node files (.hnode): the whole-graph checks of `check`, `describe --graph` (dot and
JSON), nodes in `describe --json`, and the generated code against tests/golden/nodes.

Refresh the generated-code golden files after an intended change, then read the diff:
    HORUS_UPDATE_GOLDEN=1 /usr/bin/python3 -m pytest tests/python/test_generator_nodes.py
"""
from __future__ import annotations

import json
import os

import pytest

from generator_testing import GOLDEN, SCHEMAS, run_horus_gen

NODES = SCHEMAS / "test_nodes"
PAIR = [str(NODES / "talker.hnode"), str(NODES / "listener.hnode")]


def warnings_of(stderr: str) -> list[str]:
    return [line.split(": warning: ", 1)[1] for line in stderr.splitlines() if ": warning: " in line]


def write(tmp_path, name: str, text: str) -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_check_warns_about_topics_nobody_publishes_or_reads_and_still_succeeds():
    result = run_horus_gen("check", "-I", str(SCHEMAS), *PAIR)
    assert result.returncode == 0, result.stderr
    # pair.pose has both ends; the listener's echo has no reader among these files.
    assert warnings_of(result.stderr) == [
        "node 'listener' publishes topic 'pair.echo', which no node of these files subscribes to"]
    assert result.stderr.endswith("1 warning generated.\n")


def test_check_warns_about_a_topic_nobody_publishes_at_its_subscription():
    listener = str(NODES / "listener.hnode")
    result = run_horus_gen("check", "-I", str(SCHEMAS), listener)
    assert result.returncode == 0, result.stderr
    # Without the talker, nobody publishes the pose the listener subscribes to.
    assert f"{listener}:12:13: warning: node 'listener' subscribes to topic 'pair.pose', which no " \
        "node of these files publishes\n" in result.stderr
    assert warnings_of(result.stderr) == [
        "node 'listener' subscribes to topic 'pair.pose', which no node of these files publishes",
        "node 'listener' publishes topic 'pair.echo', which no node of these files subscribes to"]
    assert result.stderr.endswith("2 warnings generated.\n")


def test_check_warns_about_a_service_nobody_serves(tmp_path):
    result = run_horus_gen("check", "-I", str(SCHEMAS), str(NODES / "tracker.hnode"))
    assert result.returncode == 0, result.stderr
    assert "node 'tracker' calls service 'test_msgs.AddInts', which no node of these files serves" in \
        warnings_of(result.stderr)
    # The tracker serves GetRobotPose, which the reporter calls: no warning for it.
    assert not any("GetRobotPose" in w for w in warnings_of(result.stderr))


def test_a_topic_with_two_types_across_files_is_an_error(tmp_path):
    publisher = write(tmp_path, "a.hnode", 'A { pub { out: test_msgs::Point2 -> "shared" } }\n')
    subscriber = write(tmp_path, "b.hnode", 'B { sub { inp: test_msgs::Pose2 -> "shared" } }\n')
    result = run_horus_gen("check", "-I", str(SCHEMAS), publisher, subscriber)
    assert result.returncode == 1
    assert "b.hnode:1:11: error: node 'B' subscribes to topic 'shared' as 'test_msgs.Pose2', but node 'A' has " \
           "it as 'test_msgs.Point2'" in result.stderr
    assert "a.hnode:1:11: note: 'A' declares it here" in result.stderr
    # generate refuses it too, and writes nothing.
    out = tmp_path / "out"
    assert run_horus_gen("generate", "--out", str(out), "-I", str(SCHEMAS), publisher, subscriber).returncode == 1
    assert not out.exists()


def test_a_service_served_by_two_nodes_is_an_error(tmp_path):
    first = write(tmp_path, "a.hnode", "A { server { s: test_msgs::AddInts } }\n")
    second = write(tmp_path, "b.hnode", "B { server { s: test_msgs::AddInts } }\n")
    result = run_horus_gen("check", "-I", str(SCHEMAS), first, second)
    assert result.returncode == 1
    assert "error: service 'test_msgs.AddInts' is served by two nodes: 'A' and 'B'" in result.stderr


def test_describe_graph_prints_graphviz_dot():
    result = run_horus_gen("describe", "--graph", "-I", str(SCHEMAS), *PAIR)
    assert result.returncode == 0, result.stderr
    assert result.stdout == """digraph horus {
  rankdir=LR;
  node [fontname="Helvetica"];
  "node:talker" [shape=box, label="talker\\n200 Hz"];
  "node:listener" [shape=box, label="listener\\non pair.pose"];
  "topic:pair.echo" [shape=ellipse, label="pair.echo\\ntest_msgs.Point2"];
  "node:listener" -> "topic:pair.echo";
  "topic:pair.pose" [shape=ellipse, label="pair.pose\\ntest_msgs.Pose2"];
  "node:talker" -> "topic:pair.pose";
  "topic:pair.pose" -> "node:listener";
}
"""


def test_describe_graph_json_lists_nodes_topics_and_services():
    files = PAIR + [str(NODES / "tracker.hnode")]
    result = run_horus_gen("describe", "--graph", "--json", "-I", str(SCHEMAS), *files)
    assert result.returncode == 0, result.stderr
    graph = json.loads(result.stdout)
    assert [n["name"] for n in graph["nodes"]] == ["talker", "listener", "tracker", "Planner", "reporter"]
    topics = {t["name"]: t for t in graph["topics"]}
    assert topics["pair.pose"] == {"name": "pair.pose", "type": "test_msgs.Pose2", "publishers": ["talker"],
                                   "subscribers": ["listener"]}
    assert topics["tracker.pose"]["subscribers"] == ["tracker", "Planner"]
    assert topics["tracker.pose"]["publishers"] == []
    services = {s["name"]: s for s in graph["services"]}
    assert services["test_msgs.GetRobotPose"] == {"name": "test_msgs.GetRobotPose", "clients": ["reporter"],
                                                  "servers": ["tracker"]}


def test_describe_json_describes_each_node_for_other_tools():
    result = run_horus_gen("describe", "--json", "-I", str(SCHEMAS), str(NODES / "tracker.hnode"))
    assert result.returncode == 0, result.stderr
    tracker = next(t for t in json.loads(result.stdout)["types"] if t["name"] == "tracker")
    assert tracker["kind"] == "node" and tracker["class"] == "test_nodes.Tracker"
    assert tracker["base_class"] == "test_nodes.TrackerBase"
    assert tracker["subscribers"] == [
        {"member": "pose", "topic": "tracker.pose", "type": "test_msgs.Pose2", "capacity": 16},
        {"member": "samples", "topic": "samples", "type": "test_msgs.Serialized"}]
    assert tracker["clients"] == [{"member": "adder", "service": "test_msgs.AddInts"}]
    assert tracker["servers"] == [{"member": "where_is", "service": "test_msgs.GetRobotPose"}]
    assert tracker["settings"] == {
        "order": 5, "rate_hz": 250.0, "budget_ns": 1_000_000, "deadline_ns": 2_500_000, "watchdog_ns": 100_000_000,
        "on_miss": "Skip", "failure_policy": {"kind": "Skip", "max_failures": 4, "cooldown_ns": 20_000_000},
        "priority": 10, "core": 0}


def test_topic_name_defaults_to_the_message_topic_attribute_then_the_member(tmp_path):
    folder = tmp_path / "robot"
    folder.mkdir()
    write(folder, "imu.hmsg", '#[topic = "imu.raw"]\nImu { x: f32 }\nPlain { x: f32 }\n')
    node = write(folder, "n.hnode", "N { sub { imu: Imu, plain: Plain, other: Imu -> \"imu.filtered\" } }\n")
    result = run_horus_gen("describe", "--json", node)
    assert result.returncode == 0, result.stderr
    subs = json.loads(result.stdout)["types"][0]["subscribers"]
    assert [(s["member"], s["topic"], s["type"]) for s in subs] == [
        ("imu", "imu.raw", "robot.Imu"), ("plain", "plain", "robot.Plain"), ("other", "imu.filtered", "robot.Imu")]


GENERATED_GOLDEN = GOLDEN / "nodes"
GENERATED_FILES = ["cpp/test_nodes/talker.hpp", "cpp/test_nodes/listener.hpp", "cpp/test_nodes/_nodes.cpp",
                   "python/test_nodes/_talker.py", "python/test_nodes/_listener.py"]


@pytest.mark.parametrize("relative", GENERATED_FILES)
def test_generated_code_matches_golden(tmp_path, relative):
    result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(tmp_path), "-I", str(SCHEMAS), *PAIR)
    assert result.returncode == 0, result.stderr
    produced = (tmp_path / relative).read_text()
    # Named .golden: the linters would otherwise format-check them as the project's own sources.
    expected = GENERATED_GOLDEN / (relative.replace("/", "__") + ".golden")
    if os.environ.get("HORUS_UPDATE_GOLDEN"):
        expected.parent.mkdir(exist_ok=True)
        expected.write_text(produced)
    assert produced == expected.read_text(), f"{relative} differs from {expected.name}"
