"""Who gets into the live view (horus-view serve with --tls, --allow and --tokens): wss:// with
`horus remote keygen`'s certificates, each client the peer its URL's token (or its client
certificate) names, and each peer limited to what the policy lines allow it: alice reads cmd_*
and writes cmd_vel and calls the Scale service, bob reads odom, carol (by certificate) reads
odom; the connection graph shows each only its services. Foxglove's own client
(client_check.mjs over npm `ws`, trusting the test's CA) is the viewer; a wrong token is refused
at the upgrade, and a server that would serve beyond this machine without TLS, or with a tokens
file others may read, does not start."""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import socket
import ssl
import subprocess
import sys
import time

import horus
import pytest
from conftest import (VIEW, Publishing, RawWebSocket, run_node_client,
                      websocket_handshake)
from horus.msg import CmdVel
from processes import wait_line

# Set by tests/view/CMakeLists.txt: the `horus` command, whose `remote keygen` makes the CA and
# the certificates.
HORUS = os.environ.get("HORUS_CLI", "")
SERVER_NAME = "robot"
TOKENS = {"alice": "alice-0123456789abcdef", "bob": "bob-0123456789abcdef00"}


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> pathlib.Path:
    """One CA with the server's certificate (robot) and carol's, a client certificate; beside it
    another CA's mallory (other/)."""
    assert HORUS, "HORUS_CLI names build/bin/horus; run this suite through ctest (pytest_view_auth)"
    folder = tmp_path_factory.mktemp("certs") / "view"
    subprocess.run([HORUS, "remote", "keygen", str(folder), SERVER_NAME, "carol"], check=True,
                   capture_output=True)
    subprocess.run([HORUS, "remote", "keygen", str(folder.parent / "other"), "mallory"],
                   check=True, capture_output=True)
    return folder


def tokens_file(folder: pathlib.Path, mode: int = 0o600) -> pathlib.Path:
    path = folder / "tokens"
    path.write_text("# peer token\n" + "".join(f"{peer} {token}\n"
                                                for peer, token in TOKENS.items()))
    path.chmod(mode)
    return path


@dataclasses.dataclass(frozen=True)
class SecureView:
    process: subprocess.Popen
    port: int
    certs: pathlib.Path

    def url(self, token: str | None = None) -> str:
        return f"wss://127.0.0.1:{self.port}/" + (f"?token={token}" if token else "")

    def tls(self, certificate: str | None = None) -> dict:
        """client_check.mjs's plan.tls: trust the CA, present `certificate`'s when given."""
        tls = {"ca": str(self.certs / "ca.crt"), "servername": SERVER_NAME}
        if certificate:
            tls.update(cert=str(self.certs / f"{certificate}.crt"),
                       key=str(self.certs / f"{certificate}.key"))
        return tls


class Topics(Publishing):
    """cmd_vel and cmd_arm (alice's to read, cmd_vel hers to write) and odom (bob's and carol's
    to read), opened before the view starts so that its first advertisement has them; odom
    published every 20 ms until the `with` ends."""

    def __init__(self) -> None:
        self.cmd_vel = horus.Topic(CmdVel, "cmd_vel")
        self.cmd_arm = horus.Topic(CmdVel, "cmd_arm")
        self.odom = horus.Topic(CmdVel, "odom")
        super().__init__()

    def publish(self, count: int) -> None:
        self.odom.send(CmdVel(stamp_nanos=count, linear=0.5, angular=0.0))


@pytest.fixture
def topics(namespace):
    with Topics() as opened:
        yield opened


@pytest.fixture
def scale_service(view_test_types):
    sys.path.insert(0, view_test_types)
    from view_test import Scale, ScaleResponse
    return Scale, ScaleResponse


@pytest.fixture
def secure_view(namespace, children, certs, topics, scale_service, tmp_path) -> SecureView:
    scale, _ = scale_service
    process = children.start([
        VIEW, "serve", "--namespace", namespace, "--listen", "127.0.0.1", "--port", "0",
        "--tls", str(certs), "--name", SERVER_NAME,
        "--allow", "alice read cmd_*", "--allow", "alice write cmd_vel",
        "--allow", f"alice call {scale.name}",
        "--allow", "bob read odom", "--allow", "carol read odom",
        "--tokens", str(tokens_file(tmp_path))], dict(os.environ))
    line = wait_line(process, "ready ")
    assert line.startswith("ready wss://127.0.0.1:"), line
    return SecureView(process, int(line.rstrip("/").rsplit(":", 1)[1]), certs)


