"""Fixtures of the live view's client suites (test_view_clients.py, test_view_page.py): a HORUS
namespace under a shared-memory root of its own, in which the test process itself publishes with
`import horus`, and `horus-view serve` on a free loopback port in it."""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import shutil
import subprocess
import uuid

import pytest
from processes import Children, wait_line

# Set by tests/view/CMakeLists.txt: the server, the Node.js clients installed by the fixture
# view_node_client (tests/view/node-client), and the generator for the test service.
VIEW = os.environ.get("HORUS_VIEW", "")
NODE_CLIENT_DIR = os.environ.get("HORUS_VIEW_NODE_CLIENT", "")
GENERATOR = os.environ.get("HORUS_GEN_PROGRAM", "")
SCHEMAS = pathlib.Path(__file__).resolve().parent / "schemas"


@pytest.fixture
def namespace(monkeypatch, tmp_path):
    """A namespace under a shared-memory root of its own, for this process (its `horus` topics)
    and the children it starts; removed at the end."""
    root = tmp_path / "shm"
    root.mkdir(mode=0o700)
    monkeypatch.setenv("HORUS_SHM_DIR", str(root))
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(root))
    name = f"view_{uuid.uuid4().hex[:12]}"
    monkeypatch.setenv("HORUS_NAMESPACE", name)
    yield name
    shutil.rmtree(root, ignore_errors=True)


@pytest.fixture
def children():
    """Children whose stderr is collected as it comes (`process.errors`)."""
    with Children(collect_stderr=True) as spawned:
        yield spawned


@dataclasses.dataclass(frozen=True)
class ViewServer:
    process: subprocess.Popen
    url: str          # ws://127.0.0.1:PORT/
    port: int

    @property
    def http_url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"


@pytest.fixture
def view_server(namespace, children) -> ViewServer:
    """`horus-view serve` of this test's namespace on a free loopback port, once it says ready."""
    assert VIEW, "HORUS_VIEW names build/bin/horus-view; run this suite through ctest (pytest_view)"
    process = children.start([VIEW, "serve", "--namespace", namespace, "--listen", "127.0.0.1",
                              "--port", "0"], dict(os.environ))
    line = wait_line(process, "ready ws://")
    url = line.split(" ", 1)[1]
    port = int(url.rstrip("/").rsplit(":", 1)[1])
    return ViewServer(process, url, port)


def run_node_client(url: str, plan: dict, timeout: float = 120) -> dict:
    """client_check.mjs (Foxglove's own client) against `url` following `plan`; its JSON result.
    Fails with what it said when it printed none."""
    assert NODE_CLIENT_DIR, ("HORUS_VIEW_NODE_CLIENT names the clients the fixture "
                             "view_node_client installs; run this suite through ctest")
    script = pathlib.Path(NODE_CLIENT_DIR) / "client_check.mjs"
    done = subprocess.run(["node", str(script), url, json.dumps(plan)], capture_output=True,
                          text=True, timeout=timeout)
    assert done.returncode == 0 and done.stdout.strip(), (
        f"client_check.mjs failed ({done.returncode}): {done.stdout} {done.stderr}")
    return json.loads(done.stdout)


@pytest.fixture(scope="session")
def view_test_types(tmp_path_factory) -> str:
    """The Python of view_test (its Scale service), generated once; the folder to import from."""
    output = tmp_path_factory.mktemp("generated")
    subprocess.run([GENERATOR, "generate", "--lang", "python", "--out", str(output), "-I",
                    str(SCHEMAS), str(SCHEMAS / "view_test" / "scale.hsrv")],
                   check=True, capture_output=True)
    return str(output / "python")
