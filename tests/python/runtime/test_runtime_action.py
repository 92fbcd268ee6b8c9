"""horus.ActionClient and horus.ActionServer in one process: goals with feedback, cancel, the three
policies, tick mode, asyncio, and a server that stops mid-goal. The action is the shared test
schema tests/schemas/test_actions/navigate.haction, generated here for Python (its C++ peer and
the process rows: test_action_crosslang.py)."""
from __future__ import annotations

import ast
import asyncio
import inspect
import math
import os
import pathlib
import subprocess
import sys
import threading
import time

import pytest

import horus

REPOSITORY = pathlib.Path(__file__).resolve().parents[3]
NAVIGATE_SCHEMA = REPOSITORY / "tests" / "schemas" / "test_actions" / "navigate.haction"


_generated: list[str] = []


def generated_actions(tmp_path_factory) -> str:
    """The Python folder of horus_test.action (Navigate, Echo), generated once per run and put on
    sys.path; children get it on their PYTHONPATH from `action_env`."""
    if not _generated:
        out = tmp_path_factory.mktemp("actions")
        generator = os.environ.get("HORUS_GEN_PROGRAM",
                                   str(REPOSITORY / "generator" / "horus-gen"))
        subprocess.run([generator, "generate", "--lang", "python", "--out", str(out),
                        str(NAVIGATE_SCHEMA)], check=True)
        _generated.append(str(out / "python"))
        sys.path.insert(0, _generated[0])
    return _generated[0]


@pytest.fixture
def actions(tmp_path_factory):
    generated_actions(tmp_path_factory)
    import horus_test.action
    return horus_test.action


def action_env(action_python_dir: str) -> dict:
    """This process's environment (namespace included) with the generated actions importable."""
    return {**os.environ,
            "PYTHONPATH": os.pathsep.join([action_python_dir, os.environ.get("PYTHONPATH", "")])}


def navigate_execute(Navigate):
    """The test server of the contract: N feedbacks `period_us` apart, then Succeeded; abort_with:
    Aborted with it; cancel: Canceled."""
    def execute(goal: horus.ServerGoal):
        g = goal.goal
        count = g.feedback_count
        distance = math.hypot(g.x, g.y)
        for step in range(1, count + 1):
            if goal.cancel_requested:
                goal.cancel()
                return None
            time.sleep(g.period_us / 1e6)
            goal.publish_feedback(Navigate.Feedback(step=step,
                                                    remaining_m=distance * (count - step) / count))
        if g.abort_with:
            goal.abort(g.abort_with)
            return None
        return Navigate.Result(reached=True, final_x=g.x, final_y=g.y, feedback_sent=count)
    return execute


def test_goal_succeeds_after_twenty_feedbacks_with_callbacks(actions):
    Navigate = actions.Navigate
    feedback_seen, states = [], []
    with horus.ActionServer(Navigate, navigate_execute(Navigate)) as server, \
            horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal(x=3.0, y=4.0), timeout=1.0,
                                  on_feedback=feedback_seen.append,
                                  on_state=lambda state, reason: states.append(state))
        assert handle.state in (horus.GoalState.Accepted, horus.GoalState.Executing)
        assert handle.goal_id == horus.GoalId(client.client_id, 1)
        assert len(str(handle.goal_id)) == 32 and str(handle.goal_id) == \
            handle.goal_id.to_bytes().hex()
        assert horus.GoalId.from_bytes(handle.goal_id.to_bytes()) == handle.goal_id
        steps = [fb.step for fb in handle.feedback(timeout=2.0)]
        result = handle.result(timeout=2.0)
        assert steps == list(range(1, 21))
        assert result.state == horus.GoalState.Succeeded and result.succeeded
        assert result.reason == ""
        assert (result.result.reached, result.result.final_x, result.result.feedback_sent) == \
            (True, 3.0, 20)
        assert handle.done and handle.latest_feedback.remaining_m == 0.0
        deadline = time.monotonic() + 1.0
        while horus.GoalState.Succeeded not in states and time.monotonic() < deadline:
            time.sleep(0.01)
        assert [fb.step for fb in feedback_seen] == list(range(1, 21))
        assert states[-1] == horus.GoalState.Succeeded and horus.GoalState.Executing in states
        assert handle.cancel() == horus.CancelCode.AlreadyDone
        stats = server.stats
        assert (stats.goals, stats.accepted, stats.succeeded, stats.feedback_sent) == (1, 1, 1, 20)


