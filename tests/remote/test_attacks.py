"""An authenticated peer attacking the robot, played by a third-party client (attacker.py:
pycapnp and remote.capnp only): 1,000 subscriptions to one topic, publishes of another type,
fingerprint or size or with bytes that are no type description, messages of the wrong size and
one over the connection's limit, and as
many streams as it may hold, never acknowledged; a peer with more connections than it may
have, one reconnecting to be refused again, and a burst of refused connections. What must hold
(docs/remote.md, "What an authenticated peer can do"): local code still opens the topic, another
peer's stream keeps its rate, the robot's memory stays within its bound per peer, refused
connections beyond a few are closed at once, every refusal is logged once per peer and kind
with a count, and nothing wrong reaches a subscriber."""
from __future__ import annotations

import pathlib
import re
import socket
import ssl
import sys
import time

from conftest import SCHEMA, connect, serve
from processes import wait_line, wait_until
from test_link import PUBLISHER
from test_resilience import STREAMER, Stamps, authenticated, resident_kib, streaming

ATTACKER = str(pathlib.Path(__file__).resolve().parent / "attacker.py")
# docs/remote.md: what one peer with one connection may cost the robot's memory, at most.
PEER_MEMORY_BOUND_KIB = 48 * 1024

# 15 topics of small messages at 200 Hz and one of 900 kB images at 30 Hz, until killed.
BUSY_ROBOT = """
import time, horus
from horus.msg import CmdVel, CompressedImage
small = [horus.Topic(CmdVel, f"small{i}", capacity=1024) for i in range(15)]
camera = horus.Topic(CompressedImage, "camera", capacity=8, max_message_size=1 << 20)
print("ready", flush=True)
i = 0
while True:
    for topic in small:
        topic.send(CmdVel(stamp_nanos=i))
    if i % 7 == 0:
        camera.send(CompressedImage(format="rgb8", data=bytes(900_000), width=640, height=480,
                                    timestamp_ns=i))
    i += 1
    time.sleep(0.005)
"""

# Opens cmd_vel as any new process on the robot would.
OPENER = """
import horus
from horus.msg import CmdVel
horus.Topic(CmdVel, "cmd_vel", capacity=512)
print("opened", flush=True)
"""

# Prints each cmd_vel message it gets on the robot.
WATCHER = """
import horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel", capacity=512)
print("ready", flush=True)
while True:
    message = topic.recv(timeout=1.0)
    if message is not None:
        print(message.stamp_nanos, message.linear, message.angular, flush=True)
"""


def attacker(children, port: int, certs, *args: str):
    return children.start([sys.executable, ATTACKER, str(SCHEMA), str(port), str(certs), *args])


def refusals(log: str, kind: str) -> tuple[int, int]:
    """(lines, refusals) the robot logged of `kind`: its first refusal of a kind is a line,
    later ones are summed up in lines saying how many more."""
    lines = [line for line in log.splitlines() if f"({kind}" in line]
    more = sum(int(m.group(1)) for line in lines
               for m in [re.search(r" (\d+) more time", line)] if m)
    return len(lines), (1 if lines else 0) + more


def private_kib(process) -> int:
    """The process's own memory (the topics' shared memory it maps left out)."""
    with open(f"/proc/{process.pid}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("RssAnon:"))


def peak_kib(process) -> int:
    """The most memory the process has held resident so far."""
    with open(f"/proc/{process.pid}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmHWM:"))


def rate(stamps: Stamps, seconds: float) -> float:
    start = len(stamps.seen)
    time.sleep(seconds)
    return (len(stamps.seen) - start) / seconds


