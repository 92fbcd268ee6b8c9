"""Fixtures of the DDS bridge suite: Cyclone DDS on loopback only, a domain per test, HORUS
namespaces with shared-memory roots of their own, the types of schemas/ and the C peer."""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys
from typing import Iterator

import pytest
from dds_domains import claimed_domain
from processes import Children, two_worlds

HERE = pathlib.Path(__file__).resolve().parent
SCHEMAS = HERE / "schemas"
GENERATOR = os.environ.get("HORUS_GEN_PROGRAM", "")
HORUS_SCHEMAS = os.environ.get("HORUS_SCHEMA_DIR", "")

# Loopback only, no multicast: the configuration docs/dds-bridge.md shows.
LOOPBACK_CONFIG = HERE.parent.parent / "docs" / "cyclonedds-loopback.xml"


@pytest.fixture(autouse=True)
def dds_domain(monkeypatch, tmp_path) -> Iterator[int]:
    """A DDS domain of this test's own, held by no other test on the machine, on loopback
    (children inherit CYCLONEDDS_URI), and the type cache of `horus` kept in tmp_path."""
    monkeypatch.setenv("CYCLONEDDS_URI", f"file://{LOOPBACK_CONFIG}")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    with claimed_domain() as domain:
        yield domain


@pytest.fixture
def worlds(tmp_path):
    """Two namespaces, A and B, that share no memory: only a bridge joins them."""
    with two_worlds(tmp_path) as made:
        yield made


@pytest.fixture
def children():
    with Children() as spawned:
        yield spawned


def horus_gen(*args: str) -> None:
    subprocess.run([GENERATOR, *args], check=True, capture_output=True)


@pytest.fixture(scope="session")
def generated(tmp_path_factory) -> pathlib.Path:
    """Python (python/) of dds_test (schemas/: messages, POD ones, a service), and IDL (idl/) of it and of
    horus.msg's geometry and vision (Image's descriptor), generated once. One run per language: a run removes what an earlier one
    left in its --out."""
    output = tmp_path_factory.mktemp("generated")
    kinds = [str(SCHEMAS / "dds_test" / name)
             for name in ("kinds.hmsg", "pod.hmsg", "scale.hsrv")]
    horus_gen("generate", "--lang", "python", "--out", str(output / "py"), "-I", str(SCHEMAS),
              *kinds)
    standard = [str(pathlib.Path(HORUS_SCHEMAS) / "horus" / "msg" / name)
                for name in ("geometry.hmsg", "vision.hmsg")]
    horus_gen("generate", "--lang", "idl", "--out", str(output / "dds"), "-I", str(SCHEMAS), "-I",
              HORUS_SCHEMAS, *kinds, *standard)
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
    """dds_peer.c built with idlc's C of the emitted IDL and of ROS 2's messages (the bridge's
    bridges/dds/ros2_idl/), as a Cyclone user would build it."""
    build = tmp_path_factory.mktemp("dds_peer")
    sources = [str(HERE / "dds_peer.c")]
    for idl in (generated / "idl", HERE.parent.parent / "bridges" / "dds" / "ros2_idl"):
        for path in sorted(idl.rglob("*.idl")):
            folder = build / path.parent.relative_to(idl)
            folder.mkdir(parents=True, exist_ok=True)
            subprocess.run(["idlc", "-I", str(idl), str(path)], cwd=folder, check=True,
                           capture_output=True)
            sources.append(str(folder / (path.stem + ".c")))
    program = build / "dds_peer"
    subprocess.run(["cc", "-O1", "-Wall", "-DDDS_NDEBUG", "-I", str(build), "-o", str(program),
                    *sources, "-lddsc", "-lm"], check=True, capture_output=True)
    return str(program)


@pytest.fixture(scope="session")
def dds_attacker(tmp_path_factory) -> str:
    """dds_attacker.c built with idlc's C of attacker_idl/ (types of other layouts than CmdVel's
    that it writes under CmdVel's DDS type name)."""
    build = tmp_path_factory.mktemp("dds_attacker")
    subprocess.run(["idlc", str(HERE / "attacker_idl" / "attack.idl")], cwd=build, check=True,
                   capture_output=True)
    program = build / "dds_attacker"
    subprocess.run(["cc", "-O1", "-Wall", "-DDDS_NDEBUG", "-I", str(build), "-o", str(program),
                    str(HERE / "dds_attacker.c"), str(build / "attack.c"), "-lddsc"], check=True,
                   capture_output=True)
    return str(program)
