"""Parameters in the live view (the Foxglove protocol's `parameters` and `parametersSubscribe`
capabilities), with Foxglove's own client (client_check.mjs): a Python node process declares
parameters; the client gets them (named NODE.PARAMETER, float64 type hints), sets one (answered
with the value after the write), is refused out of range and by the node's own veto with the
reason as a status, and receives the update `horus param set` makes from another process. With a
policy, a peer without a `param` line sees and sets none; one with it only what it names."""
from __future__ import annotations

import os
import pathlib
import subprocess

import pytest
from conftest import GENERATOR, VIEW, run_node_client
from peer_scripts import param_motor
from processes import wait_line

# Set by tests/view/CMakeLists.txt.
HORUS = os.environ.get("HORUS_CLI", "")

# The node (peer_scripts.param_motor), with a read-only integer and a bool too.
MOTOR = param_motor('self.declare_param("wheels", 4, type="u8", read_only=True)',
                    'self.declare_param("enabled", True)')

# The generated ParamNode (tests/schemas/test_nodes/param_node.hnode): every kind a params block
# declares, an enum (test_msgs::Mode) and an f32 among them.
PARAM_NODE = """
import test_nodes

class Node(test_nodes.ParamNodeBase):
    def tick(self):
        if not getattr(self, "started", False):
            self.started = True
            print("ready", flush=True)

import horus
horus.Scheduler(tick_rate=100).add(Node()).run()
"""
TEST_SCHEMAS = pathlib.Path(__file__).resolve().parents[1] / "schemas"

TOKENS = {"alice": "alice-0123456789abcdef", "bob": "bob-0123456789abcdef00"}


@pytest.fixture
def motor(namespace, children):
    process = children.python(MOTOR, dict(os.environ))
    wait_line(process, "ready")
    return process


def by_name(parameters: list[dict]) -> dict[str, dict]:
    return {entry["name"]: entry for entry in parameters}


def test_get_lists_every_parameter_with_its_type_hint(motor, view_server):
    run = run_node_client(view_server.url, {"parameters": {"get": []}})["runs"]
    run = next(iter(run.values()))
    assert "error" not in run, run
    assert {"parameters", "parametersSubscribe"} <= set(run["serverInfo"]["capabilities"])
    got = by_name(run["parameters"]["get"])
    assert got == {
        "motor.max_speed": {"name": "motor.max_speed", "value": 1, "type": "float64"},
        "motor.profile": {"name": "motor.profile", "value": "eco"},
        "motor.gains": {"name": "motor.gains", "value": [1, 0.5, 0], "type": "float64_array"},
        "motor.wheels": {"name": "motor.wheels", "value": 4},
        "motor.enabled": {"name": "motor.enabled", "value": True},
    }
    # The node's parameter service carries the view's own writes: no client calls it.
    assert not [name for name in run["parameters"]["services"] if name.startswith("_params.")]
    named = run_node_client(view_server.url, {"parameters": {
        "get": ["motor.profile", "motor.nothing", "nothing"]}})["runs"]
    assert next(iter(named.values()))["parameters"]["get"] == [
        {"name": "motor.profile", "value": "eco"}]


def test_set_answers_the_values_after_the_write_and_says_why_one_was_refused(motor,
                                                                             view_server):
    run = next(iter(run_node_client(view_server.url, {"parameters": {"set": [
        {"name": "motor.max_speed", "value": 1.5, "type": "float64"},
        {"name": "motor.gains", "value": [0.25, 0.5, 1], "type": "float64_array"},
        {"name": "motor.profile", "value": "track"},
        {"name": "motor.enabled", "value": False},
        {"name": "motor.max_speed", "value": 5},
    ]}})["runs"].values()))
    assert "error" not in run, run
    assert run["parameters"]["set"] == [
        {"name": "motor.max_speed", "value": 1.5, "type": "float64"},
        {"name": "motor.gains", "value": [0.25, 0.5, 1], "type": "float64_array"},
        {"name": "motor.profile", "value": "eco"},
        {"name": "motor.enabled", "value": False},
        {"name": "motor.max_speed", "value": 1.5, "type": "float64"},
    ]
    messages = [status["message"] for status in run["statuses"]]
    assert any("motor.profile" in message and "track mode needs the cage closed" in message
               for message in messages), messages
    assert any("motor.max_speed" in message and "above the maximum 2" in message
               for message in messages), messages
    assert all(status["level"] == 2 for status in run["statuses"])
    assert "track mode needs the cage closed" in view_server.process.errors.wait_for(
        "did not set parameter 'motor.profile'")
    # The store holds what the view set.
    again = next(iter(run_node_client(view_server.url, {"parameters": {
        "get": ["motor.max_speed", "motor.enabled"]}})["runs"].values()))
    assert again["parameters"]["get"] == [
        {"name": "motor.max_speed", "value": 1.5, "type": "float64"},
        {"name": "motor.enabled", "value": False}]