def test_a_thousand_subscriptions_to_one_topic_starve_nobody(children, worlds, certs):
    robot, laptop = worlds
    children.python(PUBLISHER, robot.env())
    server, port = serve(children, robot, certs, "laptop read cmd_vel", "attacker read *")
    streamer = children.python(STREAMER, laptop.env())
    wait_line(streamer, "ready")
    connect(children, laptop, certs, port, "--import", "cmd_vel")
    stamps = Stamps(streamer)
    stamps.grow_by(20, "before the attack")
    calm = rate(stamps, 2.0)
    before = resident_kib(server)

    start = len(stamps.seen)
    began = time.monotonic()
    attack = attacker(children, port, certs, "subscribe", "1000", "1.5")
    granted, refused = map(int, wait_line(attack, "granted").split()[1::2])
    # A new process on the robot opens the topic while the peer holds what it was granted.
    wait_line(children.python(OPENER, robot.env()), "opened")
    wait_line(attack, "dropped")
    attacked = (len(stamps.seen) - start) / (time.monotonic() - began)
    attack.wait(timeout=20)

    assert (granted, refused) == (4, 1196)
    assert attacked >= 0.8 * calm, f"{attacked:.0f}/s under the attack, {calm:.0f}/s without"
    grown = peak_kib(server) - before
    assert grown < PEER_MEMORY_BOUND_KIB, f"the robot grew by {grown} KiB"
    assert server.poll() is None, server.errors.text()
    kinds = {"handle limit": 996, "no such topic": 100, "another type": 100}
    # Summed up within 5 s of each kind's first line.
    wait_until(lambda: all(refusals(server.errors.text(), kind)[1] == count
                           for kind, count in kinds.items()), "every refusal logged or counted")
    log = server.errors.text()
    for kind, count in kinds.items():
        lines, logged = refusals(log, kind)
        assert 1 <= lines <= 3 and logged == count, (kind, lines, logged, count, log)
    assert "attacker" in log and "cmd_vel" in log, log


def test_refused_publishes_are_logged_and_reach_no_subscriber(children, worlds, certs):
    robot, _ = worlds
    watcher = children.python(WATCHER, robot.env())
    wait_line(watcher, "ready")
    server, port = serve(children, robot, certs, "attacker read *", "attacker write cmd_vel")
    before = resident_kib(server)
    attack = attacker(children, port, certs, "publish", "50")
    counts = [int(n) for n in wait_line(attack, "refused").split()[1:]]
    assert counts == [50, 50, 50, 50, 50], counts
    server.errors.wait_for("over its limit")
    attack.wait(timeout=20)
    grown = peak_kib(server) - before
    assert grown < PEER_MEMORY_BOUND_KIB, f"the robot grew by {grown} KiB"
    # The one right message of the attack, and nothing else.
    assert wait_line(watcher, "") == "0 0.0 0.0"
    server.errors.wait_for("disconnected")
    kinds = {"another type": 150, "bad type description": 50, "wrong message": 50}
    wait_until(lambda: all(refusals(server.errors.text(), kind)[1] == count
                           for kind, count in kinds.items()), "every refusal logged or counted")
    text = server.errors.text()
    for kind, count in kinds.items():
        lines, logged = refusals(text, kind)
        assert 1 <= lines <= 3 and logged == count, (kind, lines, logged, count, text)
    over = [line for line in text.splitlines() if "over its limit" in line]
    assert len(over) == 1 and "attacker" in over[0], text
    time.sleep(0.5)
    watcher.kill()
    assert watcher.communicate()[0] == "", "a message of the attack reached the subscriber"


def test_streams_never_acknowledged_cost_the_robot_a_bounded_memory(children, worlds, certs):
    robot, _ = worlds
    wait_line(children.python(BUSY_ROBOT, robot.env()), "ready")
    server, port = serve(children, robot, certs, "attacker read *")
    before = private_kib(server)
    attack = attacker(children, port, certs, "stall")
    # 16 topics, 5 subscriptions each asked for: 4 each granted (64, all a peer may hold).
    assert wait_line(attack, "granted").split()[1::2] == ["64", "16"]
    grown = []
    for _ in range(4):  # the small streams fill their queues (1024 messages) in 5 s
        time.sleep(1.0)
        grown.append(private_kib(server) - before)
    assert max(grown) < PEER_MEMORY_BOUND_KIB, f"the robot grew by {grown} KiB"
    assert grown[-1] - grown[1] < 4 * 1024, f"the robot kept growing: {grown} KiB"
    assert server.poll() is None, server.errors.text()