def channel_topics(run: dict) -> set[str]:
    return {channel["topic"] for channel in run["channels"]}


def error_statuses(run: dict) -> list[str]:
    return [status.get("message", str(status)) for status in run["statuses"]
            if status.get("level", 0) >= 2 or "clientError" in status]


def test_a_peer_sees_only_what_it_may_read_and_publishes_where_it_may_write(secure_view, topics):
    alice = run_node_client(secure_view.url(TOKENS["alice"]), {
        "tls": secure_view.tls(), "topics": ["cmd_vel", "cmd_arm"],
        "publish": {"topic": "cmd_vel", "messages": [
            {"stamp_nanos": "42", "linear": 2.5, "angular": 0.5}] * 3}})["runs"]
    (run,) = alice.values()
    assert "error" not in run, run
    assert channel_topics(run) == {"cmd_vel", "cmd_arm"}, run["channels"]
    assert not error_statuses(run), run["statuses"]
    received = []
    while (message := topics.cmd_vel.try_recv()) is not None:
        received.append(message)
    assert [(m.stamp_nanos, m.linear, m.angular) for m in received] == [(42, 2.5, 0.5)] * 3

    bob = run_node_client(secure_view.url(TOKENS["bob"]), {
        "tls": secure_view.tls(), "topics": ["odom"], "subscribe": {"odom": 2}})["runs"]
    (run,) = bob.values()
    assert "error" not in run, run
    assert channel_topics(run) == {"odom"}, run["channels"]
    assert [m["linear"] for m in run["messages"]["odom"]["decoded"]] == [0.5, 0.5]


def test_publishing_where_a_peer_may_not_write_is_refused_and_logged(secure_view, topics):
    while topics.odom.try_recv() is not None:
        pass
    result = run_node_client(secure_view.url(TOKENS["alice"]), {
        "tls": secure_view.tls(), "topics": ["cmd_vel"],
        "publish": {"topic": "odom", "messages": [
            {"stamp_nanos": "666", "linear": 9.0, "angular": 9.0}] * 2}})["runs"]
    (run,) = result.values()
    assert "error" not in run, run
    refusals = error_statuses(run)
    assert any("publishing into 'odom'" in text and "peer 'alice' may not write it" in text
               for text in refusals), refusals
    intruding = []
    while (message := topics.odom.try_recv()) is not None:
        if message.stamp_nanos == 666:
            intruding.append(message)
    assert not intruding, intruding
    logged = secure_view.process.errors.wait_for("horus-view: refused alice (127.0.0.1:")
    assert logged.endswith("publishing into 'odom'"), logged


def test_a_peer_calls_only_the_services_it_may_call(secure_view, scale_service):
    scale, response = scale_service
    with horus.ServiceServer(scale, lambda request: response(
            product=request.value * request.factor, note="scaled")):
        alice = run_node_client(secure_view.url(TOKENS["alice"]), {
            "tls": secure_view.tls(),
            "call": {"service": scale.name, "request": {"value": 2.0, "factor": 3.0}}})["runs"]
        # Advertised to alice by now: bob, who may not call it, waits for it in vain.
        bob = run_node_client(secure_view.url(TOKENS["bob"]), {
            "tls": secure_view.tls(), "timeout_ms": 2000,
            "call": {"service": scale.name, "request": {"value": 1.0, "factor": 1.0}}})["runs"]
    (run,) = alice.values()
    assert "error" not in run, run
    assert run["call"] == {"response": {"product": 6.0, "note": "scaled"}, "encoding": "json"}
    (run,) = bob.values()
    assert "the advertisement of service" in run.get("error", ""), run


