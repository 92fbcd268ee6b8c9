"""Actions across `horus bridge --export-action`: a HORUS action server (tests/process/
action_peer.cpp serving tests/schemas/test_actions' Navigate) reached by a ROS 2 action client,
dds_action_client.c, a plain Cyclone program built with idlc from ROS 2's action IDL (horus-gen's
navigate_action.idl, action_msgs and unique_identifier_msgs of bridges/dds/ros2_idl/) on ROS 2's
names: rq/Navigate/_action/send_goalRequest, ..., rt/Navigate/_action/feedback and status. And
across `horus bridge --import-action`: a HORUS Python action client reaching a ROS 2 action
server, dds_action_server.c, built the same way."""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

from conftest import HERE, horus_gen
from processes import Output, wait_line
from test_bridge import DEPTH, HORUS

ACTION_PEER = os.environ.get("HORUS_ACTION_PEER", "")  # tests/process/action_peer.cpp
ROS2_IDL = HERE.parent.parent / "bridges" / "dds" / "ros2_idl"
NAVIGATE = HERE.parent / "schemas" / "test_actions" / "navigate.haction"


@pytest.fixture(scope="session")
def navigate_python(tmp_path_factory) -> pathlib.Path:
    """Navigate's generated Python: how `horus bridge` learns the types of the action's services
    before any local call made their topics (docs/dds-bridge.md, "Services")."""
    output = tmp_path_factory.mktemp("navigate_python")
    horus_gen("generate", "--lang", "python", "--out", str(output), "-I",
              str(HERE.parent / "schemas"), str(NAVIGATE))
    return output / "python"


def ros2_action_program(tmp_path_factory, name: str) -> str:
    """tests/dds/NAME.c built with idlc's C of the action's IDL, as a Cyclone user would."""
    build = tmp_path_factory.mktemp(name)
    horus_gen("generate", "--lang", "idl", "--out", str(build / "gen"), "-I",
              str(HERE.parent / "schemas"), str(NAVIGATE))
    generated = build / "gen" / "idl"
    idl = [(generated, generated / "horus_test" / "action" / "navigate_action.idl"),
           (HERE / "action_idl", HERE / "action_idl" / "ros2_action_calls.idl")]
    idl += [(ROS2_IDL, ROS2_IDL / part) for part in (
        "builtin_interfaces/msg/Time.idl", "unique_identifier_msgs/msg/UUID.idl",
        "action_msgs/msg/GoalInfo.idl", "action_msgs/msg/GoalStatus.idl",
        "action_msgs/msg/GoalStatusArray.idl", "action_msgs/srv/CancelGoal.idl")]
    sources = [str(HERE / f"{name}.c")]
    for root, path in idl:
        folder = build / path.parent.relative_to(root)
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run(["idlc", "-I", str(ROS2_IDL), "-I", str(generated), str(path)], cwd=folder,
                       check=True, capture_output=True)
        sources.append(str(folder / (path.stem + ".c")))
    program = build / name
    subprocess.run(["cc", "-O1", "-Wall", "-DDDS_NDEBUG", "-I", str(build), "-o", str(program),
                    *sources, "-lddsc", "-lm"], check=True, capture_output=True, text=True)
    return str(program)


@pytest.fixture(scope="session")
def dds_action_client(tmp_path_factory) -> str:
    return ros2_action_program(tmp_path_factory, "dds_action_client")


@pytest.fixture(scope="session")
def dds_action_server(tmp_path_factory) -> str:
    return ros2_action_program(tmp_path_factory, "dds_action_server")


def run_client(children, world, client: str, domain: int, *args: str) -> list[str]:
    process = children.start([client, str(domain), *args], world.env())
    out, errors = process.communicate(timeout=60)
    assert process.returncode == 0, (out, errors)
    return out.splitlines()


def serve_and_export(children, world, navigate_python, domain: int) -> None:
    server = children.start([ACTION_PEER, "serve"], world.env())
    wait_line(server, "ready")
    path = os.pathsep.join([str(navigate_python), os.environ.get("PYTHONPATH", "")])
    exporter = children.start([HORUS, "bridge", "--domain", str(domain), "--depth", DEPTH,
                               "--export-action", "Nav*"], world.env(PYTHONPATH=path))
    wait_line(exporter, "exporting action 'Navigate' as rq/Navigate/_action/")


def answers(lines: list[str]) -> list[str]:
    """The lines of dds_action_client other than its status arrays, one of which may come before
    send_goal's answer (the bridge publishes the array as soon as it learns of a goal)."""
    return [line for line in lines if not line.startswith("status")]