def test_a_peer_has_at_most_four_connections(children, worlds, certs):
    robot, laptop = worlds
    server, port = serve(children, robot, certs, "laptop read cmd_vel")
    held = [authenticated(certs, port) for _ in range(4)]
    try:
        client = connect(children, laptop, certs, port)
        line = client.errors.wait_for("the robot refused this peer")
        assert "peer 'laptop' has 4 connections to this robot already" in line, line
        server.errors.wait_for("refused laptop at 127.0.0.1:")
        held.pop().close()
        wait_line(client, "connected to")  # one connection fewer: room for this one
    finally:
        for connection in held:
            connection.close()


def test_a_peer_that_reconnects_is_logged_once_per_kind(children, worlds, certs):
    robot, _ = worlds
    children.python(PUBLISHER, robot.env())
    server, port = serve(children, robot, certs, "attacker read cmd_vel")
    # A connection each, asking for a topic outside the policy, one after another.
    for _ in range(5):
        attack = attacker(children, port, certs, "outside", "secret")
        assert wait_line(attack, "") == "refused"
        attack.wait(timeout=20)
    kind = "read topic: not in the policy"
    # The first refusal is a line; the next four, on other connections, are summed up (5 s
    # after the first line at most), not each a first line again.
    wait_until(lambda: refusals(server.errors.text(), kind)[1] == 5,
               "the refusals of the later connections summed up")
    text = server.errors.text()
    first = [line for line in text.splitlines() if f"({kind}; more of this kind" in line]
    assert len(first) == 1 and "attacker read topic secret" in first[0], text
    lines, logged = refusals(text, kind)
    assert lines == 2 and logged == 5, text


def closed_at_once(peer) -> bool:
    """Whether the robot closes `peer` within a second instead of keeping it to be told why."""
    peer.settimeout(1.0)
    try:
        return peer.recv(1) == b""
    except socket.timeout:
        return False
    except OSError:  # reset, or the TLS stream cut short
        return True


def test_a_burst_of_refused_connections_is_bounded(children, worlds, certs):
    robot, laptop = worlds
    server, port, _, stamps = streaming(children, robot, laptop, certs)
    before = resident_kib(server)
    stranger = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    stranger.load_verify_locations(certs / "ca.crt")
    stranger.load_cert_chain(certs / "stranger.crt", certs / "stranger.key")
    # A certificate of our CA that no policy line names, opening connection after connection:
    # each is refused; 4 are kept to be told why, the rest closed at once.
    peers = []
    try:
        for _ in range(50):
            raw = socket.create_connection(("127.0.0.1", port), timeout=10)
            peers.append(stranger.wrap_socket(raw, server_hostname="robot"))
        closed = sum(closed_at_once(peer) for peer in peers)
        stamps.grow_by(50, "while refused connections came")
        grown = resident_kib(server) - before
    finally:
        for peer in peers:
            peer.close()
    assert closed == 46, f"{closed} of 50 refused connections closed at once"
    assert grown < PEER_MEMORY_BOUND_KIB, f"the robot grew by {grown} KiB"
    assert server.poll() is None, server.errors.text()
    text = server.errors.text()
    assert text.count("refused stranger at 127.0.0.1:") == 4, text
    kind = "refused connections over the limit"
    wait_until(lambda: refusals(server.errors.text(), kind)[1] == 46,
               "the connections closed at once logged and counted")
    lines, _ = refusals(server.errors.text(), kind)
    assert lines <= 3, server.errors.text()
