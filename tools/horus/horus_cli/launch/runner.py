"""Running a launch Plan: processes started in dependency order, restarted by their policy, their
output prefixed and logged, controlled from other terminals, stopped in reverse start order, and
never left behind.

One thread, one loop: a selector over the processes' output pipes, the control socket and the
signal wake-up pipe, with a short tick for what has no descriptor (ended processes, dependencies
not met yet, backoff delays, stop timeouts).

How nothing is left behind (docs/launch.md, "No orphans"):
- every process leads a process group of its own, which its children join; a stop signals the
  whole group, and a group still there after its leader ended is stopped as well;
- the launcher is a child subreaper (PR_SET_CHILD_SUBREAPER): the orphans of its processes are
  reparented to it, reaped by it, and stopped at the end with the rest;
- the guardian (guardian.py), forked before anything starts, does the shutdown when the launcher
  ends without doing it (SIGKILL included), learning of each group from the process itself;
- at the end, `horus shm clean`'s clean-up runs in every namespace the processes used: what a
  killed process held, and what a restarted process's predecessor made, once nobody uses it.
"""
from __future__ import annotations

import ctypes
import errno
import json
import os
import selectors
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field

from horus_cli.common import CommandFailed
from horus_cli.launch import control
from horus_cli.launch.groups import adopted_children, group_alive
from horus_cli.launch.guardian import EXIT_LINE, end_line, start_guardian, start_line

# Exit statuses of `horus launch`: what happened (128 + the signal that stopped it, as shells say).
EXIT_DONE = 0        # every process ended with status 0, or `horus launch stop` stopped it
EXIT_FAILED = 1      # a process failed (given up on, a required one ended), a dependency timed out
SIGNAL_EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129}

# A `process` dependency is met once the process announced itself in its namespace (a HORUS
# program) or ran this long (any program).
PROCESS_SETTLE_S = 0.5
# A run this long counts as steady: the restarts after it start a new series (the first delay and
# the whole limit again), so a process that fails once a day is not given up on after a week.
STEADY_RUN_S = 10.0
TICK_S = 0.05
# Output without a newline this long is shown as a line of its own, not held without bound.
MAX_LINE_BYTES = 64 * 1024
DEPENDENCY_POLL_S = 0.1

PR_SET_CHILD_SUBREAPER = 36

# Prefix colours on a terminal, one a process in plan order (cyan, green, yellow, magenta, blue and
# their bright kin).
COLOURS = (36, 32, 33, 35, 34, 96, 92, 93, 95, 94)

# A process's states, as `horus launch status` shows them.
WAITING, RUNNING, BACKOFF, STOPPING, STOPPED, EXITED, FAILED = (
    "waiting", "running", "backoff", "stopping", "stopped", "exited", "failed")


def default_log_dir(name: str) -> str:
    """~/.local/state/horus/launch/<name>/<UTC start time> ($XDG_STATE_HOME first)."""
    state = os.environ.get("XDG_STATE_HOME") or os.path.expanduser("~/.local/state")
    folder = os.path.join(state, "horus", "launch", name,
                          time.strftime("%Y%m%dT%H%M%SZ", time.gmtime()))
    return folder + f"-{os.getpid()}" if os.path.exists(folder) else folder


def describe_end(code: int) -> str:
    """An exit status as people read it: "exit 3", or the signal's name."""
    if code >= 0:
        return f"exit {code}"
    try:
        return signal.Signals(-code).name
    except ValueError:
        return f"signal {-code}"


def _set_child_subreaper() -> None:
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
    except (OSError, AttributeError):
        pass  # not Linux: the process groups and the guardian still hold


def _horus_package_folder() -> str:
    """The folder holding the horus package this launcher imports."""
    import horus
    return os.path.dirname(os.path.dirname(os.path.abspath(horus.__file__)))