def test_serialized_action_round_trips(actions):
    Echo = actions.Echo

    def execute(goal):
        for n in range(1, goal.goal.repeat + 1):
            goal.publish_feedback(Echo.Feedback(partial=[goal.goal.text] * n))
        return Echo.Result(text=goal.goal.text * goal.goal.repeat)

    with horus.ActionServer(Echo, execute), horus.ActionClient(Echo) as client:
        handle = client.send_goal(Echo.Goal(text="ab"))
        assert [len(fb.partial) for fb in handle.feedback(timeout=2.0)] == [1, 2, 3]
        assert handle.result(2.0).result.text == "ababab"


def test_cancel_mid_goal_ends_it_canceled_and_the_server_serves_on(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, navigate_execute(Navigate)) as server, \
            horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal(x=1.0, feedback_count=200, period_us=5000))
        assert handle.next_feedback(timeout=2.0) is not None
        assert handle.cancel() == horus.CancelCode.Accepted
        result = handle.result(timeout=2.0)
        assert (result.state, result.reason) == (horus.GoalState.Canceled, "canceled by a client")
        assert server.stats.canceled == 1
        assert client.send_goal(Navigate.Goal(x=1.0, feedback_count=2)).result(2.0).succeeded


def test_abort_reason_and_execute_outcomes(actions):
    Navigate = actions.Navigate
    outcomes = iter(["abort", "none", "raise"])

    def execute(goal):
        what = next(outcomes)
        if what == "abort":
            goal.abort("blocked by a pallet", Navigate.Result(final_x=0.5))
        elif what == "raise":
            raise ValueError("no map")
        return None

    with horus.ActionServer(Navigate, execute), horus.ActionClient(Navigate) as client:
        first = client.send_goal(Navigate.Goal()).result(2.0)
        assert (first.state, first.reason, first.result.final_x) == \
            (horus.GoalState.Aborted, "blocked by a pallet", 0.5)
        second = client.send_goal(Navigate.Goal()).result(2.0)
        assert (second.state, second.reason) == \
            (horus.GoalState.Aborted, "execute returned without an outcome")
        third = client.send_goal(Navigate.Goal()).result(2.0)
        assert third.reason == "execute raised: ValueError: no map"


def test_reject_policy_refuses_a_second_client_while_busy(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, navigate_execute(Navigate)) as server, \
            horus.ActionClient(Navigate) as first, horus.ActionClient(Navigate) as second:
        running = first.send_goal(Navigate.Goal(feedback_count=20, period_us=10000))
        refused = second.send_goal(Navigate.Goal())
        assert refused.state == horus.GoalState.Rejected and refused.done
        assert refused.reason == f"busy: goal {running.goal_id} is executing"
        assert refused.result(0).state == horus.GoalState.Rejected
        assert running.result(2.0).succeeded
        assert server.stats.rejected == 1


def test_preempt_policy_cancels_the_running_goal_for_the_new_one(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, navigate_execute(Navigate), policy="preempt"), \
            horus.ActionClient(Navigate) as first, horus.ActionClient(Navigate) as second:
        old = first.send_goal(Navigate.Goal(feedback_count=200, period_us=5000))
        assert old.next_feedback(timeout=2.0) is not None
        new = second.send_goal(Navigate.Goal(x=2.0, feedback_count=3))
        old_result = old.result(2.0)
        assert (old_result.state, old_result.reason) == \
            (horus.GoalState.Canceled, f"preempted by goal {new.goal_id}")
        assert new.result(2.0).succeeded


def test_queue_policy_runs_goals_in_order_and_bounds_the_queue(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, navigate_execute(Navigate), policy="queue",
                            queue_capacity=1), \
            horus.ActionClient(Navigate) as first, horus.ActionClient(Navigate) as second:
        running = first.send_goal(Navigate.Goal(feedback_count=10, period_us=10000))
        assert running.next_feedback(timeout=2.0) is not None
        queued = second.send_goal(Navigate.Goal(feedback_count=2))
        assert queued.state == horus.GoalState.Accepted
        full = second.send_goal(Navigate.Goal())
        assert (full.state, full.reason) == (horus.GoalState.Rejected,
                                             "queue full (1 goals waiting)")
        assert running.result(2.0).succeeded
        assert queued.result(2.0).succeeded


