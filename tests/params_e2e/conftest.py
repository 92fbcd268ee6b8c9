"""Fixtures of the end-to-end parameter suite: a namespace per test under a shared-memory root of
its own, the Python classes of tests/schemas/test_nodes generated once, and the two node programs
(param_node.cpp built as HORUS_PARAM_E2E_NODE, py_param_node.py) started as children."""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest
from processes import Children, private_namespace, wait_line

HERE = pathlib.Path(__file__).resolve().parent
HORUS = os.environ.get("HORUS_CLI", "")
# Each language's node runs under its own name: both come from the same .hnode, whose declared
# name a program may replace (a second owner of one name would be refused).
NAMES = {"cpp": "cpp_params", "python": "py_params"}


@pytest.fixture(scope="session")
def generated_python(tmp_path_factory) -> str:
    """The folder holding test_msgs and test_nodes generated for Python from the test schemas."""
    schemas = pathlib.Path(os.environ["HORUS_SCHEMA_DIR"])
    files = [str(p) for p in sorted((schemas / "test_msgs").iterdir())
             if p.suffix in (".hmsg", ".hsrv")]
    files += [str(schemas / "other_pkg" / "stamp.hmsg"),
              str(schemas / "test_nodes" / "param_node.hnode")]
    out = tmp_path_factory.mktemp("generated")
    subprocess.run([sys.executable, os.environ["HORUS_GEN_PROGRAM"], "generate", "--lang",
                    "python", "--out", str(out), "-I", str(schemas), *files], check=True)
    return str(out / "python")


@pytest.fixture(autouse=True)
def namespace(monkeypatch, tmp_path):
    yield from private_namespace(monkeypatch, tmp_path, "params")


def run_horus(*args: str, timeout: float = 30) -> subprocess.CompletedProcess:
    """Runs the command as a user would (bin/horus of the build tree)."""
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_params_e2e)"
    return subprocess.run([HORUS, *args], capture_output=True, text=True, timeout=timeout)


class NodePrograms:
    """Starts the node program of a language under its name: `start(language, params_file)`
    returns the child once it printed its `ready` line, kept as `child.ready`."""

    def __init__(self, children: Children, generated_python: str) -> None:
        self.children = children
        self.python_env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [generated_python, os.environ.get("PYTHONPATH", "")]))

    def launch(self, language: str, params_file: str | None = None):
        """The child, not yet waited on (for a start expected to fail)."""
        extra = [params_file] if params_file else []
        if language == "cpp":
            return self.children.start([os.environ["HORUS_PARAM_E2E_NODE"], NAMES["cpp"],
                                        *extra])
        return self.children.start([sys.executable, str(HERE / "py_param_node.py"),
                                    NAMES["python"], *extra], self.python_env)

    def start(self, language: str, params_file: str | None = None):
        child = self.launch(language, params_file)
        child.ready = wait_line(child, "ready ")
        return child


@pytest.fixture
def nodes(generated_python):
    with Children() as children:
        yield NodePrograms(children, generated_python)


@pytest.fixture(params=["cpp", "python"])
def language(request) -> str:
    return request.param


@pytest.fixture
def children_with_stderr():
    """Children whose stderr (their log lines) is collected as it comes (`child.errors`)."""
    with Children(collect_stderr=True) as children:
        yield children
