"""A robot's action used from a laptop's namespace across `horus remote`, under one `call` rule
naming the action (no `read` rule, no --import), Python and C++ at both ends: a goal sent on the
laptop gets its 20 feedbacks and its result, a goal canceled mid-way ends canceled, the robot's
server or link killed mid-goal ends the laptop's goal aborted within a second, a goal whose laptop
process exits (POD and serialized goals), or whose link ends, is canceled on the robot, and an
action the policy does not name is not carried."""
from __future__ import annotations

import concurrent.futures
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest
from conftest import GENERATOR, connect, free_port, serve
from processes import stderr_after_kill, wait_line

ACTIONS = pathlib.Path(__file__).resolve().parents[1] / "schemas" / "test_actions"
# tests/process/action_peer.cpp: Navigate served or sent from C++.
ACTION_PEER = os.environ.get("HORUS_ACTION_PEER", "")

# The robot's Navigate server (the contract's test server): `feedback_count` feedbacks each
# `period_us`, then succeeded; canceled when asked. Prints "executing" as a goal starts and
# "canceled REASON" as one ends canceled.
SERVER = """
import time, horus
from horus_test.action import Navigate
def execute(goal):
    wanted = goal.goal
    count = wanted.feedback_count
    for step in range(1, count + 1):
        if step == 1:
            print("executing", flush=True)
        if goal.cancel_requested:
            print("canceled", goal.cancel_reason, flush=True)
            goal.cancel()
            return None
        goal.publish_feedback(Navigate.Feedback(step=step, remaining_m=float(count - step)))
        time.sleep(wanted.period_us / 1e6)
    return Navigate.Result(reached=True, final_x=wanted.x, final_y=wanted.y, feedback_sent=count)
server = horus.ActionServer(Navigate, execute=execute)
print("ready", flush=True)
while True:
    time.sleep(1)
"""

# The laptop's client: one goal per line on stdin.
# "run": 20 feedbacks of 5 ms, then the result; "cancel": canceled after its 5th feedback;
# "long": a goal of 100 s, "executing" printed at its first feedback, then its end.
CLIENT = """
import sys, horus
from horus_test.action import Navigate
client = horus.ActionClient(Navigate)
print("server", client.wait_for_server(30), flush=True)
for line in sys.stdin:
    mode = line.strip()
    count, period = (20, 5000) if mode == "run" else (10000, 10000)
    handle = client.send_goal(Navigate.Goal(x=3.0, y=4.0, feedback_count=count,
                                            period_us=period), timeout=5)
    steps = []
    for feedback in handle.feedback(timeout=30):
        steps.append(feedback.step)
        if len(steps) == 1 and mode == "long":
            print("executing", flush=True)
        if len(steps) == 5 and mode == "cancel":
            print("cancel", handle.cancel(timeout=5).name, flush=True)
    outcome = handle.result(timeout=30)
    print(outcome.state.name, outcome.reason, outcome.result.feedback_sent,
          steps == list(range(1, len(steps) + 1)), len(steps), flush=True)
"""


@pytest.fixture(scope="module")
def actions(tmp_path_factory) -> pathlib.Path:
    """The Python of the test schema's actions (Navigate), generated once."""
    output = tmp_path_factory.mktemp("actions")
    subprocess.run([GENERATOR, "generate", "--lang", "python", "--out", str(output), "-I",
                    str(ACTIONS), str(ACTIONS / "navigate.haction")],
                   check=True, capture_output=True)
    return output / "python"


def line_within(process, expected: str, limit: float = 10.0) -> str:
    """wait_line, failing (the child killed) when no such line comes within `limit` seconds."""
    with concurrent.futures.ThreadPoolExecutor(1) as reader:
        line = reader.submit(wait_line, process, expected)
        try:
            return line.result(timeout=limit)
        except concurrent.futures.TimeoutError:
            raise AssertionError(f"no line {expected!r} within {limit} s: "
                                 f"{stderr_after_kill(process)!r}") from None


def env_with(world, actions) -> dict:
    env = world.env()
    env["PYTHONPATH"] = os.pathsep.join([str(actions), env.get("PYTHONPATH", "")])
    return env


def robot_and_laptop(children, worlds, certs, actions):
    """The robot's server and link, the laptop's link and a client waiting for goals."""
    robot, laptop = worlds
    robot_server = children.python(SERVER, env_with(robot, actions))
    wait_line(robot_server, "ready")
    link_server, port = serve(children, robot, certs, "laptop call Navigate", port=free_port())
    link = connect(children, laptop, certs, port)
    client = children.start([sys.executable, "-c", CLIENT],
                            env_with(laptop, actions), keep_stdin=True)
    assert wait_line(client, "server") == "server True"
    return robot_server, link_server, port, link, client


def ask(client, mode: str) -> None:
    client.stdin.write(mode + "\n")
    client.stdin.flush()


def test_goal_feedback_result_and_cancel_across_the_link(children, worlds, certs, actions):
    robot_server, _, _, link, client = robot_and_laptop(children, worlds, certs, actions)
    ask(client, "run")
    assert line_within(client, "") == "Succeeded  20 True 20"
    link.errors.wait_for("importing Navigate.feedback")

    ask(client, "cancel")
    assert line_within(client, "cancel") == "cancel Accepted"
    state, *_, in_order, steps = line_within(client, "").split()
    assert (state, in_order) == ("Canceled", "True") and int(steps) >= 5
    assert line_within(robot_server, "canceled").startswith("canceled")