def statuses(lines: list[str]) -> list[dict[str, int]]:
    return [{entry.split(":")[0]: int(entry.split(":")[1]) for entry in line.split()[1:]}
            for line in lines if line.startswith("status")]


def test_a_ros2_client_sends_a_goal_gets_feedback_status_and_the_result(
        dds_domain, worlds, children, navigate_python, dds_action_client):
    world, _ = worlds
    serve_and_export(children, world, navigate_python, dds_domain)
    lines = run_client(children, world, dds_action_client, dds_domain, "3", "4", "5", "40000")

    assert answers(lines)[0] == "accepted 1 1", lines
    feedback = [line for line in lines if line.startswith("feedback")]
    assert feedback == [f"feedback {step} {5.0 * (5 - step) / 5:.6f}" for step in range(1, 6)]
    assert "second accepted 0" in lines  # the Reject policy: goal 01 is executing
    assert lines[-1] == "result 4 1 3.000000 4.000000 5", lines
    seen = statuses(lines)
    assert all("b0" not in array for array in seen), seen  # a rejected goal is never a status
    assert any(array.get("01") == 2 for array in seen), seen  # executing
    assert any(array.get("01") == 4 for array in seen), seen  # succeeded


def test_a_ros2_client_cancels_a_goal_mid_way(dds_domain, worlds, children, navigate_python,
                                              dds_action_client):
    world, _ = worlds
    serve_and_export(children, world, navigate_python, dds_domain)
    lines = run_client(children, world, dds_action_client, dds_domain, "3", "4", "100", "20000",
                       "2")

    assert answers(lines)[0] == "accepted 1 1", lines
    assert "cancel 0 1 01" in lines, lines
    status, reached, *_, sent = lines[-1].split()[1:]
    assert (lines[-1].split()[0], status, reached) == ("result", "5", "0"), lines
    assert 2 <= int(sent) < 100, lines
    assert any(array.get("01") == 5 for array in statuses(lines)), lines


# A HORUS Python action client of Navigate. goal: 5 feedbacks of (3, 4); reject: a goal the
# server refuses; abort: one it aborts after its feedbacks; cancel: 100 feedbacks, canceled after
# the second; no-server: one goal at once.
# Lines: whether the bridge registered the services with the generated fingerprints, the state
# after send_goal, each feedback, the states the client was told, the outcome.
ACTION_CLIENT = """
import sys, time, horus
from horus_test.action import Navigate, NavigateGoal
mode = sys.argv[1]
client = horus.ActionClient(Navigate)
if mode == "no-server":
    start = time.monotonic()
    try:
        client.send_goal(NavigateGoal(x=3.0, y=4.0), timeout=5)
    except horus.NoServerError:
        print("refused", time.monotonic() - start < 1.0, flush=True)
    sys.exit(0)
print("server", client.wait_for_server(30), flush=True)
registered = {s["name"]: s["fingerprint"] for s in horus._core.list_services()}
print("fingerprints", all(registered.get(s.name) == s.fingerprint
                          for s in (Navigate.SendGoal, Navigate.CancelGoal, Navigate.GetResult)))
states = []
count, period = (100, 20000) if mode == "cancel" else (5, 40000)
goal = NavigateGoal(x=3.0, y=4.0, feedback_count=count, period_us=period,
                    abort_with=mode if mode in ("reject", "abort") else "")
handle = client.send_goal(goal, timeout=5, on_state=lambda state, reason: states.append(state))
print("sent", handle.state.name, handle.reason, flush=True)
if mode == "cancel":
    for _ in range(2):
        step = handle.next_feedback(20)
        print("feedback", step.step, f"{step.remaining_m:.6f}", flush=True)
    print("cancel", handle.cancel(5).name, flush=True)
else:
    for step in handle.feedback(20):
        print("feedback", step.step, f"{step.remaining_m:.6f}", flush=True)
outcome = handle.result(20)
time.sleep(0.1)  # the last state's callback
print("states", *[state.name for state in states])
result = outcome.result
print("result", outcome.state.name, result.reached, result.final_x, result.final_y,
      result.feedback_sent, outcome.reason, flush=True)
client.close()
"""


def import_from(children, world, navigate_python, domain: int, *patterns: str):
    """`horus bridge --import-action` (and `patterns`), with the action's generated Python."""
    path = os.pathsep.join([str(navigate_python), os.environ.get("PYTHONPATH", "")])
    return children.start([HORUS, "bridge", "--domain", str(domain), "--depth", DEPTH,
                           "--import-action", "Nav*", *patterns], world.env(PYTHONPATH=path))