def test_accept_and_cancel_callbacks_decide(actions):
    Navigate = actions.Navigate
    server = horus.ActionServer(
        Navigate, navigate_execute(Navigate),
        accept=lambda goal: True if goal.x >= 0 else "x must not be negative",
        cancel=lambda goal: False)
    with server, horus.ActionClient(Navigate) as client:
        refused = client.send_goal(Navigate.Goal(x=-1.0))
        assert (refused.state, refused.reason) == (horus.GoalState.Rejected,
                                                   "x must not be negative")
        handle = client.send_goal(Navigate.Goal(x=1.0, feedback_count=20, period_us=5000))
        assert handle.cancel() == horus.CancelCode.Rejected
        assert handle.result(2.0).succeeded


def test_cancel_all_and_unknown_goals(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, navigate_execute(Navigate), policy="queue"), \
            horus.ActionClient(Navigate) as client:
        running = client.send_goal(Navigate.Goal(feedback_count=200, period_us=5000))
        waiting = client.send_goal(Navigate.Goal())
        assert client.cancel_all() == horus.CancelCode.Accepted
        assert waiting.result(2.0).state == horus.GoalState.Canceled
        assert running.result(2.0).state == horus.GoalState.Canceled
        unknown = horus.GoalId(client.client_id, 99)
        assert client._cancel(unknown, 1.0) == horus.CancelCode.UnknownGoal


def test_tick_mode_hands_out_goals_one_at_a_time(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, policy="queue") as server, \
            horus.ActionClient(Navigate) as client:
        assert server.next_goal() is None
        first = client.send_goal(Navigate.Goal(x=1.0))
        second = client.send_goal(Navigate.Goal(x=2.0))
        goal = server.next_goal()
        assert goal.goal.x == 1.0 and goal.state == horus.GoalState.Executing
        assert server.next_goal() is None  # one at a time: the first has not ended
        assert goal.publish_feedback(Navigate.Feedback(step=1))
        assert first.next_feedback(timeout=2.0).step == 1
        assert goal.succeed(Navigate.Result(reached=True)) and not goal.succeed()
        assert not goal.publish_feedback(Navigate.Feedback(step=2))
        assert first.result(2.0).result.reached
        assert server.next_goal().goal.x == 2.0
        with pytest.raises(TypeError, match="NavigateResult"):
            goal.succeed(Navigate.Feedback())
        server.stop()
        assert (second.result(2.0).state, second.reason) == (horus.GoalState.Aborted,
                                                             "the action server stopped")


def test_asyncio_client_and_async_execute(actions):
    Navigate = actions.Navigate

    async def execute(goal):
        for step in range(1, goal.goal.feedback_count + 1):
            if goal.cancel_requested:
                goal.cancel()
                return None
            goal.publish_feedback(Navigate.Feedback(step=step))
            await asyncio.sleep(goal.goal.period_us / 1e6)
        return Navigate.Result(reached=True, feedback_sent=goal.goal.feedback_count)

    async def use(client):
        handle = await client.send_goal_async(Navigate.Goal(feedback_count=5), timeout=1.0)
        steps = [fb.step async for fb in handle.feedback_async()]
        result = await handle
        long = await client.send_goal_async(Navigate.Goal(feedback_count=400, period_us=5000))
        waiting = asyncio.ensure_future(long.result_async())
        await asyncio.sleep(0.05)
        waiting.cancel()  # a cancelled await cancels the goal
        with pytest.raises(asyncio.CancelledError):
            await waiting
        return steps, result, await long

    with horus.ActionServer(Navigate, execute), horus.ActionClient(Navigate) as client:
        steps, result, canceled = asyncio.run(asyncio.wait_for(use(client), 5.0))
    assert steps == [1, 2, 3, 4, 5] and result.result.feedback_sent == 5
    assert canceled.state == horus.GoalState.Canceled


