"""Actions across languages and processes: Python clients of the C++ server (tests/process/
action_peer.cpp), C++ clients of a Python server, each policy with a client of each language,
and the liveness rows: a server SIGKILLed mid-goal is seen as Aborted within 1 s, a client
SIGKILLed mid-goal has its goal canceled and the next client is served."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

import horus

from .test_runtime_action import action_env, generated_actions

BUILD = os.environ.get("HORUS_BUILD_DIR", "")
ACTION_PEER = os.path.join(BUILD, "tests", "process", "action_peer")

# A Python server of Navigate, the contract's test server, in a process of its own: prints
# `ready`, then `canceled <reason>` for each goal that ends canceled; stops on SIGTERM.
PYTHON_SERVER = textwrap.dedent("""
    import math, signal, sys, threading, time
    import horus
    from horus_test.action import Navigate

    def execute(goal):
        g = goal.goal
        distance = math.hypot(g.x, g.y)
        for step in range(1, g.feedback_count + 1):
            time.sleep(g.period_us / 1e6)
            if goal.cancel_requested:
                print("canceled", goal.cancel_reason, flush=True)
                goal.cancel(Navigate.Result(feedback_sent=step - 1))
                return None
            goal.publish_feedback(Navigate.Feedback(
                step=step, remaining_m=distance * (g.feedback_count - step) / g.feedback_count))
        if g.abort_with:
            goal.abort(g.abort_with)
            return None
        return Navigate.Result(reached=True, final_x=g.x, final_y=g.y,
                               feedback_sent=g.feedback_count)

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with horus.ActionServer(Navigate, execute, policy=sys.argv[1]):
        print("ready", flush=True)
        while not stop.wait(0.05):
            pass
""")

# A Python client in a process of its own: sends one long goal, prints `accepted <id>` and
# `feedback <step>`, and waits (to be SIGKILLed).
PYTHON_CLIENT = textwrap.dedent("""
    import time
    import horus
    from horus_test.action import Navigate

    client = horus.ActionClient(Navigate)
    handle = client.send_goal(Navigate.Goal(x=1.0, feedback_count=1000, period_us=5000))
    print("accepted", handle.goal_id, flush=True)
    for feedback in handle.feedback():
        print("feedback", feedback.step, flush=True)
