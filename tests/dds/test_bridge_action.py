"""Actions across `horus bridge --export-action`: a HORUS action server (tests/process/
action_peer.cpp serving tests/schemas/test_actions' Navigate) reached by a ROS 2 action client,
dds_action_client.c, a plain Cyclone program built with idlc from ROS 2's action IDL (horus-gen's
navigate_action.idl, action_msgs and unique_identifier_msgs of bridges/dds/ros2_idl/) on ROS 2's
names: rq/Navigate/_action/send_goalRequest, ..., rt/Navigate/_action/feedback and status."""
from __future__ import annotations

import os
import pathlib
import subprocess

import pytest

from conftest import HERE, horus_gen
from processes import wait_line
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


@pytest.fixture(scope="session")
def dds_action_client(tmp_path_factory) -> str:
    """dds_action_client.c built with idlc's C of the action's IDL, as a Cyclone user would."""
    build = tmp_path_factory.mktemp("dds_action_client")
    horus_gen("generate", "--lang", "idl", "--out", str(build / "gen"), "-I",
              str(HERE.parent / "schemas"), str(NAVIGATE))
    generated = build / "gen" / "idl"
    idl = [(generated, generated / "horus_test" / "action" / "navigate_action.idl"),
           (HERE / "action_idl", HERE / "action_idl" / "ros2_action_calls.idl")]
    idl += [(ROS2_IDL, ROS2_IDL / name) for name in (
        "builtin_interfaces/msg/Time.idl", "unique_identifier_msgs/msg/UUID.idl",
        "action_msgs/msg/GoalInfo.idl", "action_msgs/msg/GoalStatus.idl",
        "action_msgs/msg/GoalStatusArray.idl", "action_msgs/srv/CancelGoal.idl")]
    sources = [str(HERE / "dds_action_client.c")]
    for root, path in idl:
        folder = build / path.parent.relative_to(root)
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run(["idlc", "-I", str(ROS2_IDL), "-I", str(generated), str(path)], cwd=folder,
                       check=True, capture_output=True)
        sources.append(str(folder / (path.stem + ".c")))
    program = build / "dds_action_client"
    subprocess.run(["cc", "-O1", "-Wall", "-DDDS_NDEBUG", "-I", str(build), "-o", str(program),
                    *sources, "-lddsc"], check=True, capture_output=True, text=True)
    return str(program)


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


def statuses(lines: list[str]) -> list[dict[str, int]]:
    return [{entry.split(":")[0]: int(entry.split(":")[1]) for entry in line.split()[1:]}
            for line in lines if line.startswith("status")]


def test_a_ros2_client_sends_a_goal_gets_feedback_status_and_the_result(
        dds_domain, worlds, children, navigate_python, dds_action_client):
    world, _ = worlds
    serve_and_export(children, world, navigate_python, dds_domain)
    lines = run_client(children, world, dds_action_client, dds_domain, "3", "4", "5", "40000")

    assert lines[0] == "accepted 1 1", lines
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

    assert lines[0] == "accepted 1 1", lines
    assert "cancel 0 1 01" in lines, lines
    status, reached, *_, sent = lines[-1].split()[1:]
    assert (lines[-1].split()[0], status, reached) == ("result", "5", "0"), lines
    assert 2 <= int(sent) < 100, lines
    assert any(array.get("01") == 5 for array in statuses(lines)), lines