def test_no_server_fails_at_once_and_result_times_out(actions):
    Navigate = actions.Navigate
    with horus.ActionClient(Navigate) as client:
        started = time.monotonic()
        with pytest.raises(horus.NoServerError, match="no server of action Navigate"):
            client.send_goal(Navigate.Goal(), timeout=1.0)
        assert time.monotonic() - started < 0.5
        assert not client.wait_for_server(0.05)
        with pytest.raises(TypeError, match="NavigateGoal"):
            client.send_goal(Navigate.Feedback())
    with horus.ActionServer(Navigate, navigate_execute(Navigate)), \
            horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal(feedback_count=50, period_us=5000))
        with pytest.raises(horus.ServiceTimeout, match="did not end within"):
            handle.result(timeout=0.02)


def test_server_stop_mid_goal_aborts_the_clients_goal_promptly(actions):
    Navigate = actions.Navigate
    server = horus.ActionServer(Navigate, navigate_execute(Navigate))
    with horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal(feedback_count=400, period_us=5000))
        assert handle.next_feedback(timeout=2.0) is not None
        started = time.monotonic()
        server.stop()
        result = handle.result(timeout=1.0)
        assert time.monotonic() - started < 1.0
        assert (result.state, result.reason) == (horus.GoalState.Aborted,
                                                 "the action server stopped")
        with pytest.raises(horus.NoServerError):
            client.send_goal(Navigate.Goal())


def test_closing_the_client_cancels_its_goals(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate, navigate_execute(Navigate)) as server:
        client = horus.ActionClient(Navigate)
        handle = client.send_goal(Navigate.Goal(feedback_count=400, period_us=5000))
        assert handle.next_feedback(timeout=2.0) is not None
        client.close()
        assert (handle.state, handle.reason) == (horus.GoalState.Aborted,
                                                 "the action client closed")
        deadline = time.monotonic() + 2.0
        while server.stats.canceled == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert server.stats.canceled == 1
        with pytest.raises(horus.TransportError, match="closed"):
            client.send_goal(Navigate.Goal())


def test_bad_arguments_are_told(actions):
    Navigate = actions.Navigate
    with pytest.raises(ValueError, match="policy is one of"):
        horus.ActionServer(Navigate, policy="lifo")
    with pytest.raises(TypeError, match="not a generated action class"):
        horus.ActionClient(Navigate.Goal)
    with horus.ActionServer(Navigate):
        with pytest.raises(horus.HorusError):
            horus.ActionServer(Navigate)  # one live server per action


def test_stubs_declare_the_action_classes():
    tree = ast.parse(pathlib.Path(horus.__file__).with_name("__init__.pyi").read_text())
    functions = (ast.FunctionDef, ast.AsyncFunctionDef)
    declared = {node.name: {n.name for n in node.body if isinstance(n, functions)} |
                {n.target.id for n in node.body if isinstance(n, ast.AnnAssign)}
                for node in tree.body if isinstance(node, ast.ClassDef)}
    for cls in (horus.ActionClient, horus.ActionServer, horus.GoalHandle, horus.ServerGoal,
                horus.GoalResult, horus.GoalId):
        public = {name for name, _ in inspect.getmembers(cls) if not name.startswith("_")}
        assert public <= declared[cls.__name__], (cls.__name__, public - declared[cls.__name__])


def test_many_threads_send_goals_at_once(actions):
    Navigate = actions.Navigate
    results = []
    with horus.ActionServer(Navigate, navigate_execute(Navigate), policy="queue",
                            queue_capacity=8), horus.ActionClient(Navigate) as client:
        def send():
            results.append(client.send_goal(Navigate.Goal(feedback_count=2)).result(5.0))
        threads = [threading.Thread(target=send) for _ in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert len(results) == 4 and all(r.succeeded for r in results)


def test_a_handle_keeps_the_newest_64_unread_feedbacks(actions):
    Navigate = actions.Navigate
    with horus.ActionServer(Navigate) as server, horus.ActionClient(Navigate) as client:
        handle = client.send_goal(Navigate.Goal())
        goal = server.next_goal()
        for step in range(1, 101):
            assert goal.publish_feedback(Navigate.Feedback(step=step))
        goal.succeed()
        assert handle.result(2.0).succeeded
        steps = [fb.step for fb in handle.feedback(timeout=0)]
        assert steps == list(range(37, 101))  # the topic and the handle both keep the newest
        # What the topic did not lose (it keeps 64 too), the handle counts.
        assert handle.lost_feedback + client._feedback_topic.lost() == 36
        assert handle.latest_feedback.step == 100
