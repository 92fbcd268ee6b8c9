"""Fixtures of the DDS bridge suite: Cyclone DDS on loopback only, a domain per test, HORUS
namespaces with shared-memory roots of their own, the types of schemas/ and the C peer."""
from __future__ import annotations

import os
import pathlib
import random
import shutil
import subprocess
import sys
import time
import uuid

import pytest

HERE = pathlib.Path(__file__).resolve().parent
SCHEMAS = HERE / "schemas"
GENERATOR = os.environ.get("HORUS_GEN_PROGRAM", "")
HORUS_SCHEMAS = os.environ.get("HORUS_SCHEMA_DIR", "")

# Loopback only, no multicast: the configuration docs/dds-bridge.md shows.
LOOPBACK_CONFIG = HERE.parent.parent / "docs" / "cyclonedds-loopback.xml"


@pytest.fixture(autouse=True)
def dds_domain(monkeypatch, tmp_path) -> int:
    """A DDS domain of this test's own on loopback (children inherit CYCLONEDDS_URI), and the
    type cache of `horus` kept in tmp_path."""
    monkeypatch.setenv("CYCLONEDDS_URI", f"file://{LOOPBACK_CONFIG}")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return random.randrange(1, 230)


class World:
    """A HORUS namespace under a shared-memory root of its own: what one host would have."""

    def __init__(self, root: pathlib.Path) -> None:
        root.mkdir(mode=0o700)
        self.root = root
        self.namespace = f"dds_{uuid.uuid4().hex[:12]}"

    def env(self, **extra: str) -> dict:
        env = dict(os.environ, HORUS_SHM_DIR=str(self.root), HORUS_NAMESPACE=self.namespace)
        env.update(extra)
        return env


@pytest.fixture
def worlds(tmp_path):
    """Two namespaces, A and B, that share no memory: only a bridge joins them."""
    made = (World(tmp_path / "shm_a"), World(tmp_path / "shm_b"))
    yield made
    for world in made:
        shutil.rmtree(world.root, ignore_errors=True)


class Children:
    """Processes a test starts, killed at its end."""

    def __init__(self) -> None:
        self.processes: list[subprocess.Popen] = []

    def start(self, argv: list[str], env: dict | None = None) -> subprocess.Popen:
        process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   env=env)
        self.processes.append(process)
        return process

    def python(self, code: str, env: dict | None = None, *args: str) -> subprocess.Popen:
        return self.start([sys.executable, "-c", code, *args], env)

    def kill_all(self) -> None:
        for process in self.processes:
            if process.poll() is None:
                process.kill()
            process.communicate()


@pytest.fixture
def children():
    spawned = Children()
    yield spawned
    spawned.kill_all()


def wait_line(process: subprocess.Popen, expected: str) -> None:
    """Reads the child's lines until one starts with `expected`; fails with what it said if it
    ends first."""
    seen = []
    while True:
        line = process.stdout.readline()
        if not line:
            process.kill()
            _, errors = process.communicate()
            raise AssertionError(f"expected a line {expected!r}, the child said {seen} and "
                                 f"{errors.strip()!r}")
        seen.append(line.rstrip())
        if line.startswith(expected):
            return


def wait_until(predicate, what: str, limit: float = 20.0):
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def horus_gen(*args: str) -> None:
    subprocess.run([GENERATOR, *args], check=True, capture_output=True)


@pytest.fixture(scope="session")
def generated(tmp_path_factory) -> pathlib.Path:
    """Python (python/) of dds_test (schemas/: messages, POD ones, a service), and IDL (idl/) of it and of
    horus.msg's geometry, generated once. One run per language: a run removes what an earlier one
    left in its --out."""
    output = tmp_path_factory.mktemp("generated")
    kinds = [str(SCHEMAS / "dds_test" / name)
             for name in ("kinds.hmsg", "pod.hmsg", "scale.hsrv")]
    horus_gen("generate", "--lang", "python", "--out", str(output / "py"), "-I", str(SCHEMAS),
              *kinds)
    geometry = str(pathlib.Path(HORUS_SCHEMAS) / "horus" / "msg" / "geometry.hmsg")
    horus_gen("generate", "--lang", "idl", "--out", str(output / "dds"), "-I", str(SCHEMAS), "-I",
              HORUS_SCHEMAS, *kinds, geometry)
    (output / "py" / "python").rename(output / "python")
    (output / "dds" / "idl").rename(output / "idl")
    return output


@pytest.fixture(scope="session")
def kinds_class(generated):
    sys.path.insert(0, str(generated / "python"))
    from dds_test import Kinds
    return Kinds


@pytest.fixture(scope="session")
def dds_peer(generated, tmp_path_factory) -> str:
    """dds_peer.c built with idlc's C of the emitted IDL (as a Cyclone user would build it)."""
    idl = generated / "idl"
    build = tmp_path_factory.mktemp("dds_peer")
    sources = [str(HERE / "dds_peer.c")]
    for path in sorted(idl.rglob("*.idl")):
        folder = build / path.parent.relative_to(idl)
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run(["idlc", "-I", str(idl), str(path)], cwd=folder, check=True,
                       capture_output=True)
        sources.append(str(folder / (path.stem + ".c")))
    program = build / "dds_peer"
    subprocess.run(["cc", "-O1", "-Wall", "-DDDS_NDEBUG", "-I", str(build), "-o", str(program),
                    *sources, "-lddsc"], check=True, capture_output=True)
    return str(program)
