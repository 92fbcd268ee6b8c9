"""Shared fixtures: the repository's folders and a way to run horus-gen as a user would."""
from __future__ import annotations

import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HORUS_GEN = ROOT / "generator" / "horus-gen"
SCHEMAS = ROOT / "tests" / "schemas"
GOLDEN = ROOT / "tests" / "golden"

sys.path.insert(0, str(ROOT / "generator"))

# The cross-language suite needs the C++ tools that ctest builds and names in these variables
# (test `python_crosslang`); a plain `pytest tests/python` does not collect it rather than skip it.
collect_ignore = [] if os.environ.get("HORUS_CROSSLANG_TOOL") else ["test_python_crosslang.py"]
# Likewise the Python runtime's suite needs the build's horus package and C++ peers (test
# `pytest_runtime`, which names them in HORUS_PY_PEER).
if not os.environ.get("HORUS_PY_PEER"):
    collect_ignore.append("runtime")


def run_horus_gen(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """Runs the generator in its own process with Debian's interpreter, as CMake does."""
    return subprocess.run(["/usr/bin/python3", str(HORUS_GEN), *args], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


@pytest.fixture
def horus_gen():
    return run_horus_gen


@pytest.fixture(scope="module")
def msg(tmp_path_factory):
    """The standard library `horus.msg`, generated for Python into a fresh folder and imported."""
    out = tmp_path_factory.mktemp("stdmsg")
    schemas = sorted((ROOT / "schemas" / "horus" / "msg").glob("*.hmsg"))
    result = run_horus_gen("generate", "--lang", "python", "--out", str(out), "-I", str(ROOT / "schemas"),
                           *map(str, schemas))
    assert result.returncode == 0, result.stderr
    sys.path.insert(0, str(out / "python"))
    try:
        for name in [m for m in sys.modules if m == "horus" or m.startswith("horus.")]:
            del sys.modules[name]
        yield importlib.import_module("horus.msg")
    finally:
        sys.path.remove(str(out / "python"))
