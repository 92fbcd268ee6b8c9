"""horus.Network: topics across hosts from inside a scheduler's process (docs/dds-bridge.md).

The C++ DDS bridge (horus._core.dds.DdsBridge, bridges/dds/) carries the topics, services, ROS 2
twins and coordinate frames (as ROS 2's /tf and /tf_static) on threads of its own; serve() is its
run, here on a thread of this process for the scheduler's lifetime, and in `horus bridge` (which
runs it on its main thread).
"""
from __future__ import annotations

import importlib
import sys
import threading

from . import _core

RESCAN_S = 0.5  # how often serve() looks whether the bridge stopped on its own


def _type_description(type_name: str) -> bytes | None:
    """A generated class's type description by its HORUS name, from the Python path (horus.msg,
    a user package): how the bridge learns an exported service's response type before a local
    call showed it."""
    package, _, short = type_name.rpartition(".")
    try:
        meta = getattr(importlib.import_module(package), short).__horus__
    except (ImportError, AttributeError, ValueError):
        return None
    return meta.description


def _patterns(value, what: str, names: str = "topic name") -> list[str]:
    if isinstance(value, str) or not all(isinstance(item, str) for item in value):
        raise TypeError(f"{what} takes a list of {names} patterns, got {value!r}")
    return list(value)


class Network:
    """What a scheduler carries to and from DDS, as `horus bridge` does: local topics whose name
    matches an `export` pattern go to DDS, DDS topics matching an `import_` pattern come in.

    Keywords as the command's options: domain, reliable (else best effort), depth,
    transient_local (patterns of latched topics), deadlines ({pattern: milliseconds}),
    export_services and import_services (service name patterns), service_timeout (seconds an
    exported service's server has to answer), ros2_types (patterns of topics that cross as their
    standard type's ROS 2 twin, --ros2-types), accept_untyped_writers (import from DDS writers
    that announce no type information, --accept-untyped-writers), export_frames and
    import_frames (patterns of child frames of the namespace's frame tree written to and read
    from DDS as ROS 2's /tf and /tf_static, --export-frames, --import-frames), export_actions
    (patterns of local actions served to ROS 2 action clients, --export-action), import_actions
    (patterns of ROS 2 action servers on DDS offered to local action clients, --import-action).
    """

    def __init__(self, export=(), import_=(), domain: int = 0, reliable: bool = True,
                 depth: int = 100, transient_local=(), deadlines: dict | None = None,
                 export_services=(), import_services=(), service_timeout: float = 10.0,
                 ros2_types=(), accept_untyped_writers: bool = False, export_frames=(),
                 import_frames=(), export_actions=(), import_actions=()) -> None:
        self.export = _patterns(export, "export")
        self.import_ = _patterns(import_, "import_")
        self.export_services = _patterns(export_services, "export_services")
        self.import_services = _patterns(import_services, "import_services")
        self.transient_local = _patterns(transient_local, "transient_local")
        self.ros2_types = _patterns(ros2_types, "ros2_types")
        self.export_frames = _patterns(export_frames, "export_frames", "child frame")
        self.import_frames = _patterns(import_frames, "import_frames", "child frame")
        self.export_actions = _patterns(export_actions, "export_actions", "action")
        self.import_actions = _patterns(import_actions, "import_actions", "action")
        if not (self.export or self.import_ or self.export_services or self.import_services
                or self.export_frames or self.import_frames or self.export_actions
                or self.import_actions):
            raise ValueError("a Network carries nothing: give export and/or import_ patterns "
                             "(or export_services, import_services, export_frames, "
                             "import_frames, export_actions, import_actions)")
        if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
            raise ValueError(f"domain must be a DDS domain id (0..232), got {domain!r}")
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
            raise ValueError(f"depth must be a whole number >= 1, got {depth!r}")
        self.deadlines = dict(deadlines or {})
        for pattern, milliseconds in self.deadlines.items():
            if isinstance(milliseconds, bool) or not isinstance(milliseconds, int) \
                    or milliseconds < 1:
                raise ValueError(f"the deadline of {pattern!r} must be a whole number of "
                                 f"milliseconds >= 1, got {milliseconds!r}")
        if isinstance(service_timeout, bool) or not isinstance(service_timeout, (int, float)) \
                or not service_timeout > 0:
            raise ValueError(f"service_timeout must be a number of seconds > 0, got "
                             f"{service_timeout!r}")
        self.domain, self.reliable, self.depth = domain, bool(reliable), depth
        self.service_timeout = float(service_timeout)
        self.accept_untyped_writers = bool(accept_untyped_writers)
        self._stopping: threading.Event | None = None
        self._thread: threading.Thread | None = None
        self.status = 0  # 1 once the bridge stopped on an error of its own (said on stderr)

    def serve(self, stop: threading.Event, namespace: str = "") -> int:
        """Runs the bridge in `namespace` (empty: the current one) until `stop` is set (0), or
        until it stops on an error of its own (1, said on stderr): says its first line, then
        the bridge says each topic and service it carries. RuntimeError when it cannot start."""
        try:
            from ._core import dds as _dds
        except ImportError:
            raise RuntimeError("the DDS bridge needs horus._core.dds: this horus was built "
                               "without Cyclone DDS (Debian: cyclonedds-dev)") from None
        # One write, line and newline together: under PYTHONUNBUFFERED print() writes them
        # apart, and a line of another thread could land between.
        sys.stdout.write(f"bridge on DDS domain {self.domain}: exporting "
                         f"{self.export or 'nothing'}, importing {self.import_ or 'nothing'}; "
                         f"services: exporting {self.export_services or 'nothing'}, importing "
                         f"{self.import_services or 'nothing'}"
                         + (f"; frames: exporting {self.export_frames or 'nothing'}, importing "
                            f"{self.import_frames or 'nothing'}"
                            if self.export_frames or self.import_frames else "")
                         + (f"; actions: exporting {self.export_actions or 'nothing'}, importing "
                            f"{self.import_actions or 'nothing'}"
                            if self.export_actions or self.import_actions else "") + "\n")
        sys.stdout.flush()
        bridge = _dds.DdsBridge(
            namespace, self.export, self.import_, self.domain, self.reliable, self.depth,
            self.transient_local, list(self.deadlines.items()), self.accept_untyped_writers,
            self.ros2_types, export_services=self.export_services,
            import_services=self.import_services, service_timeout=self.service_timeout,
            find_type=_type_description, export_frames=self.export_frames,
            import_frames=self.import_frames, export_actions=self.export_actions,
            import_actions=self.import_actions)
        try:
            while not stop.is_set() and bridge.broken is None:
                stop.wait(RESCAN_S)
        finally:
            bridge.stop()
        return 0 if bridge.broken is None else 1  # the bridge said why

    def _start(self, on_failure) -> None:
        """Starts the bridge's thread; `on_failure()` runs if the bridge stops on its own."""
        if not hasattr(_core, "dds"):
            raise RuntimeError("horus.Network needs horus._core.dds: this horus was built without "
                               "Cyclone DDS (Debian: cyclonedds-dev)")
        self._stopping = threading.Event()

        def serve() -> None:
            self.status = self.serve(self._stopping)
            if self.status != 0:
                on_failure()

        self._thread = threading.Thread(target=serve, name="horus network", daemon=True)
        self._thread.start()

    def _stop(self, wait: bool) -> None:
        """Ends the bridge (its topics and services leave DDS); `wait`: until it has."""
        if self._stopping is not None:
            self._stopping.set()
        if wait and self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
