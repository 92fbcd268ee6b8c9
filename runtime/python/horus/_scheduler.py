"""horus.Scheduler and horus.run: seed 001's scheduler over the C++ one."""
from __future__ import annotations

import os
import sys
import weakref
from pathlib import Path

from . import _core
from ._network import Network
from ._node import Node
from ._view import view_options


class Scheduler:
    """Runs nodes in order at their rates; a context manager that stops on exit.

    Every keyword of seed 001; `seed` sets the deterministic random sequence. `telemetry`
    ("udp://HOST:PORT" or "file:///PATH") exports every node's metrics as JSON each second while
    it runs and once when run() ends. `replay` (with deterministic=True) feeds a recording into
    the nodes' topics, each message before the tick that received it (docs/recording.md).
    `network` (a horus.Network) carries topics to and from other hosts over DDS from this
    process, as `horus bridge` does, from construction until run() returns or the scheduler is
    stopped; if that bridge fails, it stops the scheduler and run() returns 1. `view` (True, a
    port number or a horus.View) serves this scheduler's namespace to Foxglove, Lichtblick and
    the built-in page over the Foxglove WebSocket protocol, from this process, for as long
    (docs/live-view.md); it tells viewers simulated time when deterministic. `name` defaults to
    the program's (the script's file name without .py), so two programs' log lines differ.
    `params` (a YAML parameter file, `node: {name: value}`) sets the nodes' parameters as each
    starts, before init(); a malformed file, an unknown node or parameter, or a value outside its
    declaration stops the start with FILE:LINE and the reason (docs/parameters.md). Without
    `params`, the file named by the environment variable HORUS_PARAMS_FILE is used (`horus
    launch` sets it for a process whose entry gives `params:`).

    Like a C++ scheduler, it leaves nothing in shared memory: when run() returns, when the `with`
    block ends, and when it is dropped (at the latest as the interpreter exits), its nodes'
    topics close and the segments this process created that nobody uses any more are removed.
    """

    def __init__(self, tick_rate: float = 1000.0, rt: bool = False, deterministic: bool = False,
                 blackbox_mb: int = 0, watchdog_ms: float = 0, recording: bool = False,
                 name: str | None = None, cores: list[int] | None = None,
                 max_deadline_misses: int | None = None, verbose: bool = False,
                 telemetry: str | None = None, seed: int | None = None,
                 replay: str | os.PathLike | None = None,
                 network: Network | None = None, view=None,
                 params: str | os.PathLike | None = None) -> None:
        if network is not None and not isinstance(network, Network):
            raise TypeError(f"network takes a horus.Network, got {type(network).__name__}")
        if not float(tick_rate) > 0.0:
            raise ValueError(f"tick_rate must be > 0 Hz, got {tick_rate!r}")
        if watchdog_ms is None or not float(watchdog_ms) >= 0.0:
            raise ValueError(f"watchdog_ms must be >= 0, got {watchdog_ms!r}")
        self._tick_rate = float(tick_rate)
        self._owned = _Owned(_core.Scheduler(
            tick_rate=float(tick_rate), rt=bool(rt), deterministic=bool(deterministic),
            watchdog_ms=float(watchdog_ms), blackbox_mb=int(blackbox_mb),
            name=_program_name() if name is None else name, cores=list(cores or []),
            max_deadline_misses=max_deadline_misses, verbose=bool(verbose), telemetry=telemetry,
            seed=seed, recording=bool(recording),
            replay=None if replay is None else os.fspath(replay), view=view_options(view),
            params=None if params is None else os.fspath(params)))
        # Runs when this scheduler is dropped, or as the interpreter exits (before it finalizes:
        # the nodes' shutdowns still run, and the C++ scheduler takes its presence entry along).
        self._close = weakref.finalize(self, _close, self._owned)
        self._network = network
        if network is not None:
            network._start(on_failure=self.stop)

    # -- building ---------------------------------------------------------------------------

    def add(self, node, **settings) -> "Scheduler":
        """Adds a horus.Node (configured by its own keywords) or a C++ node from an extension
        (configured by `settings`: the Node keywords order, rate, budget, ...). Returns self."""
        if isinstance(node, Node):
            if settings:
                raise TypeError(f"node '{node.name}' carries its own settings; "
                                f"add() takes none, got {sorted(settings)}")
            node._attach(self)
            core_node = node._core_node()
            settings = dict(order=node.order, rate=node.rate, budget=node.budget,
                            deadline=node.deadline, on_miss=node.on_miss,
                            failure_policy=node.failure_policy, compute=node.compute,
                            on=node.on, async_io=node.is_async, priority=node.priority,
                            core=node.core, watchdog=node.watchdog)
        elif isinstance(node, _core.Node):
            core_node = node
            settings = _cpp_settings(node.name, settings)
        else:
            raise TypeError(f"add() takes a horus.Node or a C++ node, got {type(node).__name__}")
        self._core.add(core_node, **settings)
        self._owned.nodes[core_node.name] = node
        return self

    def add_critical_node(self, name: str, timeout_ms: float) -> "Scheduler":
        """Marks `name` safety-critical with its own watchdog timeout."""
        self._core.add_critical_node(name, float(timeout_ms) * 1e-3)
        return self

    # -- running ----------------------------------------------------------------------------

    def run(self, duration: float | None = None) -> int:
        """Runs until stop(), Ctrl+C, SIGTERM, a node's request_stop() or `duration` seconds;
        shuts the nodes down in reverse order. 0, or 1 when a failure stopped it (a node's, or
        every node's init() failing: with no node left, it does not idle)."""
        try:
            status = self._core.run() if duration is None else self._core.run_for(float(duration))
        finally:
            if self._network is not None:
                self._network._stop(wait=True)
        self._owned.release_topics()  # the nodes are shut down, and a scheduler runs once
        return status or (self._network.status if self._network is not None else 0)

    def tick_once(self, names: list[str] | None = None) -> None:
        """One cycle on this thread (only the named nodes, when given)."""
        self._core.tick_once(None if names is None else list(names))

    def tick_for(self, seconds: float, names: list[str] | None = None) -> None:
        """Runs the loop for `seconds` (only the named nodes, when given) without shutting down."""
        self._core.tick_for(float(seconds), list(names or []))

    def stop(self) -> None:
        self._core.stop()
        if self._network is not None:
            self._network._stop(wait=False)

    def __enter__(self) -> "Scheduler":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
        if self._network is not None:
            self._network._stop(wait=True)
        if not self._core.is_running():  # a run() on another thread is still shutting down
            self._owned.release_topics()

    @property
    def _core(self) -> _core.Scheduler:
        core = self._owned.core
        if core is None:
            raise _core.HorusError("this scheduler was closed as the interpreter exited")
        return core

    # -- runtime changes --------------------------------------------------------------------

    def set_node_rate(self, name: str, rate: float) -> bool:
        return self._core.set_node_rate(name, float(rate))

    def set_tick_budget(self, name: str, budget_us: float) -> bool:
        """Microseconds, as seed 001 has it (unlike Node(budget=...), in seconds):
        set_tick_budget("motor", 500) allows 500 us per tick."""
        return self._core.set_tick_budget(name, float(budget_us) * 1e-6)

    def remove_node(self, name: str) -> bool:
        removed = self._core.remove_node(name)
        self._owned.nodes.pop(name, None)
        return removed

    # -- introspection ----------------------------------------------------------------------

    def status(self) -> str:
        """"idle", "running" or "stopped"."""
        return self._core.status()

    def current_tick(self) -> int:
        return self._core.current_tick()

    def is_running(self) -> bool:
        return self._core.is_running()

    def scheduler_name(self) -> str:
        return self._core.name()

    def get_node_count(self) -> int:
        return self._core.node_count()

    def get_node_names(self) -> list[str]:
        return self._core.node_names()

    def has_node(self, name: str) -> bool:
        return self._core.has_node(name)

    def get_node_info(self, name: str) -> int | None:
        """The node's execution order, or None for an unknown node."""
        info = self._core.node_info(name)
        return None if info is None else info["order"]

    def get_all_nodes(self) -> list[dict]:
        """Every node's name, order, state, execution class, rate, budget, ... as dicts."""
        return self._core.nodes()

    def get_node_stats(self, name: str) -> dict | None:
        """The node's priority (None when unset), tick counts, durations (seconds), misses and
        restarts."""
        return self._core.node_metrics(name)

    def safety_stats(self) -> dict:
        return self._core.safety_stats()

    def timing_report(self) -> str:
        return self._core.timing_report()

    def stop_reason(self) -> str:
        return self._core.stop_reason()

    def has_full_rt(self) -> bool:
        return self._core.has_full_rt()

    def degradations(self) -> list[str]:
        return self._core.degradations()

    def capabilities(self) -> dict:
        return self._core.capabilities()

    def dump_blackbox(self, path: str) -> None:
        self._core.dump_blackbox(str(path))

    # -- recording (docs/recording.md) -------------------------------------------------------

    def is_recording(self) -> bool:
        """Whether a session is being recorded: from the first run()/tick_once() of a
        Scheduler(recording=True) until stop_recording()."""
        return self._core.is_recording()

    def stop_recording(self) -> list[str]:
        """Finishes the session file and returns its path (an empty list when nothing was
        recording)."""
        return self._core.stop_recording()

    def list_recordings(self) -> list[str]:
        """The session names in $HORUS_RECORDINGS (default ~/.local/share/horus/recordings)."""
        return self._core.list_recordings()

    def delete_recording(self, session: str) -> bool:
        """Removes a session file by name; whether it existed."""
        return self._core.delete_recording(session)


