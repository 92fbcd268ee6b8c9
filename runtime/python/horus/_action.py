"""horus.ActionClient and horus.ActionServer: generated actions from Python.

An action is three generated services (`A.send_goal`, `A.cancel_goal`, `A.get_result`) and three
topics (`A.feedback`, `A.status`, `A.result`); this module speaks that wire over
horus.ServiceClient, the byte-level service server and horus.Topic, with the states, texts,
policies and timing of the C++ runtime (horus/action.hpp; the wire: runtime/src/action/README.md),
so either side of a goal may be C++ or Python.
"""
from __future__ import annotations

import asyncio
import collections
import dataclasses
import enum
import inspect
import itertools
import struct
import threading
import time
import traceback

from . import _core
from ._service import NoServerError, ServiceClient, ServiceTimeout, TransportError
from ._topic import Topic

_KEPT_FEEDBACK = 64  # feedback messages a handle keeps unread; older ones are counted as lost
_KEPT_ENDED = 64  # ended goals a server remembers for get_result and cancel
_SERVER_CHECK = 0.01  # how often a client with live goals re-reads the server's registration
_CLIENT_CHECK = 0.05  # how often a server looks for goals whose client exited
_BUSY_SLICE = 0.01  # the pump's wait on the feedback topic while a goal is live
_IDLE_SLICE = 0.25  # the pump's wait with no live goal (it then keeps the topics read)
_SERVE_SLICE = 0.05  # a server thread's wait for a request (it checks its stop flag between)
_RESULT_GRACE = 0.1  # a terminal status without its result message this long: asked with get_result
_CLOSE_CANCEL = 0.1  # how long closing a client waits for the cancel of its live goals
# The texts both languages write (runtime/src/action/README.md lists them).
_CLIENT_CLOSED = "the action client closed"
_STOPPED = "the action server stopped"
_RETURNED = "execute returned without an outcome"
_CANCELED_BY_CLIENT = "canceled by a client"


class GoalState(enum.IntEnum):
    """A goal's state: action_msgs/GoalStatus's values 0-6, and Rejected (never sent to ROS)."""

    Unknown = 0
    Accepted = 1
    Executing = 2
    Canceling = 3
    Succeeded = 4
    Canceled = 5
    Aborted = 6
    Rejected = 7

    @property
    def terminal(self) -> bool:
        return self >= GoalState.Succeeded

    def __str__(self) -> str:
        return self.name.lower()


class CancelCode(enum.IntEnum):
    """The answer to a cancel request (action_msgs/CancelGoal's return codes)."""

    Accepted = 0
    Rejected = 1
    UnknownGoal = 2
    AlreadyDone = 3


# Which state may follow which: a late or repeated status never moves a goal backwards.
_NEXT = {
    GoalState.Unknown: {GoalState.Accepted, GoalState.Executing, GoalState.Canceling,
                        GoalState.Succeeded, GoalState.Canceled, GoalState.Aborted,
                        GoalState.Rejected},
    GoalState.Accepted: {GoalState.Executing, GoalState.Canceling, GoalState.Succeeded,
                         GoalState.Canceled, GoalState.Aborted},
    GoalState.Executing: {GoalState.Canceling, GoalState.Succeeded, GoalState.Canceled,
                          GoalState.Aborted},
    GoalState.Canceling: {GoalState.Canceled, GoalState.Succeeded, GoalState.Aborted},
}
_POLICIES = ("reject", "preempt", "queue")


@dataclasses.dataclass(frozen=True, order=True)
class GoalId:
    """A goal's id: the sending client's id and a count from 1. On the wire 16 bytes, each half
    little-endian (the place of ROS 2's UUID); all zero means every goal (cancel only)."""

    client_id: int
    sequence: int

    def to_bytes(self) -> bytes:
        return struct.pack("<QQ", self.client_id, self.sequence)

    @classmethod
    def from_bytes(cls, data) -> "GoalId":
        raw = bytes(data)
        if len(raw) != 16:
            raise ValueError(f"a goal id is 16 bytes, not {len(raw)}")
        return cls(*struct.unpack("<QQ", raw))

    @property
    def is_all(self) -> bool:
        return self.client_id == 0 and self.sequence == 0

    def __str__(self) -> str:
        return self.to_bytes().hex()


_ALL_GOALS = GoalId(0, 0)


@dataclasses.dataclass(frozen=True)
class GoalResult:
    """How a goal ended: its terminal state, the reason (empty when it succeeded) and the result
    (the default one when the server gave none)."""

    state: GoalState
    reason: str
    result: object

    @property
    def succeeded(self) -> bool:
        return self.state == GoalState.Succeeded


def _stamp_ns() -> int:
    return time.time_ns()


