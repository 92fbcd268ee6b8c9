"""Fixtures of the live view's client suites (test_view_clients.py, test_view_page.py): a HORUS
namespace under a shared-memory root of its own, in which the test process itself publishes with
`import horus`, and `horus-view serve` on a free loopback port in it."""
from __future__ import annotations

import base64
import dataclasses
import json
import os
import pathlib
import shutil
import socket
import struct
import subprocess
import threading
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


class Publishing:
    """Publishes on a thread of its own every 20 ms while the `with` lasts: each round calls
    publish(count), count 1, 2, ..."""

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *failure) -> None:
        self._stop.set()
        self._thread.join()

    def publish(self, count: int) -> None:
        raise NotImplementedError

    def _run(self) -> None:
        count = 0
        while not self._stop.wait(0.02):
            count += 1
            self.publish(count)


def websocket_handshake(connection: socket.socket, port: int, subprotocol: str,
                        path: str = "/") -> tuple[str, bytes]:
    """Sends the opening handshake of `path`; (the status line, the bytes read past the
    headers)."""
    key = base64.b64encode(os.urandom(16)).decode()
    connection.sendall((f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                        "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                        f"Sec-WebSocket-Protocol: {subprotocol}\r\n\r\n").encode())
    received = b""
    while b"\r\n\r\n" not in received:
        chunk = connection.recv(4096)
        if not chunk:
            break
        received += chunk
    headers, _, rest = received.partition(b"\r\n\r\n")
    return headers.split(b"\r\n", 1)[0].decode(), rest


class RawWebSocket:
    """A WebSocket client of our own over `connection` (plain or TLS) that reads frames only when
    asked to and sends masked text frames."""

    def __init__(self, connection: socket.socket, port: int,
                 subprotocol: str = "foxglove.websocket.v1", path: str = "/") -> None:
        self.socket = connection
        status, self.buffer = websocket_handshake(connection, port, subprotocol, path)
        assert status.startswith("HTTP/1.1 101"), status

    def _take(self, size: int) -> bytes:
        while len(self.buffer) < size:
            chunk = self.socket.recv(65536)
            assert chunk, "the server closed the connection"
            self.buffer += chunk
        taken, self.buffer = self.buffer[:size], self.buffer[size:]
        return taken

    def read_frame(self) -> tuple[int, bytes]:
        """(opcode, payload) of the next frame."""
        first, second = self._take(2)
        size = second & 0x7F
        if size == 126:
            size = struct.unpack(">H", self._take(2))[0]
        elif size == 127:
            size = struct.unpack(">Q", self._take(8))[0]
        return first & 0x0F, self._take(size)

    def send_text(self, text: str) -> None:
        payload = text.encode()
        mask = os.urandom(4)
        if len(payload) < 126:
            header = bytes([0x81, 0x80 | len(payload)])
        else:
            header = bytes([0x81, 0x80 | 126]) + struct.pack(">H", len(payload))
        masked = bytes(byte ^ mask[index % 4] for index, byte in enumerate(payload))
        self.socket.sendall(header + mask + masked)

    def close(self) -> None:
        self.socket.close()


CHROMIUM = pathlib.Path("/usr/bin/chromium")
CHROMEDRIVER = pathlib.Path("/usr/bin/chromedriver")


@pytest.fixture
def browser():
    """Headless Chromium driven by Debian's chromedriver (the page suites)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    for path, package in ((CHROMIUM, "chromium"), (CHROMEDRIVER, "chromium-driver")):
        assert path.exists(), f"{path} is missing: install Debian's {package} (scripts/install-deps)"
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for argument in ("--headless=new", "--disable-gpu", "--disable-dev-shm-usage",
                     "--window-size=1400,1000"):
        options.add_argument(argument)
    if os.geteuid() == 0:
        options.add_argument("--no-sandbox")  # Chromium refuses to run its sandbox as root
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()
