"""What the Python suites that run real processes share (tests/cli, tests/dds, tests/remote):
the children a test starts, waiting on them, and namespaces under shared-memory roots of their
own. Plain Python, no fixtures: each suite's conftest.py makes its fixtures of these."""
from __future__ import annotations

import contextlib
import os
import pathlib
import shutil
import subprocess
import sys
import threading
import time
import uuid


def wait_until(predicate, what: str, limit: float = 20.0):
    """The first true value of `predicate()`, asked every 50 ms; fails naming `what` after
    `limit` seconds."""
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


class Output:
    """A child's stderr lines, collected by a thread (so a chatty child never blocks on a full
    pipe) and searchable while it runs."""

    def __init__(self, stream) -> None:
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.lines.append(line.rstrip())

    def text(self) -> str:
        return "\n".join(self.lines)

    def wait_for(self, fragment: str, limit: float = 20.0) -> str:
        return wait_until(lambda: next((l for l in self.lines if fragment in l), None),
                          f"{fragment!r} on stderr; it said {self.lines}", limit)

    def wait_closed(self) -> None:
        """Waits until the child's end of the pipe is closed (it ended) and all is read."""
        self._thread.join()


class Children:
    """Processes a test starts, killed at its end (leaving the `with`). With `collect_stderr`,
    each child's stderr is read as it comes into `process.errors`, an Output; without it, the
    test reads stderr itself."""

    def __init__(self, collect_stderr: bool = False) -> None:
        self.collect_stderr = collect_stderr
        self.processes: list[subprocess.Popen] = []

    def __enter__(self) -> Children:
        return self

    def __exit__(self, *failure) -> None:
        self.kill_all()

    def start(self, argv: list[str], env: dict | None = None, *,
              keep_stdin: bool = False) -> subprocess.Popen:
        """`argv` with stdout and stderr piped (and stdin, if `keep_stdin`: the child sees it
        open until the test ends)."""
        process = subprocess.Popen(argv, stdin=subprocess.PIPE if keep_stdin else None,
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   env=env)
        if self.collect_stderr:
            process.errors = Output(process.stderr)
        self.processes.append(process)
        return process

    def python(self, code: str, env: dict | None = None, *args: str) -> subprocess.Popen:
        """`code` run by this interpreter, with `args` as its sys.argv[1:]."""
        return self.start([sys.executable, "-c", code, *args], env)

    def program(self, *argv: str) -> subprocess.Popen:
        """A program whose stdin stays open until the test ends (the service peer serves
        until it closes)."""
        return self.start(list(argv), keep_stdin=True)

    def kill_all(self) -> None:
        for process in self.processes:
            if process.poll() is None:
                process.kill()
            # The reader first, so that it and communicate() never read stderr at once.
            if self.collect_stderr:
                process.errors.wait_closed()
            process.communicate()


def stderr_after_kill(process: subprocess.Popen) -> str:
    """All the child said on stderr; it is killed first, so that this never waits on it."""
    process.kill()
    errors = getattr(process, "errors", None)
    if errors is None:
        return process.communicate()[1].strip()
    process.wait()
    errors.wait_closed()
    return errors.text()


def wait_line(process: subprocess.Popen, expected: str) -> str:
    """Reads the child's stdout until a line starts with `expected` and returns that line; fails
    with what it said if it ends first."""
    seen = []
    while True:
        line = process.stdout.readline()
        if not line:
            raise AssertionError(f"expected a line {expected!r}, the child said {seen} and "
                                 f"{stderr_after_kill(process)!r}")
        seen.append(line.rstrip())
        if line.startswith(expected):
            return line.rstrip()


class World:
    """A HORUS namespace under a shared-memory root of its own: what one host would have. Its
    runtime folder is that root too (horus-remote keeps its status files there)."""

    def __init__(self, root: pathlib.Path) -> None:
        root.mkdir(mode=0o700)
        self.root = root
        self.namespace = f"world_{uuid.uuid4().hex[:12]}"

    def env(self, **extra: str) -> dict:
        """This process's environment in this world, and `extra`."""
        env = dict(os.environ, HORUS_SHM_DIR=str(self.root), HORUS_NAMESPACE=self.namespace,
                   XDG_RUNTIME_DIR=str(self.root))
        env.update(extra)
        return env


@contextlib.contextmanager
def two_worlds(folder: pathlib.Path):
    """Worlds A and B (folder/shm_a, folder/shm_b), which share no memory; removed at the end."""
    made = (World(folder / "shm_a"), World(folder / "shm_b"))
    try:
        yield made
    finally:
        for world in made:
            shutil.rmtree(world.root, ignore_errors=True)


def private_namespace(monkeypatch, tmp_path: pathlib.Path, prefix: str):
    """Yields a namespace of its own under a shared-memory root of its own (children and the
    command inherit both, so nothing another run left in the default root can disturb a test),
    with the test running in tmp_path; removes the root after. For a suite's autouse fixture."""
    root = tmp_path / "shm"
    root.mkdir(mode=0o700)
    monkeypatch.setenv("HORUS_SHM_DIR", str(root))
    name = f"{prefix}_{uuid.uuid4().hex[:12]}"
    monkeypatch.setenv("HORUS_NAMESPACE", name)
    monkeypatch.chdir(tmp_path)
    yield name
    shutil.rmtree(root, ignore_errors=True)


def command_succeeded(result: subprocess.CompletedProcess, args) -> subprocess.CompletedProcess:
    """`result` of `horus ARGS`, which must have exited 0."""
    assert result.returncode == 0, f"horus {' '.join(args)}: {result.stderr}"
    return result


def command_refused(result: subprocess.CompletedProcess, args) -> str:
    """The reason (stderr, no traceback) of `horus ARGS`, which must have exited 1."""
    assert result.returncode == 1, (f"horus {' '.join(args)} should fail, exit "
                                    f"{result.returncode}: {result.stdout} {result.stderr}")
    assert "Traceback" not in result.stderr
    return result.stderr