def _check_action(action) -> None:
    missing = [name for name in ("Goal", "Result", "Feedback", "SendGoal", "CancelGoal",
                                 "GetResult", "FeedbackMessage", "Status", "ResultMessage",
                                 "feedback_topic", "status_topic", "result_topic")
               if not hasattr(action, name)]
    if missing:
        raise TypeError(f"{action!r} is not a generated action class (it has no "
                        f"{', '.join(missing)}): pass the class horus-gen made from a .haction")


def _wait(condition: threading.Condition, ready, timeout: float | None) -> bool:
    """Waits on `condition` (held) until ready(), at most `timeout` seconds (None: however long,
    in slices so Ctrl+C gets through); whether ready() holds."""
    deadline = None if timeout is None else time.monotonic() + timeout
    while not ready():
        left = 0.1 if deadline is None else deadline - time.monotonic()
        if left <= 0:
            return False
        condition.wait(min(left, 0.1))
    return True


# ---- client ------------------------------------------------------------------------------------

class GoalHandle:
    """A goal sent by an ActionClient: its state, feedback and result as the client's pump thread
    receives them. `await handle` is `await handle.result_async()`."""

    def __init__(self, client: "ActionClient", goal_id: GoalId, on_feedback, on_state) -> None:
        self._client = client
        self.goal_id = goal_id
        self._state = GoalState.Unknown
        self._reason = ""
        self._result = None
        self._feedback = collections.deque()
        self._latest = None
        self._lost = 0
        self._on_feedback = on_feedback
        self._on_state = on_state
        self._events = []  # (feedback or None, state or None, reason) for the callbacks
        self._async_waiters = []  # (loop, asyncio.Event) woken on every change
        self._server_instance = 0
        self._server_pid = 0
        self._answered = False
        self._terminal_status_at = None  # when a terminal status came without its result

    # Read under the client's lock by the pump; plain reads are enough for the user.
    @property
    def state(self) -> GoalState:
        return self._state

    @property
    def reason(self) -> str:
        return self._reason

    @property
    def done(self) -> bool:
        return self._state.terminal

    @property
    def latest_feedback(self):
        """The newest feedback received, or None (read or not)."""
        return self._latest

    @property
    def lost_feedback(self) -> int:
        """Feedback messages dropped because more than 64 waited unread."""
        return self._lost

    def try_feedback(self):
        """The next unread feedback, or None; never blocks."""
        with self._client._lock:
            return self._feedback.popleft() if self._feedback else None

    def next_feedback(self, timeout: float | None = None):
        """The next unread feedback, waiting up to `timeout` seconds (None: until one comes or the
        goal ends); None when none came."""
        with self._client._changed:
            _wait(self._client._changed, lambda: self._feedback or self.done, timeout)
            return self._feedback.popleft() if self._feedback else None

    def feedback(self, timeout: float | None = None):
        """Iterates the feedback until the goal ends (and its feedback is read), or until none
        came for `timeout` seconds."""
        while True:
            item = self.next_feedback(timeout)
            if item is None:
                return
            yield item

    def try_result(self) -> GoalResult | None:
        """The outcome once the goal ended, else None (for a tick)."""
        return self._result if self.done else None

    def result(self, timeout: float | None = None) -> GoalResult:
        """The goal's outcome, waiting up to `timeout` seconds (None: until it ends); raises
        horus.ServiceTimeout when it did not end in time (the goal goes on)."""
        with self._client._changed:
            if not _wait(self._client._changed, lambda: self.done, timeout):
                raise ServiceTimeout(f"goal {self.goal_id} of {self._client.action.name} did not "
                                     f"end within {timeout:g} s (it is {self._state})")
            return self._result

    def cancel(self, timeout: float = 1.0) -> CancelCode:
        """Asks the server to cancel this goal; the answer (the goal itself ends as Canceled, or
        as the server decides, later). Raises a ServiceError when the call gets no answer."""
        if self.done:
            return CancelCode.AlreadyDone
        return self._client._cancel(self.goal_id, timeout)

    async def result_async(self) -> GoalResult:
        """The goal's outcome, awaited; a cancelled await cancels the goal."""
        try:
            while not self.done:
                await self._changed_async(lambda: self.done)
        except asyncio.CancelledError:
            await self._cancel_quietly()
            raise
        return self._result

    async def feedback_async(self):
        """Iterates the feedback until the goal ends; a cancelled iteration cancels the goal."""
        try:
            while True:
                item = self.try_feedback()
                if item is not None:
                    yield item
                elif self.done:
                    return
                else:
                    await self._changed_async(lambda: self._feedback or self.done)
        except asyncio.CancelledError:
            await self._cancel_quietly()
            raise

    def __await__(self):
        return self.result_async().__await__()

    async def _changed_async(self, ready) -> None:
        """Returns once ready() holds (checked under the client's lock), or after a change."""
        loop = asyncio.get_running_loop()
        event = asyncio.Event()
        with self._client._lock:
            if ready():
                return
            self._async_waiters.append((loop, event))
        try:
            await event.wait()
        finally:
            with self._client._lock:
                if (loop, event) in self._async_waiters:
                    self._async_waiters.remove((loop, event))

    async def _cancel_quietly(self) -> None:
        if not self.done:
            loop = asyncio.get_running_loop()
            try:
                await loop.run_in_executor(None, self.cancel)
            except Exception:  # noqa: BLE001 - the await was cancelled: nothing left to tell
                pass

    def __repr__(self) -> str:
        return f"<GoalHandle {self._client.action.name} {self.goal_id} {self._state}>"


