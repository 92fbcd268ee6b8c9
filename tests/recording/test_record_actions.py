"""An action's run in a recording: an action is three services and three topics, so `horus record
-a` holds the goal (send_goal's request), each feedback, each status and the result as it holds
any service and topic, and the Foxglove export decodes them."""
from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys

import pytest

import horus

from processes import wait_until
from test_record import export_validated, run_horus

ACTIONS = pathlib.Path(__file__).resolve().parents[1] / "schemas" / "test_actions"


@pytest.fixture
def navigate(tmp_path):
    """The test schema's Navigate action, generated for Python."""
    generator = os.environ.get("HORUS_GEN_PROGRAM", "")
    assert generator, "HORUS_GEN_PROGRAM: run through ctest (pytest_record)"
    subprocess.run([generator, "generate", "--lang", "python", "--out", str(tmp_path / "gen"),
                    "-I", str(ACTIONS), str(ACTIONS / "navigate.haction")],
                   check=True, capture_output=True)
    folder = str(tmp_path / "gen" / "python")
    sys.path.insert(0, folder)
    try:
        from horus_test.action import Navigate
    finally:
        sys.path.remove(folder)
    return Navigate


def subscribed(topic: str) -> bool:
    return any(t["name"] == topic and t["subscribers"] for t in horus._core.list_topics(""))


def test_a_recorded_action_run_holds_goal_feedback_status_and_result(tmp_path, navigate):
    Navigate = navigate

    def execute(goal):
        count = goal.goal.feedback_count
        for step in range(1, count + 1):
            goal.publish_feedback(Navigate.Feedback(step=step, remaining_m=float(count - step)))
        return Navigate.Result(reached=True, final_x=goal.goal.x, final_y=goal.goal.y,
                               feedback_sent=count)

    out = tmp_path / "action.mcap"
    recorder = subprocess.Popen([os.environ["HORUS_CLI"], "record", "-a", "-o", str(out)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with horus.ActionServer(Navigate, execute=execute), horus.ActionClient(Navigate) as client:
        parts = ("Navigate.send_goal.request", "Navigate.feedback", "Navigate.status",
                 "Navigate.result")
        for topic in parts:
            wait_until(lambda: subscribed(topic), f"horus-record to subscribe to {topic}", limit=30)
        handle = client.send_goal(Navigate.Goal(x=3.0, y=4.0, feedback_count=20), timeout=5)
        outcome = handle.result(timeout=10)
        assert outcome.state == horus.GoalState.Succeeded
        wait_until(lambda: sum(t["message_count"] for t in horus._core.list_topics("")
                               if t["name"] == "Navigate.status") >= 3, "the goal's statuses")
    recorder.send_signal(signal.SIGINT)
    _, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr

    described = json.loads(run_horus("record", "info", str(out), "--json").stdout)
    counts = {t["topic"]: t["messages"] for t in described["topics"]}
    assert counts["Navigate.feedback"] == 20
    assert counts["Navigate.result"] == 1 and counts["Navigate.status"] >= 3

    exported = {}
    for topic, _, value in export_validated(out, tmp_path / "action_foxglove.mcap"):
        exported.setdefault(topic, []).append(value)
    # The stopping servers' wake-ups (every field zero) beside the one goal.
    goals = [r["payload"] for r in exported["Navigate.send_goal.request"]
             if any(r["payload"]["goal_id"])]
    assert len(goals) == 1
    goal = goals[0]
    assert (goal["goal"]["x"], goal["goal"]["y"], goal["goal"]["feedback_count"]) == (3.0, 4.0, 20)
    goal_id = goal["goal_id"]
    assert [f["feedback"]["step"] for f in exported["Navigate.feedback"]] == list(range(1, 21))
    assert all(f["goal_id"] == goal_id for f in exported["Navigate.feedback"])
    states = [s["state"] for s in exported["Navigate.status"] if s["goal_id"] == goal_id]
    assert states[0] == int(horus.GoalState.Accepted)
    assert states[-1] == int(horus.GoalState.Succeeded)
    assert int(horus.GoalState.Executing) in states
    result = exported["Navigate.result"][0]
    assert result["goal_id"] == goal_id and result["state"] == int(horus.GoalState.Succeeded)
    assert result["result"]["feedback_sent"] == 20 and result["result"]["reached"] is True