""")


@pytest.fixture
def actions(tmp_path_factory):
    generated_actions(tmp_path_factory)
    import horus_test.action
    return horus_test.action


@pytest.fixture
def processes(tmp_path_factory):
    """Starts action_peer (`cpp`) or a Python script (`python`) with the generated actions
    importable; kills what is left at the end."""
    assert os.access(ACTION_PEER, os.X_OK), \
        f"{ACTION_PEER} is missing: build the target action_peer (run this suite through ctest)"
    python_dir = generated_actions(tmp_path_factory)
    started = []

    def start(kind: str, *args: str) -> subprocess.Popen:
        command = [ACTION_PEER, *args] if kind == "cpp" else [sys.executable, "-c", *args]
        child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True, env=action_env(python_dir))
        started.append(child)
        return child
    yield start
    for child in started:
        if child.poll() is None:
            child.kill()
        child.communicate()


def serve(processes, language: str, policy: str = "reject") -> subprocess.Popen:
    server = processes("cpp", "serve", "--policy", policy) if language == "cpp" else \
        processes("python", PYTHON_SERVER, policy)
    line = server.stdout.readline().strip()
    assert line == "ready", (line, server.stderr.read() if server.poll() is not None else "")
    return server


def lines_of(process: subprocess.Popen, timeout: float = 10.0) -> list[str]:
    out, err = process.communicate(timeout=timeout)
    return out.splitlines() + ([f"stderr: {err.strip()}"] if err.strip() else [])


def test_python_client_of_the_cpp_server(processes, actions):
    Navigate = actions.Navigate
    serve(processes, "cpp")
    with horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal(x=3.0, y=4.0))
        feedback = list(handle.feedback(timeout=2.0))
        result = handle.result(timeout=2.0)
        assert [fb.step for fb in feedback] == list(range(1, 21))
        assert feedback[0].remaining_m == pytest.approx(5.0 * 19 / 20)
        assert result.succeeded and result.result.final_y == 4.0
        assert result.result.feedback_sent == 20

        handle = client.send_goal(Navigate.Goal(x=1.0, feedback_count=400))
        assert handle.next_feedback(timeout=2.0) is not None
        assert handle.cancel() == horus.CancelCode.Accepted
        assert (handle.result(2.0).state, handle.reason) == (horus.GoalState.Canceled,
                                                             "canceled by a client")

        aborted = client.send_goal(Navigate.Goal(abort_with="no path")).result(2.0)
        assert (aborted.state, aborted.reason) == (horus.GoalState.Aborted, "no path")


def test_cpp_client_of_the_python_server(processes):
    serve(processes, "python")
    sent = lines_of(processes("cpp", "send", "3", "4"))
    assert sent[0].startswith("accepted ") and len(sent[0].split()[1]) == 32
    assert sent[1:-1] == [f"feedback {step}" for step in range(1, 21)]
    assert sent[-1] == "succeeded "

    canceled = lines_of(processes("cpp", "send", "1", "0", "--count", "400", "--cancel-after",
                                  "3"))
    assert canceled[-1] == "canceled canceled by a client"
    aborted = lines_of(processes("cpp", "send", "1", "0", "--abort-with", "no path"))
    assert aborted[-1] == "aborted no path"


@pytest.mark.parametrize("server_language", ["cpp", "python"])
def test_each_policy_with_a_client_of_each_language(processes, actions, server_language):
    Navigate = actions.Navigate
    for policy in ("reject", "preempt", "queue"):
        server = serve(processes, server_language, policy)
        with horus.ActionClient(Navigate) as client:
            running = client.send_goal(Navigate.Goal(x=1.0, feedback_count=40, period_us=5000))
            assert running.next_feedback(timeout=2.0) is not None
            other = lines_of(processes("cpp", "send", "2", "0", "--count", "2"))
            if policy == "reject":
                assert other[-1] == f"rejected busy: goal {running.goal_id} is executing"
                assert running.result(2.0).succeeded
            elif policy == "preempt":
                assert other[-1] == "succeeded "
                result = running.result(2.0)
                assert result.state == horus.GoalState.Canceled
                assert result.reason == f"preempted by goal {other[0].split()[1]}"
            else:
                assert running.result(2.0).succeeded and other[-1] == "succeeded "
        server.send_signal(signal.SIGTERM)
        assert server.wait(5) == 0


@pytest.mark.parametrize("server_language", ["cpp", "python"])
def test_sigkilled_server_is_seen_as_aborted_within_a_second(processes, actions,
                                                             server_language):
    Navigate = actions.Navigate
    server = serve(processes, server_language)
    with horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal(x=1.0, feedback_count=1000))
        assert handle.next_feedback(timeout=2.0) is not None
        killed = time.monotonic()
        server.kill()
        result = handle.result(timeout=1.0)
        assert time.monotonic() - killed < 1.0
        assert (result.state, result.reason) == (
            horus.GoalState.Aborted, f"the action server (pid {server.pid}) exited mid-goal")
    # And a C++ client of a killed Python server.
    if server_language == "python":
        server = serve(processes, "python")
        client = processes("cpp", "send", "1", "0", "--count", "1000")
        assert client.stdout.readline().startswith("accepted ")
        assert client.stdout.readline().startswith("feedback ")
        server.kill()
        assert lines_of(client, 2.0)[-1] == \
            f"aborted the action server (pid {server.pid}) exited mid-goal"


@pytest.mark.parametrize("languages", [("python", "cpp"), ("cpp", "python")])
def test_sigkilled_client_has_its_goal_canceled_and_the_next_is_served(processes, actions,
                                                                       languages):
    Navigate = actions.Navigate
    server_language, client_language = languages
    server = serve(processes, server_language)
    if client_language == "cpp":
        doomed = processes("cpp", "send", "1", "0", "--count", "1000")
    else:
        doomed = processes("python", PYTHON_CLIENT)
    assert doomed.stdout.readline().startswith("accepted ")
    assert doomed.stdout.readline().startswith("feedback ")
    with horus.ActionClient(Navigate) as watcher:
        statuses = horus.Topic(Navigate.Status, Navigate.status_topic)
        doomed.kill()
        doomed.wait()
        reason = f"the client (pid {doomed.pid}) exited"
        deadline = time.monotonic() + 2.0
        seen = []
        while time.monotonic() < deadline and not any(
                s.state == horus.GoalState.Canceled for s in seen):
            status = statuses.recv(0.05)
            if status is not None:
                seen.append(status)
        assert any(s.state == horus.GoalState.Canceled and s.reason == reason for s in seen), seen
        if server_language == "python":
            assert server.stdout.readline().strip() == f"canceled {reason}"
        assert watcher.send_goal(Navigate.Goal(x=1.0, feedback_count=2)).result(2.0).succeeded