class ActionClient:
    """Sends goals to a generated action's server (C++ or Python, in any process).

    send_goal() raises horus.NoServerError at once with no server (or ServiceTimeout,
    TransportError); a rejected goal comes back as a handle in state Rejected with the reason. One
    pump thread (from the first goal) receives feedback, states and results for every goal of this
    client and runs the callbacks; it also watches the server: one that stops, exits or restarts
    ends the live goals as Aborted within 10 ms. close() (or leaving a `with` block) cancels the
    live goals and ends their handles as Aborted "the action client closed".
    """

    def __init__(self, action) -> None:
        _check_action(action)
        self.action = action
        self._send = ServiceClient(action.SendGoal)
        self._cancel_client = ServiceClient(action.CancelGoal)
        self._get_result = ServiceClient(action.GetResult)
        self.client_id = self._send.client_id
        # Opened now, so nothing sent for a goal after its send_goal is missed.
        self._feedback_topic = Topic(action.FeedbackMessage, action.feedback_topic)
        self._status_topic = Topic(action.Status, action.status_topic)
        self._result_topic = Topic(action.ResultMessage, action.result_topic)
        self._registration = _core.ServiceRegistrationTopic(action.SendGoal.name)
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._goals: dict[bytes, GoalHandle] = {}
        self._sequence = itertools.count(1)
        self._pump = None
        self._pump_wake = threading.Event()  # set by a new goal or close(): the pump waits no more
        self._closed = False
        self._results_lost = 0
        self._ended_with_callbacks: list[GoalHandle] = []  # their last callbacks still to run

    # -- sending -----------------------------------------------------------------------------

    def wait_for_server(self, timeout: float) -> bool:
        """Waits up to `timeout` seconds for a live server; False if none came."""
        return self._send.wait_for_server(timeout)

    def send_goal(self, goal, timeout: float = 1.0, *, on_feedback=None,
                  on_state=None) -> GoalHandle:
        """Sends `goal` (the action's Goal) and returns its handle once the server decided.
        `on_feedback(feedback)` and `on_state(state, reason)` run on the pump thread."""
        if not isinstance(goal, self.action.Goal):
            raise TypeError(f"{self.action.name} takes a {self.action.Goal.__name__}, not "
                            f"{type(goal).__name__}")
        if self._closed:
            raise TransportError(_CLIENT_CLOSED)
        # The server the goal goes to: its later withdrawal, exit or restart ends the goal.
        registration = self._registration.latest()
        if registration is None or registration["server_pid"] == 0:
            raise NoServerError(f"no server of action {self.action.name}")
        goal_id = GoalId(self.client_id, next(self._sequence))
        handle = GoalHandle(self, goal_id, on_feedback, on_state)
        handle._server_instance = registration["server_instance"]
        handle._server_pid = registration["server_pid"]
        key = goal_id.to_bytes()
        with self._lock:
            self._goals[key] = handle  # early feedback (it races the answer) is kept
        self._start_pump()
        self._pump_wake.set()  # out of an idle wait: the server check runs every slice from now
        request = self.action.SendGoal.Request(goal_id=list(key), goal=goal)
        try:
            response = self._send.call(request, timeout)
        except BaseException:
            with self._lock:
                self._goals.pop(key, None)
            raise
        with self._changed:
            handle._answered = True
            if response.accepted:
                self._advance(handle, GoalState.Accepted, "")
            else:
                self._end(handle, GoalState.Rejected, response.reason, None)
        return handle

    async def send_goal_async(self, goal, timeout: float = 1.0, *, on_feedback=None,
                              on_state=None) -> GoalHandle:
        """send_goal() awaited (the call waits on a worker thread)."""
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(
            None, lambda: self.send_goal(goal, timeout, on_feedback=on_feedback,
                                         on_state=on_state))

    def cancel_all(self, timeout: float = 1.0) -> CancelCode:
        """Asks the server to cancel every live goal (of every client)."""
        return self._cancel(_ALL_GOALS, timeout)

    def _cancel(self, goal_id: GoalId, timeout: float) -> CancelCode:
        request = self.action.CancelGoal.Request(goal_id=list(goal_id.to_bytes()))
        return CancelCode(self._cancel_client.call(request, timeout).return_code)

    # -- the pump ----------------------------------------------------------------------------

    def _start_pump(self) -> None:
        with self._lock:
            if self._pump is None:
                self._pump = threading.Thread(target=self._run_pump, daemon=True,
                                              name=f"horus-{self.action.name}-client")
                self._pump.start()

    def _run_pump(self) -> None:
        next_check = 0.0
        while not self._closed:
            try:
                next_check = self._pump_once(next_check)
            except Exception:  # noqa: BLE001 - one bad message must not end every goal's news
                traceback.print_exc()
                time.sleep(_BUSY_SLICE)

    def _pump_once(self, next_check: float) -> float:
        """One wait on the topics and what came; the time of the next server check."""
        first = None
        if self._goals:
            first = self._feedback_topic.recv(_BUSY_SLICE)
        else:
            self._pump_wake.wait(_IDLE_SLICE)
            self._pump_wake.clear()
        if self._closed:
            return next_check
        # A server sends a goal's Executing status, then its feedback, then its result: drained
        # in the other order, whatever came before a message drained is drained too.
        results = self._drain(self._result_topic)
        feedbacks = self._drain(self._feedback_topic)
        if first is not None:
            feedbacks.insert(0, first)
        statuses = self._drain(self._status_topic)
        with self._changed:
            for message in statuses:
                self._on_status(message)
            for message in feedbacks:
                self._on_feedback_message(message)
            for message in results:
                self._on_result(message)
            self._changed.notify_all()
        if self._goals and time.monotonic() >= next_check:
            next_check = time.monotonic() + _SERVER_CHECK
            self._check_server()
            self._ask_missing_results()
        self._run_callbacks()
        return next_check

    @staticmethod
    def _drain(topic: Topic) -> list:
        out = []
        while (message := topic.try_recv()) is not None:
            out.append(message)
        return out

    def _on_feedback_message(self, message) -> None:
        handle = self._goals.get(bytes(message.goal_id))
        if handle is None or handle.done:
            return
        if len(handle._feedback) == _KEPT_FEEDBACK:
            handle._feedback.popleft()
            handle._lost += 1
        handle._feedback.append(message.feedback)
        handle._latest = message.feedback
        if handle._on_feedback is not None:
            handle._events.append((message.feedback, None, ""))
        self._wake(handle)

    def _on_status(self, message) -> None:
        handle = self._goals.get(bytes(message.goal_id))
        if handle is None:
            return
        state = GoalState(message.state) if message.state <= GoalState.Rejected \
            else GoalState.Unknown
        if state.terminal:
            # The result message carries the result: its absence is looked into shortly.
            if handle._terminal_status_at is None:
                handle._terminal_status_at = time.monotonic()
            return
        self._advance(handle, state, message.reason)

    def _on_result(self, message) -> None:
        handle = self._goals.get(bytes(message.goal_id))
        if handle is None or not GoalState.Succeeded <= message.state <= GoalState.Rejected:
            return
        self._end(handle, GoalState(message.state), message.reason, message.result)

    def _advance(self, handle: GoalHandle, state: GoalState, reason: str) -> bool:
        """Moves a goal to `state` when that follows its current one (lock held)."""
        if state not in _NEXT.get(handle._state, ()):
            return False
        handle._state = state
        handle._reason = reason
        if handle._on_state is not None:
            handle._events.append((None, state, reason))
        self._wake(handle)
        return True

    def _end(self, handle: GoalHandle, state: GoalState, reason: str, result) -> None:
        """Ends a goal (lock held): its outcome, then it leaves the table."""
        if handle.done:
            return
        handle._result = GoalResult(state, reason, result if result is not None
                                    else self.action.Result())
        self._advance(handle, state, reason)
        self._goals.pop(handle.goal_id.to_bytes(), None)
        if handle._events:
            self._ended_with_callbacks.append(handle)
        self._changed.notify_all()

    @staticmethod
    def _wake(handle: GoalHandle) -> None:
        for loop, event in handle._async_waiters:
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:  # its loop closed while the await ended: nobody waits there
                pass

    def _check_server(self) -> None:
        """The server's liveness, from the send_goal registration (the services' own rules)."""
        registration = self._registration.latest()
        with self._changed:
            for handle in list(self._goals.values()):
                if not handle._answered:
                    continue  # its send_goal call watches the server itself
                if registration is None or registration["server_pid"] == 0:
                    reason = _STOPPED
                elif registration["server_instance"] != handle._server_instance:
                    reason = "the action server restarted"
                elif _core.service_server_gone(handle._server_pid):
                    reason = f"the action server (pid {handle._server_pid}) exited mid-goal"
                else:
                    continue
                self._end(handle, GoalState.Aborted, reason, None)

    def _ask_missing_results(self) -> None:
        """get_result for goals whose result message was lost (the result topic overran) or has
        not come long after their terminal status."""
        lost = self._result_topic.lost()
        overran = lost != self._results_lost
        self._results_lost = lost
        now = time.monotonic()
        with self._lock:
            asking = [h for h in self._goals.values() if h._answered and (
                overran or (h._terminal_status_at is not None
                            and now - h._terminal_status_at >= _RESULT_GRACE))]
        for handle in asking:
            request = self.action.GetResult.Request(goal_id=list(handle.goal_id.to_bytes()))
            try:
                message = self._get_result.call(request, 0.1)
            except Exception:  # noqa: BLE001 - the server check tells a dead server
                continue
            with self._changed:
                self._on_result(message)

    def _run_callbacks(self) -> None:
        with self._lock:
            handles = list(self._goals.values()) + self._ended_with_callbacks
            self._ended_with_callbacks = []
            pending = [(h, h._events) for h in handles if h._events]
            for handle, _ in pending:
                handle._events = []
        for handle, events in pending:
            for feedback, state, reason in events:
                try:
                    if feedback is not None:
                        handle._on_feedback(feedback)
                    else:
                        handle._on_state(state, reason)
                except Exception:  # noqa: BLE001 - one callback's bug must not stop the pump
                    traceback.print_exc()

    # -- closing -----------------------------------------------------------------------------

    def close(self) -> None:
        """Cancels this client's live goals (waiting up to 100 ms for each answer), ends their
        handles as Aborted "the action client closed" and stops the pump."""
        if self._closed:
            return
        with self._lock:
            live = list(self._goals.values())
        for handle in live:
            try:
                handle.cancel(_CLOSE_CANCEL)
            except Exception:  # noqa: BLE001 - no server: nothing to cancel there
                pass
        with self._changed:
            for handle in list(self._goals.values()):
                self._end(handle, GoalState.Aborted, _CLIENT_CLOSED, None)
            self._closed = True
        self._pump_wake.set()
        if self._pump is not None and self._pump is not threading.current_thread():
            self._pump.join()
        self._send.close()
        self._cancel_client.close()
        self._get_result.close()

    def __enter__(self) -> "ActionClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        if hasattr(self, "_pump"):
            self.close()