def test_unknown_and_read_only_parameters_are_refused_with_the_reason(motor, view_server):
    run = next(iter(run_node_client(view_server.url, {"parameters": {"set": [
        {"name": "motor.wheels", "value": 6},
        {"name": "motor.nothing", "value": 1},
        {"name": "motor.max_speed", "value": {"not": "a value"}},
    ]}})["runs"].values()))
    assert run["parameters"]["set"] == [{"name": "motor.wheels", "value": 4}]
    messages = " | ".join(status["message"] for status in run["statuses"])
    assert "read-only" in messages
    assert "no parameter 'motor.nothing'" in messages
    assert "a number, true/false, a string or a list" in messages


@pytest.fixture
def param_node(namespace, children, tmp_path):
    files = sorted(str(path) for path in (TEST_SCHEMAS / "test_msgs").iterdir()
                   if path.suffix in (".hmsg", ".hsrv"))
    files += [str(TEST_SCHEMAS / "other_pkg" / "stamp.hmsg"),
              str(TEST_SCHEMAS / "test_nodes" / "param_node.hnode")]
    subprocess.run([GENERATOR, "generate", "--lang", "python", "--out", str(tmp_path / "gen"),
                    "-I", str(TEST_SCHEMAS), *files], check=True, capture_output=True)
    environment = dict(os.environ)
    environment["PYTHONPATH"] = f"{tmp_path / 'gen' / 'python'}:{environment['PYTHONPATH']}"
    process = children.python(PARAM_NODE, environment)
    wait_line(process, "ready")
    return process


def test_a_generated_nodes_enum_f32_and_arrays_are_json_values(param_node, view_server):
    run = next(iter(run_node_client(view_server.url, {"parameters": {"get": [], "set": [
        {"name": "param_node.mode", "value": "Idle"},
        {"name": "param_node.mode", "value": "Sprint"},
        {"name": "param_node.gain", "value": 0.25, "type": "float64"},
        {"name": "param_node.mask", "value": [False, True]},
    ]}})["runs"].values()))
    assert "error" not in run, run
    got = by_name(run["parameters"]["get"])
    assert got["param_node.mode"] == {"name": "param_node.mode", "value": "Run"}
    assert got["param_node.gain"] == {"name": "param_node.gain", "value": 0.5, "type": "float64"}
    assert got["param_node.mask"] == {"name": "param_node.mask", "value": [True, False]}
    assert got["param_node.ticks"] == {"name": "param_node.ticks", "value": 0}
    assert got["param_node.offset"] == {"name": "param_node.offset", "value": 0}
    assert run["parameters"]["set"] == [
        {"name": "param_node.mode", "value": "Idle"},
        {"name": "param_node.mode", "value": "Idle"},
        {"name": "param_node.gain", "value": 0.25, "type": "float64"},
        {"name": "param_node.mask", "value": [False, True]},
    ]
    messages = " | ".join(status["message"] for status in run["statuses"])
    assert "'Sprint' is no enumerator of" in messages, messages


def test_a_subscriber_receives_the_change_horus_param_set_makes(motor, view_server):
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest"
    run = next(iter(run_node_client(view_server.url, {"parameters": {"watch": {
        "names": ["motor.max_speed", "motor.profile"],
        "command": [HORUS, "param", "set", "motor", "max_speed", "0.75"],
        "count": 1}}})["runs"].values()))
    assert "error" not in run, run
    assert run["parameters"]["command"] == 0
    assert run["parameters"]["updates"][0] == [
        {"name": "motor.max_speed", "value": 0.75, "type": "float64"}]


@pytest.fixture
def guarded_view(namespace, children, tmp_path):
    """A loopback view with a policy: alice may read and set motor's max_speed only, bob reads
    topics and has no `param` line."""
    tokens = tmp_path / "tokens"
    tokens.write_text("".join(f"{peer} {token}\n" for peer, token in TOKENS.items()))
    tokens.chmod(0o600)
    process = children.start([
        VIEW, "serve", "--namespace", namespace, "--listen", "127.0.0.1", "--port", "0",
        "--allow", "alice param motor.max_speed", "--allow", "bob read *",
        "--tokens", str(tokens)], dict(os.environ))
    line = wait_line(process, "ready ws://")
    return line.split(" ", 1)[1].strip()


def test_the_policy_param_verb_decides_what_a_peer_sees_and_sets(motor, guarded_view):
    plan = {"parameters": {"get": [], "set": [{"name": "motor.max_speed", "value": 0.5},
                                              {"name": "motor.profile", "value": "sport"}]}}
    bob = next(iter(run_node_client(f"{guarded_view}?token={TOKENS['bob']}",
                                    plan)["runs"].values()))
    assert "error" not in bob, bob
    assert (bob["parameters"]["get"], bob["parameters"]["set"]) == ([], [])
    assert any("not one peer 'bob' may set" in status["message"] for status in bob["statuses"])
    alice = next(iter(run_node_client(f"{guarded_view}?token={TOKENS['alice']}",
                                      plan)["runs"].values()))
    assert alice["parameters"]["get"] == [
        {"name": "motor.max_speed", "value": 1, "type": "float64"}]
    assert alice["parameters"]["set"] == [
        {"name": "motor.max_speed", "value": 0.5, "type": "float64"}]
    assert any("not one peer 'alice' may set" in status["message"]
               for status in alice["statuses"])
