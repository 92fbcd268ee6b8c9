"""`horus action list|info|send` against the C++ server of the test action Navigate
(tests/process/action_peer.cpp): the command learns every type from the live segments."""
from __future__ import annotations

import json
import os
import pathlib
import re
import signal
import subprocess

import pytest
from conftest import HORUS, run_horus, wait_ready

ACTION_PEER = os.path.join(os.environ.get("HORUS_BUILD_DIR", ""), "tests", "process",
                           "action_peer")
SCHEMAS = pathlib.Path(__file__).resolve().parents[1] / "schemas" / "test_actions"


@pytest.fixture
def server(children):
    """The C++ Navigate server (policy reject), ready."""
    assert os.access(ACTION_PEER, os.X_OK), f"{ACTION_PEER} is missing: build action_peer"
    process = children.start([ACTION_PEER, "serve"])
    wait_ready(process)
    return process


def test_list_shows_the_action_its_type_and_server(server):
    listed = run_horus("action", "list")
    assert listed.returncode == 0, listed.stderr
    header, row = listed.stdout.splitlines()
    assert header.split() == ["ACTION", "TYPE", "SERVER", "LAST_STATUS"]
    assert row.split() == ["Navigate", "horus_test.action.Navigate", str(server.pid), "-"]
    assert run_horus("action", "send", "Navigate", "{feedback_count: 1}").returncode == 0
    (entry,) = json.loads(run_horus("action", "list", "--json").stdout)
    assert (entry["name"], entry["type"], entry["server_pid"]) == \
        ("Navigate", "horus_test.action.Navigate", server.pid)
    assert re.fullmatch(r"succeeded [0-9a-f]{32}", entry["last_status"]), entry


def test_info_names_the_services_topics_and_the_actions_fingerprint(server):
    described = subprocess.run([os.environ["HORUS_GEN_PROGRAM"], "describe", "--json",
                                str(SCHEMAS / "navigate.haction")], capture_output=True,
                               text=True, check=True)
    (described_action,) = [t for t in json.loads(described.stdout)["types"]
                           if t["kind"] == "action" and t["name"] == "horus_test.action.Navigate"]
    info = run_horus("action", "info", "Navigate")
    assert info.returncode == 0, info.stderr
    lines = info.stdout.splitlines()
    assert lines[:2] == ["action: Navigate", "type: horus_test.action.Navigate"]
    assert lines[2] == f"fingerprint: {int(described_action['fingerprint'], 16):016x}"
    assert lines[3] == f"server: pid {server.pid}"
    assert ("  Navigate.send_goal: horus_test.action.NavigateSendGoalRequest -> "
            "horus_test.action.NavigateSendGoalResponse") in lines
    assert "  Navigate.feedback: horus_test.action.NavigateFeedbackMessage" in lines
    assert "    remaining_m: f64," in lines
    as_json = json.loads(run_horus("action", "info", "Navigate", "--json").stdout)
    assert as_json["topics"]["status"]["type"] == "horus_test.action.NavigateStatus"
    missing = run_horus("action", "info", "Navigat")
    assert missing.returncode == 1 and "no action 'Navigat'" in missing.stderr
    assert "did you mean 'Navigate'" in missing.stderr


def test_send_prints_feedback_and_the_result(server):
    sent = run_horus("action", "send", "Navigate", "{x: 3.0, y: 4.0}")
    assert sent.returncode == 0, sent.stderr
    lines = sent.stdout.splitlines()
    assert re.fullmatch(r"goal [0-9a-f]{32} accepted", lines[0])
    assert lines[1] == "executing"
    feedback = [line for line in lines if line.startswith("feedback: ")]
    assert len(feedback) == 20  # the goal's default feedback_count
    assert feedback[0] == "feedback: {step: 1, remaining_m: 4.75}"
    assert lines[-1] == "succeeded: {reached: true, final_x: 3.0, final_y: 4.0, feedback_sent: 20}"

    quiet = run_horus("action", "send", "Navigate", "{feedback_count: 3}", "--no-feedback",
                      "--json")
    events = [json.loads(line) for line in quiet.stdout.splitlines()]
    assert [e["event"] for e in events] == ["accepted", "state", "result"]
    assert events[-1]["result"]["feedback_sent"] == 3 and events[-1]["state"] == "succeeded"


def test_send_exits_1_with_the_reason_when_the_goal_fails(server, children):
    aborted = run_horus("action", "send", "Navigate", "{abort_with: blocked}")
    assert aborted.returncode == 1
    assert aborted.stdout.splitlines()[-1] == "aborted"
    assert re.search(r"goal [0-9a-f]{32} aborted: blocked", aborted.stderr)

    running = children.start([HORUS, "action", "send", "Navigate", "{feedback_count: 400}"])
    assert running.stdout.readline().endswith("accepted\n")
    rejected = run_horus("action", "send", "Navigate", "{}")
    assert rejected.returncode == 1
    assert re.search(r"rejected: busy: goal [0-9a-f]{32} is executing", rejected.stderr)
    running.kill()


def test_ctrl_c_cancels_the_goal(server, children):
    sending = children.start([HORUS, "action", "send", "Navigate",
                              "{feedback_count: 1000, period_us: 5000}"])
    assert sending.stdout.readline().endswith("accepted\n")
    assert sending.stdout.readline() == "executing\n"
    assert sending.stdout.readline().startswith("feedback: ")
    sending.send_signal(signal.SIGINT)
    out, err = sending.communicate(timeout=5)
    assert sending.returncode == 1, err
    assert out.splitlines()[-1] == "canceled"
    assert re.search(r"goal [0-9a-f]{32} canceled: canceled by a client", err)
    # The server ended the goal and serves the next.
    assert run_horus("action", "send", "Navigate", "{feedback_count: 2}").returncode == 0


def test_result_timeout_cancels_the_goal(server):
    late = run_horus("action", "send", "Navigate", "{feedback_count: 1000}", "--result-timeout",
                     "0.2", "--no-feedback")
    assert late.returncode == 1
    assert "did not end within 0.2 s: canceled" in late.stderr
    assert run_horus("action", "send", "Navigate", "{feedback_count: 2}").returncode == 0


def test_usage_and_missing_server(server):
    bad = run_horus("action", "send", "Navigate", "{x: [")
    assert bad.returncode == 2 and "cannot parse the goal" in bad.stderr
    wrong = run_horus("action", "send", "Navigate", "{speed: 1}")
    assert wrong.returncode == 1 and "speed" in wrong.stderr
    server.send_signal(signal.SIGTERM)
    assert server.wait(5) == 0
    gone = run_horus("action", "send", "Navigate", "{}")
    assert gone.returncode == 1 and "action 'Navigate' has no live server" in gone.stderr