# ---- server ------------------------------------------------------------------------------------

class ServerGoal:
    """A goal the server accepted, as its execute function (or a tick) sees it. Ending it
    (succeed, abort, cancel) publishes the result; a second ending does nothing and returns
    False."""

    def __init__(self, server: "ActionServer", goal_id: GoalId, goal, caller_id: int) -> None:
        self._server = server
        self.goal_id = goal_id
        self.goal = goal
        self._caller_id = caller_id
        self._state = GoalState.Accepted
        self._cancel_requested = False
        self._cancel_reason = ""

    @property
    def state(self) -> GoalState:
        return self._state

    @property
    def done(self) -> bool:
        return self._state.terminal

    @property
    def cancel_requested(self) -> bool:
        """Whether a client, a preempting goal, the client's exit or stop() asked to cancel."""
        return self._cancel_requested

    @property
    def cancel_reason(self) -> str:
        return self._cancel_reason

    def publish_feedback(self, feedback) -> bool:
        """Sends `feedback` (the action's Feedback) to the client; False once the goal ended or
        when the topic refused it."""
        action = self._server.action
        if not isinstance(feedback, action.Feedback):
            raise TypeError(f"{action.name}'s feedback is a {action.Feedback.__name__}, not "
                            f"{type(feedback).__name__}")
        return self._server._publish_feedback(self, feedback)

    def succeed(self, result=None) -> bool:
        return self._server._end(self, GoalState.Succeeded, "", result)

    def abort(self, reason: str, result=None) -> bool:
        return self._server._end(self, GoalState.Aborted, reason, result)

    def cancel(self, result=None) -> bool:
        """Ends the goal as Canceled (normally once cancel_requested)."""
        return self._server._end(self, GoalState.Canceled, self._cancel_reason, result)

    def __repr__(self) -> str:
        return f"<ServerGoal {self._server.action.name} {self.goal_id} {self._state}>"


