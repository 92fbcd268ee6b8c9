"""Fixtures of the remote link suite: two HORUS namespaces with shared-memory roots of their own
(a robot, A, and a laptop, B) joined only by `horus remote` over loopback TCP, and the
certificates `horus remote keygen` makes."""
from __future__ import annotations

import os
import pathlib
import shutil
import socket
import subprocess

import pytest
from processes import Children, two_worlds, wait_line

HORUS = os.environ.get("HORUS_CLI", "")
GENERATOR = os.environ.get("HORUS_GEN_PROGRAM", "")
# A third-party peer with a Sink of its own (sink_peer.cpp).
SINK_PEER = os.environ.get("HORUS_REMOTE_SINK_PEER", "")
SCHEMAS = pathlib.Path(__file__).resolve().parent / "schemas"
# The wire interface, all a third-party client (attacker.py) is given.
SCHEMA = pathlib.Path(__file__).resolve().parents[2] / "bridges" / "remote" / "remote.capnp"


@pytest.fixture
def worlds(tmp_path):
    """The robot (A) and the laptop (B), which share no memory."""
    with two_worlds(tmp_path) as made:
        yield made


@pytest.fixture
def children():
    """Children whose stderr is collected as it comes (`process.errors`)."""
    with Children(collect_stderr=True) as spawned:
        yield spawned


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="session")
def generated(tmp_path_factory) -> pathlib.Path:
    """The Python of remote_test (its Scale and Halve services), generated once; the folder to
    import from."""
    output = tmp_path_factory.mktemp("generated")
    subprocess.run([GENERATOR, "generate", "--lang", "python", "--out", str(output), "-I",
                    str(SCHEMAS), *(str(SCHEMAS / "remote_test" / f"{name}.hsrv")
                                    for name in ("scale", "halve"))],
                   check=True, capture_output=True)
    return output / "python"


@pytest.fixture(scope="session")
def certs(tmp_path_factory) -> pathlib.Path:
    """One CA with robot, laptop, attacker (a third-party client, attacker.py) and stranger (whom
    no policy names); `intruder` presents a certificate of another CA while trusting the
    robot's."""
    folder = tmp_path_factory.mktemp("certs") / "link"
    subprocess.run([HORUS, "remote", "keygen", str(folder), "robot", "laptop", "attacker",
                    "stranger"], check=True, capture_output=True)
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