class GraphWatcher:
    """A WebSocket client of our own over TLS that asks for the connection graph and reads the
    server's text messages."""

    def __init__(self, view: SecureView, token: str) -> None:
        context = ssl.create_default_context(cafile=str(view.certs / "ca.crt"))
        raw = socket.create_connection(("127.0.0.1", view.port), timeout=10)
        self.websocket = RawWebSocket(context.wrap_socket(raw, server_hostname=SERVER_NAME),
                                      view.port, path=f"/?token={token}")
        self.websocket.send_text(json.dumps({"op": "subscribeConnectionGraph"}))

    def graph_updates(self, seconds: float):
        """The connectionGraphUpdate messages that come within `seconds`."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            self.websocket.socket.settimeout(left)
            try:
                opcode, payload = self.websocket.read_frame()
            except (socket.timeout, TimeoutError):
                return
            if opcode == 1 and json.loads(payload).get("op") == "connectionGraphUpdate":
                yield json.loads(payload)

    def close(self) -> None:
        self.websocket.close()


def test_the_connection_graph_holds_only_the_services_a_peer_may_call(secure_view,
                                                                      scale_service):
    scale, response = scale_service
    with horus.ServiceServer(scale, lambda request: response(product=0.0, note="")):
        alice = GraphWatcher(secure_view, TOKENS["alice"])
        try:
            provided = next((update for update in alice.graph_updates(10)
                             if update["advertisedServices"]), None)
        finally:
            alice.close()
        assert provided is not None, "alice, who may call it, never saw the service's server"
        assert [s["name"] for s in provided["advertisedServices"]] == [scale.name], provided
        # The graph holds the server now: bob, who may not call it, is sent none of it.
        bob = GraphWatcher(secure_view, TOKENS["bob"])
        try:
            seen = list(bob.graph_updates(1.5))
        finally:
            bob.close()
    assert seen, "bob was sent no graph on asking for it"
    assert not any(update["advertisedServices"] for update in seen), seen


def test_a_client_certificate_names_its_peer(secure_view):
    result = run_node_client(secure_view.url(), {
        "tls": secure_view.tls(certificate="carol"), "topics": ["odom"],
        "subscribe": {"odom": 1}})["runs"]
    (run,) = result.values()
    assert "error" not in run, run
    assert channel_topics(run) == {"odom"}, run["channels"]


def upgrade_status(view: SecureView, path: str, certificate: pathlib.Path | None = None) -> str:
    """The status line a WebSocket upgrade of `path` is answered with, over TLS trusting the CA
    (presenting `certificate`.crt and .key when given)."""
    context = ssl.create_default_context(cafile=str(view.certs / "ca.crt"))
    if certificate:
        context.load_cert_chain(f"{certificate}.crt", f"{certificate}.key")
    with socket.create_connection(("127.0.0.1", view.port), timeout=10) as raw, \
            context.wrap_socket(raw, server_hostname=SERVER_NAME) as connection:
        status, _ = websocket_handshake(connection, view.port, "foxglove.websocket.v1", path)
    return status


def test_a_wrong_or_missing_token_is_refused_at_the_upgrade(secure_view):
    assert upgrade_status(secure_view, "/?token=not-a-token-of-anyone").startswith(
        "HTTP/1.1 401"), "a wrong token"
    assert upgrade_status(secure_view, "/").startswith("HTTP/1.1 401"), "no token"
    logged = secure_view.process.errors.wait_for("horus-view: refused a client (127.0.0.1:")
    assert "token" in logged, logged
    assert upgrade_status(secure_view, f"/?token={TOKENS['bob']}").startswith("HTTP/1.1 101")


def test_a_client_certificate_of_another_ca_fails_the_handshake(secure_view):
    mallory = secure_view.certs.parent / "other" / "mallory"
    try:
        status = upgrade_status(secure_view, "/", certificate=mallory)
    except (ssl.SSLError, ConnectionError) as error:
        status = f"refused: {error}"
    assert not status.startswith("HTTP/1.1 101"), status
    logged = secure_view.process.errors.wait_for("horus-view: refused a client (127.0.0.1:")
    assert "its certificate does not verify against our CA" in logged, logged


def refused_start(namespace: str, *arguments: str) -> str:
    """What horus-view serve says on stderr when it refuses to start with `arguments`."""
    done = subprocess.run([VIEW, "serve", "--namespace", namespace, "--port", "0", *arguments],
                          capture_output=True, text=True, timeout=30)
    assert done.returncode != 0 and "ready" not in done.stdout, (done.stdout, done.stderr)
    return done.stderr


def test_listening_beyond_this_machine_without_tls_is_refused_at_start(namespace, tmp_path):
    said = refused_start(namespace, "--listen", "0.0.0.0", "--allow", "alice read *",
                         "--tokens", str(tokens_file(tmp_path)))
    assert said.count("\n") == 1, said
    assert "listening on 0.0.0.0" in said and "add --tls DIR --name NAME" in said, said


def test_a_tokens_file_others_may_read_is_refused_at_start(namespace, tmp_path):
    path = tokens_file(tmp_path, mode=0o644)
    said = refused_start(namespace, "--allow", "alice read *", "--tokens", str(path))
    assert f"the tokens file {path} has mode 0644" in said and f"chmod 600 {path}" in said, said
