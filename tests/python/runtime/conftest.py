"""Fixtures of the Python runtime suite (module `runtime.conftest`: no clash with ../conftest.py)."""
from __future__ import annotations

import os
import subprocess
import sys
import uuid

import pytest

import horus

PEER = os.environ.get("HORUS_PY_PEER", "")


def pytest_configure(config):
    config.addinivalue_line("markers", "quiet_machine: holds only where thread wake-ups keep "
                            "100-200 us deadlines (ctest label quiet-machine, not in scripts/test)")


@pytest.fixture(autouse=True)
def namespace(monkeypatch, tmp_path):
    """Each test in its own topic namespace, removed afterwards with its log ring and presence
    folder (children inherit it), and in a folder of its own (a fatal stop writes the scheduler's
    blackbox into the current folder). A test that leaves anything of its namespace fails."""
    name = f"pyrt_{uuid.uuid4().hex[:12]}"
    monkeypatch.setenv("HORUS_NAMESPACE", name)
    monkeypatch.chdir(tmp_path)
    yield name
    horus._core.remove_namespace(name)
    left = [o["path"] for o in horus._core.list_namespace_objects(name)]
    if os.path.exists(horus._core.namespace_directory(name)):
        left.append(horus._core.namespace_directory(name))
    assert not left, f"left in shared memory: {left}"


@pytest.fixture
def peer():
    """Runs the C++ peer program (tests/python/runtime/peer.cpp) built beside this suite."""
    assert PEER, "HORUS_PY_PEER names the C++ peer; run this suite through ctest (pytest_runtime)"

    def start(*args: str) -> subprocess.Popen:
        return subprocess.Popen([PEER, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    return start


def python_child(code: str) -> subprocess.Popen:
    """A Python process running `code` with this process's environment (PYTHONPATH, namespace)."""
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