def run_action_client(children, world, navigate_python, mode: str) -> list[str]:
    path = os.pathsep.join([str(navigate_python), os.environ.get("PYTHONPATH", "")])
    process = children.start([sys.executable, "-c", ACTION_CLIENT, mode],
                             world.env(PYTHONPATH=path))
    out, errors = process.communicate(timeout=90)
    assert process.returncode == 0, (out, errors)
    return out.splitlines()


@pytest.fixture
def ros2_server(dds_domain, worlds, children, navigate_python, dds_action_server):
    """dds_action_server on the test's domain, imported into namespace A."""
    world, _ = worlds
    server = children.start([dds_action_server, str(dds_domain)], world.env())
    wait_line(server, "ready")
    bridge = import_from(children, world, navigate_python, dds_domain)
    wait_line(bridge, "importing action 'Navigate' from rr/Navigate/_action/")
    return server


def test_a_horus_client_sends_a_goal_to_a_ros2_server(worlds, children, navigate_python,
                                                       ros2_server):
    lines = run_action_client(children, worlds[0], navigate_python, "goal")

    # The Executing status may come before send_goal's answer (the handle then skips Accepted).
    assert lines[:2] == ["server True", "fingerprints True"], lines
    assert lines[2] in ("sent Accepted ", "sent Executing "), lines
    assert [line for line in lines if line.startswith("feedback")] == [
        f"feedback {step} {5.0 * (5 - step) / 5:.6f}" for step in range(1, 6)]
    assert lines[-2] in ("states Accepted Executing Succeeded", "states Executing Succeeded"), lines
    assert lines[-1] == "result Succeeded True 3.0 4.0 5 ", lines


def test_a_goal_the_ros2_server_rejects_is_rejected(worlds, children, navigate_python,
                                                   ros2_server):
    lines = run_action_client(children, worlds[0], navigate_python, "reject")

    reason = "rejected by the ROS 2 action server (ROS 2 gives no reason)"
    assert lines[2] == f"sent Rejected {reason}", lines
    assert not [line for line in lines if line.startswith("feedback")], lines
    assert lines[-2:] == ["states Rejected", f"result Rejected False 0.0 0.0 0 {reason}"], lines
    assert wait_line(ros2_server, "goal ").endswith(" rejected")


def test_a_goal_the_ros2_server_aborts_ends_aborted_with_its_result(worlds, children,
                                                                    navigate_python, ros2_server):
    lines = run_action_client(children, worlds[0], navigate_python, "abort")

    assert len([line for line in lines if line.startswith("feedback")]) == 5, lines
    assert lines[-1] == ("result Aborted False 0.0 0.0 5 aborted by the ROS 2 action server "
                         "(ROS 2 gives no reason)"), lines


def test_a_horus_client_cancels_a_goal_of_a_ros2_server(worlds, children, navigate_python,
                                                       ros2_server):
    lines = run_action_client(children, worlds[0], navigate_python, "cancel")

    assert lines[2] in ("sent Accepted ", "sent Executing "), lines
    assert lines[3:6] == ["feedback 1 4.950000", "feedback 2 4.900000", "cancel Accepted"], lines
    assert "Executing" in lines[-2].split() and lines[-2].endswith(" Canceled"), lines
    state, reached, _, _, sent, *reason = lines[-1].split()[1:]
    assert (state, reached, " ".join(reason)) == (
        "Canceled", "False", "canceled on the ROS 2 action server"), lines
    assert 2 <= int(sent) < 100, lines


def test_a_goal_with_no_ros2_server_is_refused_at_once(dds_domain, worlds, children,
                                                      navigate_python):
    world, _ = worlds
    bridge = import_from(children, world, navigate_python, dds_domain)
    wait_line(bridge, "bridge on DDS domain")

    assert run_action_client(children, world, navigate_python, "no-server") == ["refused True"]


def test_an_action_both_exported_and_imported_is_refused(dds_domain, worlds, children,
                                                         navigate_python, ros2_server):
    world, _ = worlds
    bridge = import_from(children, world, navigate_python, dds_domain, "--export-action",
                         "Navigate")
    Output(bridge.stderr).wait_for("horus bridge: refusing action 'Navigate': it matches both "
                                   "--export-action and --import-action")


def test_horus_action_send_reaches_a_ros2_server(worlds, children, ros2_server):
    """The command checks each service's fingerprint against its payload types, and learns
    every type from the namespace: the import registered and opened them as a server would."""
    process = children.start([HORUS, "action", "send", "Navigate",
                              "{x: 3.0, y: 4.0, feedback_count: 3, period_us: 1000}"],
                             worlds[0].env())
    out, errors = process.communicate(timeout=60)

    assert process.returncode == 0, (out, errors)
    assert out.splitlines()[-1] == ("succeeded: {reached: true, final_x: 3.0, final_y: 4.0, "
                                    "feedback_sent: 3}"), out
