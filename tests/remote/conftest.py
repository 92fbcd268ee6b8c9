"""Fixtures of the remote link suite: two HORUS namespaces with shared-memory roots of their own
(a robot, A, and a laptop, B) joined only by `horus remote` over loopback TCP, and the
certificates `horus remote keygen` makes."""
from __future__ import annotations

import os
import pathlib
import shutil
import socket
import subprocess
import sys
import threading
import time
import uuid

import pytest

HORUS = os.environ.get("HORUS_CLI", "")
GENERATOR = os.environ.get("HORUS_GEN_PROGRAM", "")
SCHEMAS = pathlib.Path(__file__).resolve().parent / "schemas"


class World:
    """A HORUS namespace under a shared-memory root of its own: what one host would have."""

    def __init__(self, root: pathlib.Path) -> None:
        root.mkdir(mode=0o700)
        self.root = root
        self.namespace = f"remote_{uuid.uuid4().hex[:12]}"

    def env(self) -> dict:
        # XDG_RUNTIME_DIR: horus-remote's status files go with the rest of the world.
        return dict(os.environ, HORUS_SHM_DIR=str(self.root), HORUS_NAMESPACE=self.namespace,
                    XDG_RUNTIME_DIR=str(self.root))


@pytest.fixture
def worlds(tmp_path):
    """The robot (A) and the laptop (B), which share no memory."""
    made = (World(tmp_path / "shm_a"), World(tmp_path / "shm_b"))
    yield made
    for world in made:
        shutil.rmtree(world.root, ignore_errors=True)


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


class Children:
    """Processes a test starts, killed at its end."""

    def __init__(self) -> None:
        self.processes: list[subprocess.Popen] = []

    def start(self, argv: list[str], env: dict) -> subprocess.Popen:
        process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   env=env)
        process.errors = Output(process.stderr)
        self.processes.append(process)
        return process

    def python(self, code: str, env: dict, *args: str) -> subprocess.Popen:
        return self.start([sys.executable, "-c", code, *args], env)

    def kill_all(self) -> None:
        for process in self.processes:
            if process.poll() is None:
                process.kill()
            process.wait()


@pytest.fixture
def children():
    spawned = Children()
    yield spawned
    spawned.kill_all()


def wait_until(predicate, what: str, limit: float = 20.0):
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def wait_line(process: subprocess.Popen, expected: str) -> str:
    """Reads the child's stdout until a line starts with `expected`; fails with what it said if
    it ends first."""
    seen = []
    while True:
        line = process.stdout.readline()
        if not line:
            process.wait()
            raise AssertionError(f"expected a line {expected!r}, the child said {seen} and "
                                 f"{process.errors.text()!r}")
        seen.append(line.rstrip())
        if line.startswith(expected):
            return line.rstrip()


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="session")
def generated(tmp_path_factory) -> pathlib.Path:
    """The Python of remote_test (its Scale service), generated once; the folder to import from."""
    output = tmp_path_factory.mktemp("generated")
    subprocess.run([GENERATOR, "generate", "--lang", "python", "--out", str(output), "-I",
                    str(SCHEMAS), str(SCHEMAS / "remote_test" / "scale.hsrv")], check=True,
                   capture_output=True)
    return output / "python"


@pytest.fixture(scope="session")
def certs(tmp_path_factory) -> pathlib.Path:
    """One CA with robot, laptop and stranger (whom no policy names); `intruder` presents a
    certificate of another CA while trusting the robot's."""
    folder = tmp_path_factory.mktemp("certs") / "link"
    subprocess.run([HORUS, "remote", "keygen", str(folder), "robot", "laptop", "stranger"],
                   check=True, capture_output=True)
    other = folder.parent / "other"
    subprocess.run([HORUS, "remote", "keygen", str(other), "intruder"], check=True,
                   capture_output=True)
    intruder = folder.parent / "intruder"
    intruder.mkdir()
    shutil.copy(folder / "ca.crt", intruder / "ca.crt")
    for suffix in ("crt", "key"):
        shutil.copy(other / f"intruder.{suffix}", intruder / f"intruder.{suffix}")
    return folder


def serve(children, world, certs, *rules: str, port: int = 0, policy=None):
    """`horus remote serve` of `world` on loopback, allowing `rules` (and the lines of the file
    `policy`); (process, port)."""
    allow = [arg for rule in rules for arg in ("--allow", rule)]
    if policy is not None:
        allow += ["--policy", str(policy)]
    # --namespace given to `serve` here and to `horus` in connect(): both forms reach the tool.
    env = dict(world.env(), HORUS_NAMESPACE="not_this_one")
    process = children.start([HORUS, "remote", "serve", "--namespace", world.namespace,
                              "--listen", f"127.0.0.1:{port}", "--certs", str(certs), "--name",
                              "robot", *allow], env)
    line = wait_line(process, "serving namespace")
    return process, int(line.rsplit(" ", 1)[1])


def connect(children, world, certs, port: int, *args: str, name: str = "laptop"):
    """`horus remote connect` from `world` to the robot on `port`."""
    env = dict(world.env(), HORUS_NAMESPACE="not_this_one")
    return children.start([HORUS, "--namespace", world.namespace, "remote", "connect",
                           f"127.0.0.1:{port}", "--certs", str(certs), "--name", name,
                           "--server-name", "robot", *args], env)
