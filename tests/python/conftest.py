"""Shared fixtures of the generator's suites (their helpers are in generator_testing.py)."""
from __future__ import annotations

import importlib
import os
import sys

import pytest

from generator_testing import ROOT, SCHEMAS, TEST_SCHEMAS, generate_python, import_from, run_horus_gen

# The Python runtime's suite needs the build's horus package and C++ peers, which its ctest entry
# (pytest_runtime) names: a plain `pytest tests/python` leaves it out.
collect_ignore = [] if os.environ.get("HORUS_PY_PEER") else ["runtime"]


@pytest.fixture
def horus_gen():
    return run_horus_gen


@pytest.fixture(scope="session")
def test_schemas_root(tmp_path_factory):
    """The test schemas generated once per session, importable as test_msgs, other_pkg, crosslang_msgs."""
    return generate_python(tmp_path_factory.mktemp("mirror"), *TEST_SCHEMAS, extra=("-I", str(SCHEMAS)))


@pytest.fixture(scope="session")
def msgs(test_schemas_root):
    return import_from(test_schemas_root, "test_msgs")[0]


@pytest.fixture(scope="session")
def other(test_schemas_root):
    return import_from(test_schemas_root, "other_pkg")[0]


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