@dataclass
class Child:
    """A process of the plan and what happened to it."""
    spec: object                          # plan.ProcessSpec
    env: dict
    namespace: str                        # the namespace it runs in (resolved)
    shm_dir: str                          # its HORUS_SHM_DIR ("" for the default root)
    colour: int
    state: str = WAITING
    pid: int | None = None                # of the current run; its process group's id too
    pgid: int | None = None               # of the last run (its group may outlive it)
    started_at: float = 0.0               # monotonic, of the current run
    ever_started: bool = False
    dependency_met: bool = False          # as a `process` dependency of others
    waiting_since: float | None = None    # when its dependencies' clocks started
    restarts: int = 0                     # every restart, on failure or asked for
    failures_in_row: int = 0              # restarts since it last ran steadily
    next_start: float = 0.0               # in BACKOFF
    last_end: str = ""
    stop_requested: bool = False          # `horus launch stop NAME`: not restarted
    restart_requested: bool = False       # `horus launch restart NAME`: started again at once
    logs: dict = field(default_factory=dict)   # "stdout"/"stderr" -> open binary file


class Launcher:
    """Runs one plan until it ends; run() returns the exit status."""

    def __init__(self, plan, namespace: str = "", out=None, err=None) -> None:
        self.plan = plan
        self.out = out or sys.stdout
        self.err = err or sys.stderr
        self.colour = os.environ.get("NO_COLOR") is None
        self.width = max([len(spec.name) for spec in plan.processes] or [0])
        self.children: list[Child] = []
        for index, spec in enumerate(plan.processes):
            env = dict(os.environ)
            if namespace:
                env["HORUS_NAMESPACE"] = namespace
            env.update(spec.env)
            # Python children write their lines as they come, not in blocks, into a pipe.
            env.setdefault("PYTHONUNBUFFERED", "1")
            # A Python program imports the horus package this launcher runs, wherever it was
            # installed (a prefix of the user's own is not on Python's own path).
            package = _horus_package_folder()
            env["PYTHONPATH"] = os.pathsep.join(
                [package] + [path for path in env.get("PYTHONPATH", "").split(os.pathsep)
                             if path and path != package])
            self.children.append(Child(spec=spec, env=env,
                                       namespace=env.get("HORUS_NAMESPACE") or "default",
                                       shm_dir=env.get("HORUS_SHM_DIR", ""),
                                       colour=COLOURS[index % len(COLOURS)]))
        self.by_name = {child.spec.name: child for child in self.children}
        self.by_pid: dict[int, Child] = {}
        self.start_order: list[Child] = []
        self.stopping_groups: dict[int, float] = {}   # pgid -> when SIGKILL is due
        self.shutting_down = False
        self.stop_queue: list[Child] = []
        self.exit_status = EXIT_DONE
        self.reason = ""
        self.signals: list[int] = []
        self.selector = selectors.DefaultSelector()
        self.streams: dict[int, tuple[Child, str, bytearray]] = {}
        self.terminal_gone = False
        self.log_dir = plan.log_dir or default_log_dir(plan.name)
        self.launch_log = None
        self.guardian_pid = 0
        self.guardian_fd = -1
        self.started_wall = time.time()
        self._presence_cache: dict = {}

    # ---- the run ------------------------------------------------------------------------------

    def run(self) -> int:
        try:
            os.makedirs(self.log_dir, mode=0o700, exist_ok=True)
        except OSError as error:
            raise CommandFailed(f"cannot create the log folder {self.log_dir}: "
                                f"{error.strerror} (choose another with --log-dir)") from error
        launch_log_path = os.path.join(self.log_dir, "launch.log")
        self.launch_log = open(launch_log_path, "a", encoding="utf-8")
        # First, while this process has no thread and no descriptor the guardian must not hold.
        self.guardian_pid, self.guardian_fd = start_guardian(launch_log_path)
        _set_child_subreaper()
        wake_read, wake_write = os.pipe()
        os.set_blocking(wake_read, False)
        os.set_blocking(wake_write, False)
        previous_wakeup = signal.set_wakeup_fd(wake_write)
        handlers = {signo: signal.signal(signo, self._on_signal)
                    for signo in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGCHLD)}
        self.selector.register(wake_read, selectors.EVENT_READ, "wake")
        server = socket_path = None
        try:
            try:
                server, socket_path = control.listen(self.plan.name)
                self.selector.register(server, selectors.EVENT_READ, "control")
            except (control.ControlError, OSError) as error:
                self._event(f"no control from other terminals: {error}")
            self._event(f"{self.plan.name}: {len(self.children)} process"
                        f"{'es' if len(self.children) != 1 else ''}, logs in {self.log_dir}"
                        + (f"; see it with `horus launch status {self.plan.name}`"
                           if server is not None else ""))
            self._loop()
        finally:
            for signo, handler in handlers.items():
                signal.signal(signo, handler)
            signal.set_wakeup_fd(previous_wakeup)
            if server is not None:
                self.selector.unregister(server)
                server.close()
                try:
                    os.unlink(socket_path)
                except OSError:
                    pass
            self._finish_guardian()
            for child in self.children:
                for log in child.logs.values():
                    log.close()
            self.selector.close()
            os.close(wake_read)
            os.close(wake_write)
        self._event(f"ended ({self.reason}): exit status {self.exit_status}")
        self.launch_log.close()
        return self.exit_status

    def _loop(self) -> None:
        last_dependency_check = 0.0
        while True:
            for key, _ in self.selector.select(TICK_S):
                if key.data == "wake":
                    self._drain_wakeups(key.fd)
                elif key.data == "control":
                    self._serve(key.fileobj)
                else:
                    self._read_output(key.fd)
            arrived, self.signals = self.signals, []
            for signo in arrived:
                self._handle_signal(signo)
            self._reap()
            now = time.monotonic()
            self._watch_stopping_groups(now)
            if self.shutting_down:
                if self._shutdown_step():
                    self._stop_adopted()
                    self._drain_output()
                    self._clean_namespaces()
                    return
                continue
            if now - last_dependency_check >= DEPENDENCY_POLL_S:
                last_dependency_check = now
                self._presence_cache.clear()
                self._start_ready(now)
            self._restart_due(now)
            if all(child.state in (EXITED, FAILED) for child in self.children):
                failed = [c.spec.name for c in self.children if c.state == FAILED]
                self.exit_status = EXIT_FAILED if failed else EXIT_DONE
                self.reason = (f"every process ended; failed: {', '.join(failed)}" if failed
                               else "every process ended")
                self.shutting_down = True

    # ---- starting -----------------------------------------------------------------------------

    def _start_ready(self, now: float) -> None:
        """Starts each waiting process whose dependencies are met; fails the launch on one whose
        dependency cannot be met any more or timed out."""
        for child in self.children:
            if child.state != WAITING or self.shutting_down:
                continue
            dependencies = child.spec.depends_on
            processes = [self.by_name[d.name] for d in dependencies if d.kind == "process"]
            for other in processes:
                if other.state in (FAILED, STOPPED) and not other.dependency_met:
                    self._shutdown(
                        f"{child.spec.name} ({child.spec.where}) cannot start: it depends on "
                        f"{other.spec.name}, which {other.state} ({other.last_end or 'never ran'})",
                        EXIT_FAILED)
                    return
            if child.waiting_since is None:
                if not all(other.ever_started for other in processes):
                    continue  # their own dependencies hold them; this one's clocks wait
                child.waiting_since = now
            unmet = [d for d in dependencies if not self._met(child, d, now)]
            if not unmet:
                self._start(child)
                continue
            for dependency in unmet:
                if now - child.waiting_since > dependency.timeout:
                    self._shutdown(
                        f"{child.spec.name} ({dependency.where}): depends_on "
                        f"{dependency.kind} '{dependency.name}' "
                        f"{self._unmet_reason(child, dependency)} after {dependency.timeout:g} s",
                        EXIT_FAILED)
                    return

    def _met(self, child: Child, dependency, now: float) -> bool:
        if dependency.kind == "process":
            other = self.by_name[dependency.name]
            if not other.dependency_met:
                running_long = other.state == RUNNING and now - other.started_at >= PROCESS_SETTLE_S
                other.dependency_met = (running_long or other.state == EXITED or
                                        (other.state == RUNNING and self._announced(other)))
            return other.dependency_met
        names = self._namespace_names(dependency.kind, child)
        return dependency.name in names

    def _unmet_reason(self, child: Child, dependency) -> str:
        if dependency.kind == "process":
            return f"not running ({self.by_name[dependency.name].state})"
        return f"not in namespace '{child.namespace}'"

    def _introspection(self):
        from horus import introspection
        return introspection

    def _with_root(self, child: Child):
        if child.shm_dir:
            os.environ["HORUS_SHM_DIR"] = child.shm_dir
        else:
            os.environ.pop("HORUS_SHM_DIR", None)

    def _namespace_names(self, kind: str, child: Child) -> set:
        """The topics with a live user, or the services with a live server, of the child's
        namespace (asked once a dependency poll)."""
        key = (kind, child.shm_dir, child.namespace)
        if key not in self._presence_cache:
            core = self._introspection()
            self._with_root(child)
            try:
                if kind == "topic":
                    names = {t["name"] for t in core.list_topics(child.namespace)
                             if t["user_pids"]}
                else:
                    names = {s["name"] for s in core.list_services(child.namespace)
                             if s["servers"]}
            except core.HorusError:
                names = set()
            self._presence_cache[key] = names
        return self._presence_cache[key]

    def _announced(self, child: Child) -> bool:
        key = ("presence", child.shm_dir, child.namespace)
        if key not in self._presence_cache:
            try:
                core = self._introspection()
                self._with_root(child)
                self._presence_cache[key] = {entry["pid"] for entry in
                                             core.list_presence(child.namespace)
                                             if entry["alive"]}
            except Exception:  # noqa: BLE001 (not a HORUS program's namespace: the settle time)
                self._presence_cache[key] = set()
        return child.pid in self._presence_cache[key]

    def _start(self, child: Child) -> None:
        spec = child.spec
        for stream in ("stdout", "stderr"):
            if stream not in child.logs:
                child.logs[stream] = open(os.path.join(self.log_dir, f"{spec.name}.{stream}.log"),
                                          "ab")
        out_read, out_write = os.pipe()
        err_read, err_write = os.pipe()
        announce = (self.guardian_fd, spec.stop_timeout, child.shm_dir, child.namespace)

        def tell_the_guardian() -> None:
            # In the child, after setpgid, before exec: a launcher killed right after the fork
            # still leaves the guardian knowing this group.
            fd, stop_timeout, shm_dir, namespace = announce
            try:
                os.write(fd, start_line(os.getpid(), stop_timeout, shm_dir, namespace))
            except OSError:
                pass

        try:
            process = subprocess.Popen(spec.argv, cwd=spec.cwd, env=child.env,
                                       stdin=subprocess.DEVNULL, stdout=out_write,
                                       stderr=err_write, process_group=0,
                                       preexec_fn=tell_the_guardian)
        except (OSError, subprocess.SubprocessError) as error:
            os.close(out_read)
            os.close(err_read)
            child.last_end = "cannot start"
            self._event(f"{spec.name}: cannot start {spec.argv[0]}: "
                        f"{getattr(error, 'strerror', None) or error} ({spec.where})")
            self._ended(child, 127, ran_for=0.0)
            return
        finally:
            os.close(out_write)
            os.close(err_write)
        # Reaped by _reap (waitpid of any child: orphans are reparented here too), not by Popen.
        process.returncode = 0
        child.pid = child.pgid = process.pid
        child.started_at = time.monotonic()
        child.state = RUNNING
        if not child.ever_started:
            child.ever_started = True
            self.start_order.append(child)
        self.by_pid[process.pid] = child
        for fd, stream in ((out_read, "stdout"), (err_read, "stderr")):
            os.set_blocking(fd, False)
            self.streams[fd] = (child, stream, bytearray())
            self.selector.register(fd, selectors.EVENT_READ, stream)
        self._event(f"{spec.name} started (pid {process.pid})"
                    + (f", restart {child.restarts}" if child.restarts else ""))

    def _restart_due(self, now: float) -> None:
        for child in self.children:
            if child.state == BACKOFF and now >= child.next_start:
                self._start(child)

    # ---- ends and restarts --------------------------------------------------------------------

    def _reap(self) -> None:
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            child = self.by_pid.pop(pid, None)
            if child is not None:
                code = os.waitstatus_to_exitcode(status)
                self._leader_ended(child, code)
            elif pid == self.guardian_pid:
                self.guardian_pid = 0
                self._event("the guardian ended: a SIGKILL of this launcher would now leave its "
                            "processes running")
            # else: an adopted orphan of one of the processes, reaped

    def _leader_ended(self, child: Child, code: int) -> None:
        ran_for = time.monotonic() - child.started_at
        child.pid = None
        if group_alive(child.pgid):
            # Its own children outlive it: they end with it.
            if child.pgid not in self.stopping_groups:
                self._signal_group(child.pgid, signal.SIGINT)
                self.stopping_groups[child.pgid] = time.monotonic() + child.spec.stop_timeout
        else:
            self._group_gone(child.pgid)
        child.last_end = describe_end(code)
        self._ended(child, code, ran_for)

    def _ended(self, child: Child, code: int, ran_for: float) -> None:
        """What follows a process's end: its restart, or its final state (and the launch's end
        when it was required)."""
        spec = child.spec
        if self.shutting_down or (child.stop_requested and not child.restart_requested):
            child.state = STOPPED
            self._event(f"{spec.name} stopped ({child.last_end})")
            return
        if child.restart_requested:
            child.restart_requested = child.stop_requested = False
            child.state, child.next_start = BACKOFF, time.monotonic()
            child.restarts += 1
            child.failures_in_row = 0
            self._event(f"{spec.name} stopped ({child.last_end}); restarting as asked")
            return
        failed = code != 0
        if ran_for >= STEADY_RUN_S:
            child.failures_in_row = 0
        wanted = spec.restart == "always" or (spec.restart == "on-failure" and failed)
        if wanted and child.failures_in_row < spec.backoff.limit:
            delay = min(spec.backoff.initial * 2 ** child.failures_in_row, spec.backoff.maximum)
            child.failures_in_row += 1
            child.restarts += 1
            child.state, child.next_start = BACKOFF, time.monotonic() + delay
            self._event(f"{spec.name} ended ({child.last_end}); restart {child.failures_in_row} "
                        f"of {spec.backoff.limit} in {delay:g} s")
            return
        given_up = wanted and spec.backoff.limit > 0
        child.state = FAILED if failed or given_up else EXITED
        self._event(f"{spec.name} ended ({child.last_end})"
                    + (f"; given up after {spec.backoff.limit} restarts" if given_up else ""))
        if spec.required:
            self._shutdown(f"required process {spec.name} ended ({child.last_end})"
                           + ("; given up on" if given_up else ""),
                           EXIT_FAILED if child.state == FAILED else EXIT_DONE)

    # ---- stopping -----------------------------------------------------------------------------

    def _signal_group(self, pgid: int, signo: int) -> None:
        try:
            os.killpg(pgid, signo)
        except ProcessLookupError:
            pass

    def _stop_child(self, child: Child) -> None:
        """SIGINT to a running process's group; SIGKILL after its stop_timeout."""
        if child.pid is None:
            return
        child.state = STOPPING
        self._signal_group(child.pgid, signal.SIGINT)
        self.stopping_groups[child.pgid] = time.monotonic() + child.spec.stop_timeout

    def _watch_stopping_groups(self, now: float) -> None:
        for pgid, deadline in list(self.stopping_groups.items()):
            if not group_alive(pgid):
                del self.stopping_groups[pgid]
                self._group_gone(pgid)
            elif now >= deadline:
                child = next((c for c in self.children if c.pgid == pgid), None)
                name = child.spec.name if child else f"process group {pgid}"
                timeout = child.spec.stop_timeout if child else 0
                self._event(f"{name} still running {timeout:g} s after SIGINT: SIGKILL")
                self._signal_group(pgid, signal.SIGKILL)
                self.stopping_groups[pgid] = float("inf")

    def _group_gone(self, pgid: int) -> None:
        if self.guardian_fd >= 0:
            try:
                os.write(self.guardian_fd, end_line(pgid))
            except OSError:
                pass

    def _shutdown(self, reason: str, status: int) -> None:
        """Begins the stop of the whole launch: each process in reverse start order."""
        if self.shutting_down:
            return
        self.shutting_down = True
        self.reason, self.exit_status = reason, status
        self._event(f"stopping: {reason}")
        for child in self.children:
            if child.state in (WAITING, BACKOFF):
                child.state = STOPPED
        self.stop_queue = list(reversed(self.start_order))

    def _shutdown_step(self) -> bool:
        """One step of the stop in reverse order; True once nothing runs."""
        while self.stop_queue:
            current = self.stop_queue[0]
            if current.pid is not None and current.state != STOPPING:
                self._stop_child(current)
            if current.pid is not None or current.pgid in self.stopping_groups:
                return False
            self.stop_queue.pop(0)
        return not self.stopping_groups and not self.by_pid

    def _stop_adopted(self) -> None:
        """Orphans of the processes that left their group (daemons) and were reparented here."""
        orphans = [pid for pid in adopted_children() if pid != self.guardian_pid]
        if not orphans:
            return
        self._event(f"stopping {len(orphans)} orphan(s) of the processes: {orphans}")
        for signo in (signal.SIGINT, signal.SIGKILL):
            for pid in orphans:
                try:
                    os.kill(pid, signo)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline and any(
                    pid in adopted_children() for pid in orphans):
                self._reap()
                time.sleep(0.02)
        self._reap()

    def _kill_everything_now(self) -> None:
        """A second Ctrl+C: no more waiting."""
        self._event("stopping now: SIGKILL to every process")
        for child in self.children:
            if child.pgid is not None and group_alive(child.pgid):
                self._signal_group(child.pgid, signal.SIGKILL)
                self.stopping_groups[child.pgid] = float("inf")

    def _clean_namespaces(self) -> None:
        """`horus shm clean` in each namespace the processes used: what a killed process held,
        and what a restarted one's predecessor made (a process removes only the topics it made
        itself), once no live process uses it."""
        for shm_dir, namespace in sorted({(c.shm_dir, c.namespace) for c in self.children}):
            try:
                core = self._introspection()
                if shm_dir:
                    os.environ["HORUS_SHM_DIR"] = shm_dir
                else:
                    os.environ.pop("HORUS_SHM_DIR", None)
                removed = core.clean_namespace(namespace)
                core.clean_presence(namespace)
                core.clean_pools(namespace)
                if removed:
                    self._event(f"namespace '{namespace}': removed {removed} segment(s) no "
                                "live process uses")
            except Exception as error:  # noqa: BLE001 (the stop goes on)
                self._event(f"namespace '{namespace}': cannot clean shared memory: {error}")

    def _finish_guardian(self) -> None:
        if self.guardian_fd < 0:
            return
        if not self.by_pid and not self.stopping_groups:
            try:
                os.write(self.guardian_fd, EXIT_LINE)
            except OSError:
                pass
        os.close(self.guardian_fd)
        self.guardian_fd = -1
        if self.guardian_pid:
            try:
                os.waitpid(self.guardian_pid, 0)
            except ChildProcessError:
                pass

    # ---- signals ------------------------------------------------------------------------------

    def _on_signal(self, signo, _frame) -> None:
        self.signals.append(signo)

    def _drain_wakeups(self, fd: int) -> None:
        try:
            while os.read(fd, 512):
                pass
        except BlockingIOError:
            pass

    def _handle_signal(self, signo: int) -> None:
        if signo == signal.SIGCHLD:
            return
        name = signal.Signals(signo).name
        if self.shutting_down:
            if signo == signal.SIGINT:
                self._kill_everything_now()
            return
        self._shutdown(f"{name} received", SIGNAL_EXIT[signo])

    # ---- output -------------------------------------------------------------------------------

    def _read_output(self, fd: int) -> None:
        child, stream, pending = self.streams[fd]
        try:
            data = os.read(fd, 65536)
        except BlockingIOError:
            return
        except OSError as error:
            if error.errno != errno.EIO:
                raise
            data = b""
        if data:
            pending += data
            *lines, rest = bytes(pending).split(b"\n")
            pending[:] = rest
            for line in lines:
                self._line(child, stream, line)
            if len(pending) > MAX_LINE_BYTES:
                self._line(child, stream, bytes(pending))
                pending.clear()
            return
        if pending:
            self._line(child, stream, bytes(pending))
        self.selector.unregister(fd)
        os.close(fd)
        del self.streams[fd]

    def _drain_output(self) -> None:
        """What the processes wrote before they ended, to the last line."""
        deadline = time.monotonic() + 1.0
        while self.streams and time.monotonic() < deadline:
            for key, _ in self.selector.select(0.05):
                if key.fd in self.streams:
                    self._read_output(key.fd)
        for fd in list(self.streams):
            self.selector.unregister(fd)
            os.close(fd)
            del self.streams[fd]

    def _line(self, child: Child, stream: str, line: bytes) -> None:
        log = child.logs.get(stream)
        if log is not None:
            log.write(line + b"\n")
            log.flush()
        if self.terminal_gone:
            return
        target = self.out if stream == "stdout" else self.err
        name = child.spec.name.ljust(self.width)
        if self.colour and target.isatty():
            prefix = f"\x1b[{child.colour}m{name} |\x1b[0m "
        else:
            prefix = f"{name} | "
        try:
            target.write(prefix + line.decode("utf-8", "replace").rstrip("\r") + "\n")
            target.flush()
        except (OSError, ValueError):
            # The reader went away (a closed pipe, a hung-up terminal): the logs still get
            # every line.
            self.terminal_gone = True

    def _event(self, text: str) -> None:
        """A line of the launcher's own: on stderr and in launch.log."""
        if self.launch_log is not None and not self.launch_log.closed:
            self.launch_log.write(f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} "
                                  f"{text}\n")
            self.launch_log.flush()
        if not self.terminal_gone:
            try:
                self.err.write(f"horus launch: {text}\n")
                self.err.flush()
            except (OSError, ValueError):
                self.terminal_gone = True

    # ---- control ------------------------------------------------------------------------------

    def status(self) -> dict:
        now = time.monotonic()
        return {
            "name": self.plan.name, "pid": os.getpid(), "source": self.plan.source,
            "log_dir": self.log_dir, "started_wall": self.started_wall,
            "state": "stopping" if self.shutting_down else "running",
            "processes": [{
                "name": c.spec.name, "pid": c.pid, "state": c.state, "restarts": c.restarts,
                "uptime_s": round(now - c.started_at, 1) if c.pid is not None else None,
                "last_end": c.last_end or None, "restart": c.spec.restart,
                "required": c.spec.required, "stop_timeout": c.spec.stop_timeout}
                for c in self.children]}

    def _serve(self, server) -> None:
        try:
            connection, _ = server.accept()
        except BlockingIOError:
            return
        with connection:
            connection.settimeout(1.0)
            try:
                if not control.peer_allowed(connection):
                    return
                request = control.read_request(connection)
                answer = self._answer(request)
            except (OSError, ValueError) as error:
                answer = {"ok": False, "error": f"bad request: {error}"}
            try:
                connection.sendall((json.dumps(answer) + "\n").encode())
            except OSError:
                pass

    def _answer(self, request: dict) -> dict:
        command, name = request["command"], request.get("process")
        if command == "status":
            return {"ok": True, **self.status()}
        if command not in ("stop", "restart"):
            return {"ok": False, "error": f"unknown command '{command}' (status, stop, restart)"}
        if self.shutting_down:
            return {"ok": False, "error": f"launch {self.plan.name} is stopping"}
        if command == "stop" and name is None:
            self._shutdown("stopped by `horus launch stop`", EXIT_DONE)
            return {"ok": True, "pid": os.getpid()}
        child = self.by_name.get(name)
        if child is None:
            from horus_cli.common import did_you_mean
            return {"ok": False, "error": f"launch {self.plan.name} has no process '{name}'"
                                          f"{did_you_mean(str(name), self.by_name)}"}
        if command == "stop":
            child.stop_requested = True
            if child.pid is not None:
                self._stop_child(child)
            elif child.state in (WAITING, BACKOFF):
                child.state = STOPPED
            self._event(f"{name}: stop asked from another terminal")
            return {"ok": True}
        if child.state == WAITING:
            return {"ok": False, "error": f"{name} waits for its dependencies; it starts when "
                                          "they are met"}
        self._event(f"{name}: restart asked from another terminal")
        if child.pid is not None:
            child.restart_requested = True
            self._stop_child(child)
        else:
            child.stop_requested = False
            child.restarts += 1
            child.failures_in_row = 0
            child.state, child.next_start = BACKOFF, time.monotonic()
        return {"ok": True}