class _Owned:
    """What a Scheduler owns that must not outlive it: the C++ scheduler and the nodes, whose
    topics it closes (kept apart from the Scheduler so that its finalizer can hold them)."""

    def __init__(self, core: _core.Scheduler) -> None:
        self.core: _core.Scheduler | None = core
        self.nodes: dict[str, object] = {}

    def release_topics(self) -> None:
        """Closes the Python nodes' topics (a later use opens them again), then removes the
        segments this process created that nobody has open any more."""
        for node in self.nodes.values():
            if isinstance(node, Node):
                node._close_topics()
        _core.remove_created_topics_nobody_uses()


def _close(owned: _Owned) -> None:
    core = owned.core
    if core.is_running():
        # A loop on a thread the interpreter does not wait for (a daemon thread): destroying the
        # scheduler under it would crash the process.
        core.stop()
        return
    owned.core = None
    del core  # shuts down the nodes init() started; C++ nodes' topics and its presence entry go
    owned.release_topics()


def _program_name() -> str | None:
    """The running script's name ("agv" for agv.py, the package for `python -m package`); None
    when Python runs no file (-c, a REPL), and the C++ scheduler's default applies."""
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if not path:
        return None
    path = Path(path)
    return (path.parent.name if path.stem == "__main__" else path.stem) or None