def test_dead_robot_server_aborts_the_laptops_goal_at_once(children, worlds, certs, actions):
    robot_server, _, _, link, client = robot_and_laptop(children, worlds, certs, actions)
    ask(client, "long")
    assert line_within(client, "executing") == "executing"
    robot_server.send_signal(signal.SIGKILL)
    killed = time.monotonic()
    outcome = line_within(client, "")
    assert time.monotonic() - killed < 1.0, outcome
    assert outcome.startswith("Aborted the action server stopped"), outcome
    link.errors.wait_for("Navigate.send_goal no longer served here: on the robot its server")


def test_goals_of_an_exited_laptop_process_are_canceled(children, worlds, certs, actions):
    robot_server, _, _, _, client = robot_and_laptop(children, worlds, certs, actions)
    ask(client, "long")
    assert line_within(client, "executing") == "executing"
    client.send_signal(signal.SIGKILL)
    assert line_within(robot_server, "canceled").startswith("canceled canceled by a client")


def test_goals_of_a_lost_link_are_canceled(children, worlds, certs, actions):
    robot_server, _, _, link, client = robot_and_laptop(children, worlds, certs, actions)
    ask(client, "long")
    assert line_within(client, "executing") == "executing"
    link.send_signal(signal.SIGKILL)
    assert line_within(robot_server, "canceled").startswith("canceled canceled by a client")


def test_goals_of_a_lost_robot_link_end_on_both_sides(children, worlds, certs, actions):
    robot_server, link_server, _, _, client = robot_and_laptop(children, worlds, certs, actions)
    ask(client, "long")
    assert line_within(client, "executing") == "executing"
    link_server.send_signal(signal.SIGKILL)
    killed = time.monotonic()
    # The laptop withdraws its stand-in as the connection ends; the robot's server sees the
    # process that sent it the goal (the link's) exit.
    outcome = line_within(client, "")
    assert time.monotonic() - killed < 1.0, outcome
    assert outcome.startswith("Aborted the action server stopped"), outcome
    assert line_within(robot_server, "canceled").startswith("canceled the client (pid ")


def test_an_action_outside_the_policy_is_not_carried(children, worlds, certs, actions):
    robot, laptop = worlds
    wait_line(children.python(SERVER, env_with(robot, actions)), "ready")
    # A rule for another name, and one naming a part of the action only, carry nothing of it.
    _, port = serve(children, robot, certs, "laptop call Nav", "laptop read Navigate.status",
                    port=free_port())
    link = connect(children, laptop, certs, port)
    client = children.start([sys.executable, "-c", CLIENT.replace("30", "3", 1)],
                            env_with(laptop, actions), keep_stdin=True)
    assert line_within(client, "server") == "server False"
    assert "Navigate" not in link.errors.text()


def test_cpp_goals_across_the_link(children, worlds, certs):
    """The same with C++ at both ends (tests/process/action_peer.cpp)."""
    robot, laptop = worlds
    robot_server = children.start([ACTION_PEER, "serve"], robot.env())
    wait_line(robot_server, "ready")
    _, port = serve(children, robot, certs, "laptop call Navigate", port=free_port())
    link = connect(children, laptop, certs, port)
    link.errors.wait_for("serving Navigate.send_goal of the robot here")

    def send(*args: str) -> list[str]:
        client = children.start([ACTION_PEER, "send", "3", "4", *args], laptop.env())
        out, _ = client.communicate(timeout=30)
        return out.splitlines()

    lines = send("--count", "20")
    assert lines[0].startswith("accepted ") and lines[-1] == "succeeded "
    assert lines[1:-1] == [f"feedback {step}" for step in range(1, 21)]
    lines = send("--count", "1000", "--period-us", "10000", "--cancel-after", "5")
    assert lines[-1] == "canceled canceled by a client"

    client = children.start([ACTION_PEER, "send", "3", "4", "--count", "10000", "--period-us",
                             "10000"], laptop.env())
    assert line_within(client, "feedback") == "feedback 1"
    robot_server.send_signal(signal.SIGKILL)
    killed = time.monotonic()
    assert line_within(client, "aborted") == "aborted the action server stopped"
    assert time.monotonic() - killed < 1.0


# A serialized action: Echo's goal (a String) is MessagePack on the wire, its id too.
ECHO_SERVER = """
import time, horus
from horus_test.action import Echo
def execute(goal):
    for count in range(goal.goal.repeat):
        if goal.cancel_requested:
            print("canceled", goal.cancel_reason, flush=True)
            goal.cancel()
            return None
        goal.publish_feedback(Echo.Feedback(partial=[goal.goal.text] * count))
        time.sleep(0.01)
    return Echo.Result(text=goal.goal.text * goal.goal.repeat)
server = horus.ActionServer(Echo, execute=execute)
print("ready", flush=True)
while True:
    time.sleep(1)
"""

ECHO_CLIENT = """
import horus
from horus_test.action import Echo
client = horus.ActionClient(Echo)
print("server", client.wait_for_server(30), flush=True)
handle = client.send_goal(Echo.Goal(text="ab", repeat=10000), timeout=5)
next(iter(handle.feedback(timeout=30)))
print("executing", flush=True)
handle.result(timeout=60)
"""


def test_serialized_goals_of_an_exited_laptop_process_are_canceled(children, worlds, certs,
                                                                   actions):
    robot, laptop = worlds
    robot_server = children.python(ECHO_SERVER, env_with(robot, actions))
    wait_line(robot_server, "ready")
    _, port = serve(children, robot, certs, "laptop call Echo", port=free_port())
    connect(children, laptop, certs, port)
    client = children.python(ECHO_CLIENT, env_with(laptop, actions))
    assert line_within(client, "server") == "server True"
    assert line_within(client, "executing") == "executing"
    client.send_signal(signal.SIGKILL)
    assert line_within(robot_server, "canceled").startswith("canceled canceled by a client")
