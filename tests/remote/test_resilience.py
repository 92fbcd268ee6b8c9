"""A remote link under trouble: a robot killed and restarted mid-stream (the laptop's mirror
resumes in order, no duplicate), peers sending random bytes, malformed frames, oversized
messages and floods of calls while another peer keeps receiving, a peer that stops reading (its stream drops
the oldest messages, counted and logged, the robot's memory does not grow, others go on), and
a slow peer of its own Sink (remote.capnp) seeing the publisher's sequence numbers, with a gap
for each message its stream dropped."""
from __future__ import annotations

import json
import os
import random
import signal
import socket
import ssl
import struct
import subprocess
import threading

from conftest import HORUS, SINK_PEER, connect, free_port, serve
from processes import World, wait_line, wait_until
from test_link import PUBLISHER

# Prints each cmd_vel stamp as it arrives, until killed.
STREAMER = """
import horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel", capacity=512)
print("ready", flush=True)
while True:
    message = topic.recv(timeout=1.0)
    if message is not None:
        print(message.stamp_nanos, flush=True)
"""


class Stamps:
    """The stamps a streaming subscriber prints, collected by a thread of the test."""

    def __init__(self, process) -> None:
        self.seen: list[int] = []
        self._thread = threading.Thread(target=self._read, args=(process,), daemon=True)
        self._thread.start()

    def _read(self, process) -> None:
        for line in process.stdout:
            self.seen.append(int(line))

    def grow_by(self, count: int, what: str) -> None:
        start = len(self.seen)
        wait_until(lambda: len(self.seen) >= start + count, f"{count} more stamps {what}")


def streaming(children, robot, laptop, certs, port: int = 0, rules=("laptop read cmd_vel",)):
    """A publisher on the robot, its server, and a laptop mirroring cmd_vel into a streamer."""
    children.python(PUBLISHER, robot.env())
    server, port = serve(children, robot, certs, *rules, port=port)
    streamer = children.python(STREAMER, laptop.env())
    wait_line(streamer, "ready")
    client = connect(children, laptop, certs, port, "--import", "cmd_vel")
    stamps = Stamps(streamer)
    stamps.grow_by(20, "before any trouble")
    return server, port, client, stamps


def test_mirror_resumes_after_the_robot_restarts(children, worlds, certs):
    robot, laptop = worlds
    server, port, client, stamps = streaming(children, robot, laptop, certs, free_port())
    server.kill()
    server.wait()
    client.errors.wait_for("trying again")
    before = len(stamps.seen)
    serve(children, robot, certs, "laptop read cmd_vel", port=port)
    stamps.grow_by(20, "after the restart")
    seen = stamps.seen
    assert all(a < b for a, b in zip(seen, seen[1:])), "out of order or duplicated"
    assert seen[before] - seen[before - 1] > 1, "the outage left no gap: nothing was restarted"


def laptop_tls(certs) -> ssl.SSLContext:
    """What an authenticated peer (the laptop's certificate) connects with, in Python."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.load_verify_locations(certs / "ca.crt")
    context.load_cert_chain(certs / "laptop.crt", certs / "laptop.key")
    return context


def authenticated(certs, port: int):
    raw = socket.create_connection(("127.0.0.1", port), timeout=10)
    return laptop_tls(certs).wrap_socket(raw, server_hostname="robot")


def send_until_closed(peer, data: bytes) -> None:
    """Sends what a bad peer sends; the robot may close the connection before it is all out."""
    try:
        peer.sendall(data)
    except OSError:  # ssl.SSLError included
        pass


def test_bad_peers_leave_the_others_served(children, worlds, certs):
    robot, laptop = worlds
    server, port, _, stamps = streaming(children, robot, laptop, certs)
    noise = random.Random(27)

    def ended() -> int:
        return server.errors.text().count("disconnected")

    # Random bytes where the TLS handshake should be: refused, with the peer's address.
    with socket.create_connection(("127.0.0.1", port), timeout=10) as plain:
        send_until_closed(plain, noise.randbytes(4096))
    server.errors.wait_for("refused 127.0.0.1:")
    # Random bytes as Cap'n Proto frames, from a peer the policy knows.
    with authenticated(certs, port) as peer:
        send_until_closed(peer, noise.randbytes(65536))
        wait_until(lambda: ended() >= 1, "the garbling peer dropped")
    # A frame announcing a 512 MiB segment, far over the largest message laptop may send.
    with authenticated(certs, port) as peer:
        send_until_closed(peer, struct.pack("<II", 0, 64 * 1024 * 1024) + noise.randbytes(4096))
        wait_until(lambda: ended() >= 2, "the oversized frame refused")
    # A peer that sends nothing and reads nothing while the stream goes on.
    silent = authenticated(certs, port)
    try:
        stamps.grow_by(50, "while bad peers came and went")
    finally:
        silent.close()
    assert server.poll() is None, server.errors.text()
    seen = stamps.seen
    assert all(a < b for a, b in zip(seen, seen[1:])), "out of order or duplicated"


# 900 kB images on camera, 30 a second, until killed.
CAMERA = """
import time, horus
from horus.msg import CompressedImage
camera = horus.Topic(CompressedImage, "camera", capacity=8, max_message_size=1 << 20)
print("ready", flush=True)
i = 0
while True:
    camera.send(CompressedImage(format="rgb8", data=bytes(900_000), width=640, height=480,
                                timestamp_ns=i))
    i += 1
    time.sleep(1 / 30)
