"""horus.Node: seed 001's node, configured by keyword arguments (or subclassed, seed 000's shape)."""
from __future__ import annotations

import asyncio
import functools
import inspect
import weakref

from . import _core
from ._core import ParamError
from ._params import ParamChange, ParamValues, ParamVerdict, make_param
from ._pool import is_pool_type
from ._topic import Topic
from ._values import plain_value_of, python_spelling

_MISS_POLICIES = ("warn", "skip", "safe_mode", "stop")
_FAILURE_POLICIES = ("fatal", "restart", "skip", "ignore")


def _topic_map(topics, what: str) -> dict:
    """`subs` / `pubs` as {name: type}: a list of names means dict messages."""
    if topics is None:
        return {}
    if isinstance(topics, str):
        raise TypeError(f"{what} takes a list of topic names or a mapping name -> type, "
                        f"not the string {topics!r}")
    if isinstance(topics, dict):
        return dict(topics)
    return {name: dict for name in topics}


def _seconds(value, what: str):
    if value is None:
        return None
    value = float(value)
    if not value >= 0.0 or value == float("inf"):
        raise ValueError(f"{what} must be a finite number of seconds >= 0, got {value!r}")
    return value


class Node:
    """A unit of work the scheduler runs: `init` once, `tick` at its rate, `shutdown` once.

    Callbacks take the node (`def tick(node): ...`); a subclass may instead override `init`,
    `tick` and `shutdown` as methods. Budgets, deadlines and watchdogs are seconds (`300 * us`).
    Parameters are declared with `declare_param` and read as `node.params.NAME`; a write is
    offered to `on_param_change` first (a method, or `on_param_change=fn(node, change)`).
    """

    # Slots of the topics this node creates, by topic name (default 64); the classes horus-gen
    # generates from .hnode files set it from their #[capacity] attributes.
    topic_capacities: dict[str, int] = {}

    def __init__(self, name: str | None = None, tick=None, init=None, shutdown=None,
                 rate: float | None = None, order: int = 100, budget: float | None = None,
                 deadline: float | None = None, on_miss: str | None = None,
                 failure_policy: str | None = None, compute: bool = False, on: str | None = None,
                 priority: int | None = None, core: int | None = None,
                 watchdog: float | None = None, subs=None, pubs=None,
                 on_param_change=None) -> None:
        self.name = name if name is not None else type(self).__name__
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"a node name must be a non-empty string, got {self.name!r}")
        for label, fn in (("tick", tick), ("init", init), ("shutdown", shutdown),
                          ("on_param_change", on_param_change)):
            if fn is not None and not callable(fn):
                raise TypeError(f"node '{self.name}': {label} must be callable, got {fn!r}")
        if on_miss is not None and on_miss not in _MISS_POLICIES:
            raise ValueError(f"node '{self.name}': on_miss must be one of {_MISS_POLICIES}, "
                             f"got {on_miss!r}")
        if failure_policy is not None and failure_policy not in _FAILURE_POLICIES:
            raise ValueError(f"node '{self.name}': failure_policy must be one of "
                             f"{_FAILURE_POLICIES}, got {failure_policy!r}")
        if rate is not None and not float(rate) > 0.0:
            raise ValueError(f"node '{self.name}': rate must be > 0 Hz, got {rate!r}")
        self._tick_fn = tick
        self._init_fn = init
        self._shutdown_fn = shutdown
        self._on_param_change_fn = on_param_change
        self._params: dict = {}
        self.params = ParamValues(self.name, self._params)
        self.rate = None if rate is None else float(rate)
        self.order = int(order)
        self.budget = _seconds(budget, f"node '{self.name}': budget")
        self.deadline = _seconds(deadline, f"node '{self.name}': deadline")
        self.watchdog = _seconds(watchdog, f"node '{self.name}': watchdog")
        self.on_miss = on_miss
        self.failure_policy = failure_policy
        self.compute = bool(compute)
        self.on = on
        self.priority = priority
        self.core = core
        self.subs = _topic_map(subs, "subs")
        self.pubs = _topic_map(pubs, "pubs")
        if on is not None and on not in self.subs:
            self.subs[on] = dict
        self.is_async = inspect.iscoroutinefunction(self._tick_callable())
        self._topics: dict[str, Topic] = {}
        self._loop = None
        self._scheduler = None
        self._stop = None  # request_stop() of the C++ node, once added to a scheduler

    # -- what the scheduler calls --------------------------------------------------------------

    def _tick_callable(self):
        if type(self).tick is not Node.tick:
            return self.tick
        return self._tick_fn

    def _core_node(self) -> _core.PyNode:
        """The C++ node the scheduler runs; its callbacks are bound once, here."""
        tick = self._tick_callable()
        if tick is None:
            raise ValueError(f"node '{self.name}' has no tick: pass tick= or override tick()")
        if self.is_async:
            tick = self._tick_async
        elif type(self).tick is Node.tick:
            tick = _bind(self._tick_fn, self)
        init = self.init if type(self).init is not Node.init else _bind(self._init_fn, self)
        shutdown = self._shutdown
        safe = getattr(self, "enter_safe_state", None)
        is_safe = getattr(self, "is_safe_state", None)
        node = _core.PyNode(self.name, (_with_topics(self, init), tick, shutdown, safe, is_safe,
                                        self._param_change if self._params else None),
                            [(t, _type_name(c)) for t, c in self.pubs.items()],
                            [(t, _type_name(c)) for t, c in self.subs.items()])
        for param in self._params.values():
            param._declare(node)
        # Weak: the C++ node's callbacks hold this node, so holding it back would be a cycle
        # through C++ that the garbage collector cannot see.
        self._stop = node.stop_handle()
        return node

    def _tick_async(self) -> None:
        if self._loop is None:
            self._loop = asyncio.new_event_loop()
        overridden = type(self).tick is not Node.tick
        coro = self.tick() if overridden else self._tick_fn(self)
        self._loop.run_until_complete(coro)

    def _shutdown(self) -> None:
        try:
            if type(self).shutdown is not Node.shutdown:
                self.shutdown()
            elif self._shutdown_fn is not None:
                self._shutdown_fn(self)
        finally:
            if self._loop is not None:
                self._loop.close()
                self._loop = None

    def _param_change(self, name: str, value: bytes, source: str):
        """What the C++ node asks between two ticks (never beside another call of the node): None
        (accept) or (accepted, reason)."""
        change = ParamChange(name, self._params[name]._value_of(value), source)
        if type(self).on_param_change is not Node.on_param_change:
            verdict = self.on_param_change(change)
        elif self._on_param_change_fn is not None:
            verdict = self._on_param_change_fn(self, change)
        else:
            return None
        if verdict is None:
            return None
        if not isinstance(verdict, ParamVerdict):
            raise TypeError(f"node '{self.name}': on_param_change returns ParamVerdict.accept(), "
                            f"ParamVerdict.refuse(reason) or None, not {verdict!r}")
        return (verdict.accepted, verdict.reason)

    # -- parameters ---------------------------------------------------------------------------

    def declare_param(self, name: str, default, *, type=None, min: float | None = None,
                      max: float | None = None, choices=None, unit: str = "", doc: str = "",
                      read_only: bool = False):
        """Declares a parameter (in __init__, before a scheduler adds the node) and returns its
        horus.Param; `node.params.NAME` reads it. `type` is a schema spelling ("f32", "[f64; 3]",
        "String"), a generated IntEnum class, or None to infer it from the default (bool, int ->
        i64, float -> f64, str -> String, an enum member, a list of numbers -> [f64; N] or
        [i64; N] when all are ints, a list of bools -> [bool; N]).
        `min`/`max` bound a number (each element of an array), `choices` lists the only values
        allowed. Raises ParamError for a bad declaration (name, duplicate, a default outside its
        own range or choices, over 256 bytes), TypeError for a type it cannot tell."""
        if self._stop is not None:
            raise ParamError(f"node '{self.name}': parameter '{name}' is declared after a "
                             "scheduler added the node (declare parameters in __init__)")
        if name in self._params:
            raise ParamError(f"node '{self.name}' declares parameter '{name}' twice")
        param = make_param(name, default, type, min, max, choices, unit, doc, read_only)
        self._params[name] = param
        return param

    # -- overridable callbacks (subclass style) ------------------------------------------------

    def on_param_change(self, change: ParamChange):
        """Offered every write of one of this node's parameters between two ticks, never during
        init(), tick() or shutdown() nor beside another call of the node (on the node's thread,
        or on the parameter service's while the node's thread sleeps); return
        ParamVerdict.refuse(reason) to refuse it (None accepts)."""
        return None

    def init(self) -> None:
        """Called once when the scheduler starts (lazily, in order)."""

    def tick(self) -> None:
        """Called at the node's rate."""

    def shutdown(self) -> None:
        """Called once at stop, in reverse order of the nodes."""

    # -- topics ---------------------------------------------------------------------------------

    def _topic(self, name: str, role: str = "subs") -> Topic:
        topic = self._topics.get(name)
        if topic is None:
            msg_type = self.subs.get(name, self.pubs.get(name, dict))
            capacity = self.topic_capacities.get(name)
            try:
                topic = (Topic(msg_type, name) if capacity is None
                         else Topic(msg_type, name, capacity=capacity))
            except _core.HorusError as error:
                if msg_type is not dict:
                    raise
                hint = _typed_declaration(name, "subs" if name in self.subs else
                                          "pubs" if name in self.pubs else role)
                if hint is None:
                    raise
                raise _core.HorusError(f"node '{self.name}': {hint} ({error})") from None
            self._topics[name] = topic
        return topic

    def _close_topics(self) -> None:
        """Lets go of the topics this node opened (a later use opens them again)."""
        self._topics.clear()

    def open_topics(self) -> None:
        """Opens every declared topic now (the scheduler does it before init())."""
        for name in {**self.subs, **self.pubs}:
            self._topic(name)

    def send(self, topic: str, msg) -> bool:
        """Publishes `msg` on `topic` (a generated message, or a plain value on a dict topic)."""
        return self._topic(topic, "pubs").send(msg)

    def recv(self, topic: str):
        """The next message on `topic`, or None."""
        return self._topic(topic).try_recv()

    def has_msg(self, topic: str) -> bool:
        return self._topic(topic).has_msg()

    def request_stop(self) -> None:
        """Asks the scheduler running this node to stop (as Ctrl+C would); safe from any thread.
        A node no scheduler holds ignores it."""
        if self._stop is not None:
            self._stop.request_stop()

    # -- logging (only inside init / tick / shutdown; dropped elsewhere, as the seed says) ------

    # The runtime's log (stderr and the namespace's shared-memory ring), in this node's name.
    def _log(self, level: str, message: str) -> None:
        if _core.in_callback():
            _core.log(level, self.name, str(message))

    def log_info(self, message: str) -> None:
        self._log("info", message)

    def log_warning(self, message: str) -> None:
        self._log("warn", message)

    def log_error(self, message: str) -> None:
        self._log("error", message)

    def log_debug(self, message: str) -> None:
        self._log("debug", message)

    def _attach(self, scheduler) -> None:
        if self._scheduler is not None and self._scheduler() not in (None, scheduler):
            raise ValueError(f"node '{self.name}' is already added to another scheduler")
        self._scheduler = weakref.ref(scheduler)

    def __repr__(self) -> str:
        return f"horus.Node(name={self.name!r}, rate={self.rate}, order={self.order})"


