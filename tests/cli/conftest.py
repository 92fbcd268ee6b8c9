"""Fixtures of the `horus` command's suite: a namespace per test, the command, live peers."""
from __future__ import annotations

import os
import pathlib
import shutil
import subprocess

import pytest
from processes import Children, private_namespace


HORUS = os.environ.get("HORUS_CLI", "")


@pytest.fixture(autouse=True)
def namespace(monkeypatch, tmp_path):
    yield from private_namespace(monkeypatch, tmp_path, "cli")


def run_horus(*args: str, timeout: float = 30) -> subprocess.CompletedProcess:
    """Runs the command as a user would (bin/horus of the build tree)."""
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_cli)"
    return subprocess.run([HORUS, *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture
def children():
    with Children() as spawned:
        yield spawned


def wait_ready(process: subprocess.Popen, word: str = "ready") -> None:
    """Waits for the child's first line, which says its set-up is done."""
    line = process.stdout.readline()
    if line.strip() != word:
        process.kill()
        raise AssertionError(f"child failed: {line!r} {process.communicate()[1]}")


# The user package `cli_user` (Pose: POD, Route: serialized, Shift: a service), which the command
# is never built with. Its C++ (route.hmsg) is built for HORUS_CLI_USER_PEER by CMakeLists.txt.
USER_SCHEMAS = pathlib.Path(__file__).resolve().parent / "schemas" / "cli_user"


@pytest.fixture
def user_types(tmp_path):
    """The Python folder of the package `cli_user`, generated here from USER_SCHEMAS (copied to
    tmp_path/user_schemas, where tests point `-I`). Children put it on their PYTHONPATH."""
    source = tmp_path / "user_schemas" / "cli_user"
    shutil.copytree(USER_SCHEMAS, source)
    output = tmp_path / "user_generated"
    subprocess.run([os.environ["HORUS_GEN_PROGRAM"], "generate", "--lang", "python", "--out",
                    str(output), "-I", os.environ["HORUS_SCHEMA_DIR"], "-I", str(source.parent),
                    str(source / "route.hmsg"), str(source / "shift.hsrv")], check=True)
    return str(output / "python")