"""


def status(world) -> list[dict]:
    listed = subprocess.run([HORUS, "remote", "status", "--json"], env=world.env(),
                            capture_output=True, text=True, check=True)
    return json.loads(listed.stdout)


def resident_kib(process) -> int:
    with open(f"/proc/{process.pid}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:"))


def test_a_peer_that_stops_reading_costs_only_its_own_stream(children, worlds, certs, tmp_path):
    robot, laptop = worlds
    children.python(CAMERA, robot.env())
    server, port, _, stamps = streaming(children, robot, laptop, certs,
                                        rules=("laptop read cmd_vel", "laptop read camera"))
    # A second laptop takes the images, then stops (SIGSTOP): it reads nothing any more.
    stalled_world = World(tmp_path / "shm_c")
    stalled = connect(children, stalled_world, certs, port, "--import", "camera", "--queue", "4")
    stalled.errors.wait_for("importing camera")
    stalled.send_signal(signal.SIGSTOP)
    try:
        server.errors.wait_for("topic camera to laptop: ", limit=30)
        line = server.errors.wait_for("messages dropped so far", limit=30)
        assert "camera" in line
        # `horus remote status` shows the same streams and counts (its file is a second old
        # at most).
        def dropping():
            streams = {row["stream"]: row for row in status(robot)}
            camera = streams.get("topic camera to laptop", {"dropped": 0})
            return camera["dropped"] > 0 and streams
        streams = wait_until(dropping, "the drops in horus remote status")
        assert streams["topic cmd_vel to laptop"]["sent"] > 0
        before = resident_kib(server)
        # About 3 s: some 90 images (80 MB) published for the stalled peer meanwhile.
        stamps.grow_by(300, "while a peer reads nothing")
        assert resident_kib(server) - before < 30 * 1024, "the robot's memory grew"
    finally:
        stalled.send_signal(signal.SIGCONT)
    assert server.poll() is None, server.errors.text()


FLOOD_PEER = os.environ.get("HORUS_REMOTE_FLOOD_PEER", "")  # flood_peer.cpp


def test_a_flood_of_calls_leaves_the_others_served(children, worlds, certs):
    robot, laptop = worlds
    server, port, _, stamps = streaming(children, robot, laptop, certs)
    flood = children.start([FLOOD_PEER, str(port), str(certs)], laptop.env())
    wait_line(flood, "flooding")
    before = resident_kib(server)
    stamps.grow_by(200, "while a peer floods the robot with calls")
    assert flood.poll() is None, flood.errors.text()  # the flood went on all along
    assert server.poll() is None, server.errors.text()
    assert resident_kib(server) - before < 50 * 1024, "the robot's memory grew with the flood"
    seen = stamps.seen
    assert all(a < b for a, b in zip(seen, seen[1:])), "out of order or duplicated"



# Publishes on cmd_vel, new, as fast as it can: the message stamped i is the i-th published on
# it, its ticket.
FAST_PUBLISHER = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel", capacity=1024)
print("ready", flush=True)
i = 0
while True:
    topic.send(CmdVel(stamp_nanos=i))
    i += 1
    if i % 50 == 0:
        time.sleep(0.002)
"""


def test_a_slow_peer_sees_the_publishers_sequence_with_its_drops_as_gaps(children, worlds, certs):
    robot, _ = worlds
    wait_line(children.python(FAST_PUBLISHER, robot.env()), "ready")
    _, port = serve(children, robot, certs, "laptop read cmd_vel")
    # Two messages behind at most, a millisecond for each: once Cap'n Proto's window of
    # messages in flight is full, most of the publisher's drop.
    peer = children.start([SINK_PEER, str(port), str(certs), "cmd_vel", "2", "1"], robot.env())
    rows = []
    while len(rows) < 20000 and not any(b[0] - a[0] > 1 for a, b in zip(rows[-50:], rows[-49:])):
        rows.append(tuple(int(n) for n in wait_line(peer, "").split()))
    rows += [tuple(int(n) for n in wait_line(peer, "").split()) for _ in range(100)]
    assert all(sequence == stamp for sequence, _, stamp in rows), \
        [row for row in rows if row[0] != row[2]][:5]
    gaps = [later[0] - earlier[0] - 1 for earlier, later in zip(rows, rows[1:])]
    assert min(gaps) >= 0 and sum(gaps) > 0, rows[-100:]
    # Each message says how many the sender dropped so far: those its gaps left out (and, when
    # its reader fell a lap behind the ring, a few newer ones).
    dropped = [row[1] for row in rows]
    assert dropped == sorted(dropped) and dropped[-1] >= sum(gaps), (dropped[-1], sum(gaps))
    assert dropped[-1] - dropped[0] <= sum(gaps) + 100, (dropped[0], dropped[-1], sum(gaps))