def _bind(fn, node):
    # partial, not a lambda: no extra Python frame on every tick
    return None if fn is None else functools.partial(fn, node)


def _with_topics(node: Node, init):
    def start() -> None:
        node.open_topics()
        if init is not None:
            init()
    return start


def _typed_declaration(topic: str, role: str) -> str | None:
    """For a topic opened as dict values that carries a generated type or a plain value: how to
    declare the type instead, as Python imports or spells it (None when the topic carries none)."""
    found = next((t for t in _core.list_topics() if t["name"] == topic), None)
    type_name = found["type_name"] if found is not None else ""
    if found is not None and found["schema"] == f"value {type_name}\n":
        return (f"topic {topic!r} carries the plain value {type_name}, not dict values: declare "
                f"{role}={{{topic!r}: {python_spelling(type_name)}}}")
    module, _, cls = type_name.rpartition(".")
    if not module or not cls.isidentifier() or type_name == _type_name(dict):
        return None
    return (f"topic {topic!r} carries {type_name}, not dict values: declare "
            f"{role}={{{topic!r}: {cls}}} (from {module} import {cls})")


def _type_name(cls) -> str:
    if cls is dict:
        return "horus.msg.GenericMessage"
    if is_pool_type(cls):  # Image & co. travel as their descriptor type
        return cls.type_name
    plain = plain_value_of(cls)
    return plain.name if plain is not None else cls.__horus__.name