@dataclasses.dataclass
class ActionServerStats:
    """What a server did so far (a copy)."""

    goals: int = 0
    accepted: int = 0
    rejected: int = 0
    succeeded: int = 0
    aborted: int = 0
    canceled: int = 0
    feedback_sent: int = 0
    feedback_refused: int = 0


class ActionServer:
    """Serves a generated action: decides each goal, runs one at a time, publishes its feedback
    and ends it.

    `execute(goal: ServerGoal)` runs each goal on the server's executor thread (an `async def` on
    the server's event-loop thread); returning un-ended, a returned Result succeeds the goal and
    None (or an exception) aborts it. Without `execute` the server is in tick mode: next_goal()
    hands out the next goal to run. `accept(goal) -> True | str` may reject a goal with a reason
    (it runs on the send_goal thread: be quick); `cancel(server_goal) -> bool` may refuse a
    cancel. `policy` for a goal arriving while one runs: "reject" it (`busy: goal <id> is
    executing`), "preempt" the running one, or "queue" it (at most `queue_capacity` waiting).

    Registering fails (horus.HorusError) while another live server serves the action. A goal
    whose client process exits is canceled. stop() (or leaving a `with` block) aborts the live
    goals ("the action server stopped") and withdraws the registrations.
    """

    def __init__(self, action, execute=None, *, accept=None, cancel=None,
                 policy: str = "reject", queue_capacity: int = 8) -> None:
        _check_action(action)
        if policy not in _POLICIES:
            raise ValueError(f"policy is one of {', '.join(map(repr, _POLICIES))}, not {policy!r}")
        if queue_capacity < 1:
            raise ValueError(f"queue_capacity must be at least 1, got {queue_capacity}")
        for name, function in (("execute", execute), ("accept", accept), ("cancel", cancel)):
            if function is not None and not callable(function):
                raise TypeError(f"ActionServer({action.name}): {name} must be callable")
        self.action = action
        self.policy = policy
        self.queue_capacity = queue_capacity
        self._execute = execute
        self._accept = accept
        self._accept_cancel = cancel
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._live: dict[bytes, ServerGoal] = {}
        self._waiting: collections.deque[ServerGoal] = collections.deque()
        self._executing: ServerGoal | None = None
        self._ended: collections.OrderedDict[bytes, object] = collections.OrderedDict()
        self._stats = ActionServerStats()
        self._stopping = threading.Event()
        self._feedback_topic = Topic(action.FeedbackMessage, action.feedback_topic)
        self._status_topic = Topic(action.Status, action.status_topic)
        self._result_topic = Topic(action.ResultMessage, action.result_topic)
        self._servers = []
        try:
            for service in (action.SendGoal, action.CancelGoal, action.GetResult):
                self._servers.append(_core.ServiceServer(service))
        except BaseException:
            for raw in self._servers:
                raw.stop()
                raw.withdraw()
            raise
        self._loop = None
        self._loop_thread = None
        if execute is not None and inspect.iscoroutinefunction(execute):
            self._loop = asyncio.new_event_loop()
            self._loop_thread = threading.Thread(target=self._loop.run_forever, daemon=True,
                                                 name=f"horus-{action.name}-loop")
            self._loop_thread.start()
        # The send_goal thread also looks for goals whose client exited.
        self._service_threads = [
            threading.Thread(target=self._serve, args=(raw, handler, checks_clients),
                             daemon=True, name=f"horus-{service.name}")
            for raw, handler, checks_clients, service in zip(
                self._servers, (self._on_send_goal, self._on_cancel_goal, self._on_get_result),
                (True, False, False), (action.SendGoal, action.CancelGoal, action.GetResult))]
        self._executor_thread = None
        if execute is not None:
            self._executor_thread = threading.Thread(target=self._run_executor, daemon=True,
                                                     name=f"horus-{action.name}-execute")
        for thread in self._service_threads + [self._executor_thread]:
            if thread is not None:
                thread.start()

    # -- the three services ------------------------------------------------------------------

    def _serve(self, raw, handler, checks_clients: bool) -> None:
        next_client_check = 0.0
        while not self._stopping.is_set():
            request = raw.next(_SERVE_SLICE)
            if request is not None:
                caller, data = request
                try:
                    answer = handler(caller, data)
                except Exception as failure:  # noqa: BLE001 - the caller is told; serving goes on
                    raw.fail(caller, "ServiceFailed", f"{type(failure).__name__}: {failure}")
                    continue
                raw.answer(caller, answer.to_bytes())
            if checks_clients and time.monotonic() >= next_client_check:
                next_client_check = time.monotonic() + _CLIENT_CHECK
                self._check_clients()

    def _on_send_goal(self, caller, data: bytes):
        request = self.action.SendGoal.Request.from_bytes(data)
        goal_id = GoalId.from_bytes(request.goal_id)
        key = goal_id.to_bytes()
        with self._lock:
            self._stats.goals += 1
            rejection = self._policy_rejection(key)
        if rejection is None:
            rejection = self._decide(request.goal)  # the user's code, without the lock
        stamp = _stamp_ns()
        with self._changed:
            if rejection is None:
                rejection = self._policy_rejection(key)  # stop() may have come meanwhile
            if rejection is not None:
                self._stats.rejected += 1
                self._publish_status(goal_id, GoalState.Rejected, stamp, rejection)
                return self.action.SendGoal.Response(accepted=False, stamp_ns=stamp,
                                                     reason=rejection)
            if self.policy == "preempt":
                self._preempt(goal_id)
            goal = ServerGoal(self, goal_id, request.goal, caller.client_id)
            self._stats.accepted += 1
            self._live[key] = goal
            # Accepted goes out before the executor can say Executing.
            self._publish_status(goal_id, GoalState.Accepted, stamp, "")
            self._waiting.append(goal)
            self._changed.notify_all()
        return self.action.SendGoal.Response(accepted=True, stamp_ns=stamp, reason="")

    def _decide(self, goal) -> str | None:
        """The `accept` callback's verdict: None to accept, else the rejection's reason."""
        if self._accept is None:
            return None
        try:
            verdict = self._accept(goal)
        except Exception as failure:  # noqa: BLE001 - the goal is refused, with why
            return f"accept raised: {type(failure).__name__}: {failure}"
        if verdict is True:
            return None
        return verdict if isinstance(verdict, str) and verdict else "rejected by the server"

    def _policy_rejection(self, key: bytes) -> str | None:
        if self._stopping.is_set():
            return _STOPPED
        if key in self._live:
            return f"goal {GoalId.from_bytes(key)} already exists"
        running = self._executing if self._executing is not None and not self._executing.done \
            else (self._waiting[0] if self._waiting else None)
        if self.policy == "reject" and running is not None:
            return f"busy: goal {running.goal_id} is executing"
        if self.policy == "queue" and len(self._waiting) >= self.queue_capacity:
            return f"queue full ({len(self._waiting)} goals waiting)"
        return None

    def _preempt(self, newcomer: GoalId) -> None:
        reason = f"preempted by goal {newcomer}"
        while self._waiting:
            self._end_locked(self._waiting.popleft(), GoalState.Canceled, reason, None)
        if self._executing is not None and not self._executing.done:
            self._request_cancel(self._executing, reason)

    def _on_cancel_goal(self, caller, data: bytes):
        request = self.action.CancelGoal.Request.from_bytes(data)
        goal_id = GoalId.from_bytes(request.goal_id)
        key = goal_id.to_bytes()
        Response = self.action.CancelGoal.Response
        with self._changed:
            if goal_id.is_all:
                targets = list(self._live.values())
            elif key in self._live:
                targets = [self._live[key]]
            elif key in self._ended:
                return Response(return_code=CancelCode.AlreadyDone, goals_canceling=0)
            else:
                return Response(return_code=CancelCode.UnknownGoal, goals_canceling=0)
        # The user's cancel callback runs without the lock (it may look at the goal).
        targets = [g for g in targets if self._cancel_agreed(g)]
        with self._changed:
            canceling = 0
            for goal in targets:
                if goal.done:
                    continue
                canceling += 1
                if goal in self._waiting:
                    self._waiting.remove(goal)
                    self._end_locked(goal, GoalState.Canceled, _CANCELED_BY_CLIENT, None)
                else:
                    self._request_cancel(goal, _CANCELED_BY_CLIENT)
        if not canceling and not goal_id.is_all:
            code = CancelCode.AlreadyDone if targets else CancelCode.Rejected
            return Response(return_code=code, goals_canceling=0)
        return Response(return_code=CancelCode.Accepted, goals_canceling=canceling)

    def _cancel_agreed(self, goal: ServerGoal) -> bool:
        if self._accept_cancel is None:
            return True
        try:
            return bool(self._accept_cancel(goal))
        except Exception:  # noqa: BLE001 - a failing decision refuses, as in C++
            return False

    def _on_get_result(self, caller, data: bytes):
        request = self.action.GetResult.Request.from_bytes(data)
        key = GoalId.from_bytes(request.goal_id).to_bytes()
        with self._lock:
            ended = self._ended.get(key)
            if ended is not None:
                return ended
            live = self._live.get(key)
            state = live.state if live is not None else GoalState.Unknown
        return self.action.ResultMessage(goal_id=list(key), state=int(state), stamp_ns=_stamp_ns(),
                                         reason="", result=self.action.Result())

    # -- goals' lives ------------------------------------------------------------------------

    def _request_cancel(self, goal: ServerGoal, reason: str) -> None:
        """An executing goal asked to cancel (lock held); a waiting one of a tick-mode server
        too."""
        if goal._state in (GoalState.Accepted, GoalState.Executing):
            goal._state = GoalState.Canceling
            goal._cancel_requested = True
            goal._cancel_reason = reason
            self._publish_status(goal.goal_id, GoalState.Canceling, _stamp_ns(), reason)

    def _publish_status(self, goal_id: GoalId, state: GoalState, stamp: int, reason: str) -> None:
        self._status_topic.send(self.action.Status(goal_id=list(goal_id.to_bytes()),
                                                   state=int(state), stamp_ns=stamp,
                                                   reason=reason))

    def _publish_feedback(self, goal: ServerGoal, feedback) -> bool:
        with self._lock:
            if goal.done:
                return False
            sent = self._feedback_topic.send(self.action.FeedbackMessage(
                goal_id=list(goal.goal_id.to_bytes()), feedback=feedback))
            if sent:
                self._stats.feedback_sent += 1
            else:
                self._stats.feedback_refused += 1
            return sent

    def _end(self, goal: ServerGoal, state: GoalState, reason: str, result) -> bool:
        with self._changed:
            return self._end_locked(goal, state, reason, result)

    def _end_locked(self, goal: ServerGoal, state: GoalState, reason: str, result) -> bool:
        if result is None:
            result = self.action.Result()
        elif not isinstance(result, self.action.Result):
            raise TypeError(f"{self.action.name}'s result is a {self.action.Result.__name__}, "
                            f"not {type(result).__name__}")
        if goal.done:
            return False
        key = goal.goal_id.to_bytes()
        stamp = _stamp_ns()
        message = self.action.ResultMessage(goal_id=list(key), state=int(state), stamp_ns=stamp,
                                            reason=reason, result=result)
        goal._state = state
        self._live.pop(key, None)
        self._ended[key] = message
        while len(self._ended) > _KEPT_ENDED:
            self._ended.popitem(last=False)
        counted = {GoalState.Succeeded: "succeeded", GoalState.Aborted: "aborted",
                   GoalState.Canceled: "canceled"}[state]
        setattr(self._stats, counted, getattr(self._stats, counted) + 1)
        self._result_topic.send(message)
        self._publish_status(goal.goal_id, state, stamp, reason)
        self._changed.notify_all()
        return True

    def _take_next(self) -> ServerGoal | None:
        """The next waiting goal, now Executing (lock held); None while one runs."""
        if self._executing is not None and not self._executing.done:
            return None
        self._executing = None
        while self._waiting:
            goal = self._waiting.popleft()
            if goal.done:
                continue
            self._executing = goal
            if goal._state == GoalState.Accepted:
                goal._state = GoalState.Executing
                self._publish_status(goal.goal_id, GoalState.Executing, _stamp_ns(), "")
            return goal
        return None

    def next_goal(self) -> ServerGoal | None:
        """Tick mode: the next goal to run (now Executing), or None when none waits or the last
        one handed out has not ended yet. Never blocks."""
        if self._execute is not None:
            raise RuntimeError(f"the ActionServer of {self.action.name} runs its goals with "
                               "execute=...: next_goal() is for a server made without it")
        with self._lock:
            return self._take_next()

    def _run_executor(self) -> None:
        while True:
            with self._changed:
                goal = None
                while not self._stopping.is_set():
                    goal = self._take_next()
                    if goal is not None:
                        break
                    self._changed.wait(0.1)
                if goal is None:
                    return
            self._run_goal(goal)

    def _run_goal(self, goal: ServerGoal) -> None:
        try:
            if self._loop is not None:
                returned = asyncio.run_coroutine_threadsafe(self._execute(goal),
                                                            self._loop).result()
            else:
                returned = self._execute(goal)
        except Exception as failure:  # noqa: BLE001 - the goal ends, the server goes on
            goal.abort(f"execute raised: {type(failure).__name__}: {failure}")
            return
        if goal.done:
            return
        if returned is None:
            goal.abort(_RETURNED)
        elif isinstance(returned, self.action.Result):
            goal.succeed(returned)
        else:
            goal.abort(f"execute returned a {type(returned).__name__}, not a "
                       f"{self.action.Result.__name__} or None")

    def _check_clients(self) -> None:
        """Goals whose client process exited: a waiting one is Canceled, the executing one asked
        to cancel, so the next client is served."""
        with self._changed:
            for goal in list(self._live.values()):
                pid = goal._caller_id >> 32
                if not pid or not _core.service_server_gone(pid):
                    continue
                reason = f"the client (pid {pid}) exited"
                if goal in self._waiting:
                    self._waiting.remove(goal)
                    self._end_locked(goal, GoalState.Canceled, reason, None)
                elif goal._state != GoalState.Canceling:
                    self._request_cancel(goal, reason)

    # -- the server as a whole ---------------------------------------------------------------

    @property
    def stats(self) -> ActionServerStats:
        with self._lock:
            return dataclasses.replace(self._stats)

    @property
    def running(self) -> bool:
        return not self._stopping.is_set()

    def stop(self) -> None:
        """Aborts the live goals ("the action server stopped"), stops the service threads and the
        executor (an execute still running finds its goal ended) and withdraws the
        registrations."""
        if self._stopping.is_set():
            return
        self._stopping.set()
        for raw in self._servers:
            raw.stop()
        with self._changed:
            self._waiting.clear()
            for goal in list(self._live.values()):
                goal._cancel_requested = True
                goal._cancel_reason = _STOPPED
                self._end_locked(goal, GoalState.Aborted, _STOPPED, None)
        current = threading.current_thread()
        # The executor first: an async execute still needs the loop to finish.
        for thread in [self._executor_thread, *self._service_threads]:
            if thread is not None and thread is not current:
                thread.join()
        if self._loop is not None:
            self._loop.call_soon_threadsafe(self._loop.stop)
            if self._loop_thread is not current:
                self._loop_thread.join()
                self._loop.close()
        for raw in self._servers:
            raw.withdraw()

    def __enter__(self) -> "ActionServer":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