_CPP_DEFAULTS = dict(order=100, rate=None, budget=None, deadline=None, on_miss=None,
                     failure_policy=None, compute=False, on=None, async_io=False, priority=None,
                     core=None, watchdog=None)


def _cpp_settings(name: str, settings: dict) -> dict:
    unknown = set(settings) - set(_CPP_DEFAULTS)
    if unknown:
        raise TypeError(f"node '{name}': unknown settings {sorted(unknown)}")
    return {**_CPP_DEFAULTS, **settings}


def run(*nodes, duration: float | None = None, tick_rate: float = 1000.0, rt: bool = False,
        deterministic: bool = False, blackbox_mb: int = 0, watchdog_ms: float = 0,
        recording: bool = False, name: str | None = None, cores: list[int] | None = None,
        max_deadline_misses: int | None = None, verbose: bool = False,
        telemetry: str | None = None, network: Network | None = None, view=None,
        params: str | os.PathLike | None = None) -> int:
    """Builds a Scheduler with these keywords, adds `nodes` and runs it (forever, or for
    `duration` seconds) until Ctrl+C, SIGTERM or a stop."""
    sched = Scheduler(tick_rate=tick_rate, rt=rt, deterministic=deterministic,
                      blackbox_mb=blackbox_mb, watchdog_ms=watchdog_ms, recording=recording,
                      name=name, cores=cores, max_deadline_misses=max_deadline_misses,
                      verbose=verbose, telemetry=telemetry, network=network, view=view,
                      params=params)
    try:
        for node in nodes:
            sched.add(node)
        return sched.run(duration)
    finally:
        sched._close()
