"""The live view (horus-view) with clients that are not ours: Foxglove's own client library
(@foxglove/ws-protocol's FoxgloveClient over npm `ws`, client_check.mjs) connecting with each
subprotocol, decoding a POD, a serialized and an image topic with the schemas their channels
advertise, calling a service and publishing into a topic; and a client that stops reading, which
must cost neither the other clients their rate nor the server its memory."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time

import horus
import numpy as np
from conftest import (VIEW, Publishing, RawWebSocket, run_node_client,
                      websocket_handshake)
from horus.msg import CmdVel, OccupancyGrid

SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
WIDTH, HEIGHT = 640, 480


def image_pixels() -> np.ndarray:
    """640x480 rgb8 whose every byte says where it is, so a decoded head and sum prove the
    pixels crossed whole and in order."""
    y, x, c = np.indices((HEIGHT, WIDTH, 3))
    return ((x + 3 * y + 7 * c) % 251).astype(np.uint8)


class Publishers(Publishing):
    """CmdVel, OccupancyGrid (serialized) and Image topics published from this process until
    the `with` ends, every message the same but for CmdVel's count, so that any a client takes
    can be checked."""

    def __init__(self) -> None:
        self.cmd_vel = horus.Topic(CmdVel, "cmd_vel")
        self.map = horus.Topic(OccupancyGrid, "map")
        self.camera = horus.Topic(horus.Image, "camera")
        self.pixels = image_pixels()
        self.grid = OccupancyGrid(resolution=0.25, width=3, height=2,
                                  data=[0, 100, -1, 0, 0, 100], frame_id="map",
                                  metadata="view test")
        super().__init__()

    def publish(self, count: int) -> None:
        self.cmd_vel.send(CmdVel(stamp_nanos=count, linear=1.5, angular=-0.25))
        if count % 4 == 0:
            self.map.send(self.grid)
            self.camera.send(horus.Image.from_numpy(self.pixels))


def successful_runs(result: dict) -> dict:
    """{subprotocol: run} of client_check.mjs's result; fails naming what went wrong in any."""
    for subprotocol, run in result["runs"].items():
        assert "error" not in run, f"{subprotocol}: {run['error']}; statuses {run['statuses']}"
        assert run["protocol"] == subprotocol, run["protocol"]
        refusals = [s for s in run["statuses"] if s.get("level", 0) >= 2 or "clientError" in s]
        assert not refusals, f"{subprotocol}: {refusals}"
    return result["runs"]


def test_foxglove_client_decodes_each_kind_with_the_advertised_schema(view_server):
    with Publishers() as published:
        result = run_node_client(view_server.url, {
            "subprotocols": SUBPROTOCOLS,
            "topics": ["cmd_vel", "map", "camera"],
            "subscribe": {"cmd_vel": 3, "map": 1, "camera": 1}})

    for subprotocol, run in successful_runs(result).items():
        channels = {channel["topic"]: channel for channel in run["channels"]}
        assert (channels["cmd_vel"]["encoding"], channels["cmd_vel"]["schemaName"]) == (
            "json", "horus.msg.CmdVel")
        assert (channels["map"]["encoding"], channels["map"]["schemaName"]) == (
            "json", "horus.msg.OccupancyGrid")
        assert (channels["camera"]["encoding"], channels["camera"]["schemaName"]) == (
            "protobuf", "foxglove.RawImage")

        messages = run["messages"]
        commands_seen = messages["cmd_vel"]["decoded"]
        assert [(m["linear"], m["angular"]) for m in commands_seen] == [(1.5, -0.25)] * 3
        # u64 is a string of decimal digits (a JSON number is a double), counting up.
        stamps = [int(m["stamp_nanos"]) for m in commands_seen]
        assert stamps == sorted(stamps) and len(set(stamps)) == 3, stamps

        grid = messages["map"]["decoded"][0]
        assert (grid["width"], grid["height"], grid["resolution"], grid["frame_id"],
                grid["metadata"], grid["data"]) == (3, 2, 0.25, "map", "view test",
                                                    [0, 100, -1, 0, 0, 100]), grid

        image = messages["camera"]["decoded"][0]
        assert (image["width"], image["height"], image["encoding"], image["step"],
                image["frame_id"]) == (WIDTH, HEIGHT, "rgb8", WIDTH * 3, "camera"), image
        pixels = published.pixels.tobytes()
        assert image["data"]["length"] == len(pixels)
        assert image["data"]["head"] == list(pixels[:16])
        assert image["data"]["sum"] == sum(pixels) % 2**32


def test_foxglove_client_calls_a_service(view_server, view_test_types):
    sys.path.insert(0, view_test_types)
    from view_test import Scale, ScaleResponse

    with horus.ServiceServer(
            Scale, lambda request: ScaleResponse(product=request.value * request.factor,
                                                 note=f"{request.value} x {request.factor}")):
        result = run_node_client(view_server.url, {
            "subprotocols": SUBPROTOCOLS,
            "call": {"service": "Scale", "request": {"value": 2.5, "factor": 4.0}}})

    for run in successful_runs(result).values():
        assert run["call"] == {"response": {"product": 10.0, "note": "2.5 x 4.0"},
                               "encoding": "json"}, run["call"]


def test_foxglove_client_publishes_into_a_topic(view_server):
    # Opened before the client connects, so the topic exists for the view to advertise.
    commands = horus.Topic(CmdVel, "cmd_in")
    result = run_node_client(view_server.url, {
        "subprotocols": SUBPROTOCOLS,
        "topics": ["cmd_in"],
        "publish": {"topic": "cmd_in", "messages": [
            {"stamp_nanos": "77", "linear": 7.5, "angular": -1.25}] * 5}})

    for run in successful_runs(result).values():
        assert run["published"] == 5
    received = []
    while (message := commands.try_recv()) is not None:
        received.append(message)
    assert len(received) == 5 * len(SUBPROTOCOLS), received
    assert all((m.stamp_nanos, m.linear, m.angular) == (77, 7.5, -1.25) for m in received)


def test_an_unknown_subprotocol_is_refused(view_server):
    with socket.create_connection(("127.0.0.1", view_server.port), timeout=5) as connection:
        status, _ = websocket_handshake(connection, view_server.port, "mqtt")
    assert status.startswith("HTTP/1.1 400"), status


# A WebSocket client of our own that reads only what it chooses: the stalled viewer.

def rss_bytes(pid: int) -> int:
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError(f"no VmRSS in /proc/{pid}/status")


def view_status(namespace: str) -> dict:
    """What `horus-view status` says of the server of `namespace`, as JSON."""
    done = subprocess.run([VIEW, "status", "--namespace", namespace], capture_output=True,
                          text=True, timeout=10)
    assert done.returncode == 0, f"horus-view status failed: {done.stdout} {done.stderr}"
    return json.loads(done.stdout)


# Published by a child of its own (the test's process is busy measuring): CmdVel at 1 kHz on
# "fast" and 640x480 rgb8 images at 30 Hz on "camera", on deadlines, for argv[1] seconds; prints
# "ready" once both topics exist, then {"fast": rate, "camera": rate} at the end.
FLOOD_PUBLISHER = """
import json, sys, time
import horus, numpy as np
from horus.msg import CmdVel
seconds = float(sys.argv[1])
fast = horus.Topic(CmdVel, "fast")
camera = horus.Topic(horus.Image, "camera")
pixels = np.full((480, 640, 3), 90, dtype=np.uint8)
camera.send(horus.Image.from_numpy(pixels))
print("ready", flush=True)
start = time.monotonic()
sent = {"fast": 0, "camera": 0}
tick = 0
while (now := time.monotonic()) - start < seconds:
    deadline = start + tick / 1000
    if deadline > now:
        time.sleep(deadline - now)
    tick += 1
    fast.send(CmdVel(stamp_nanos=tick, linear=float(tick % 100), angular=0.0))
    sent["fast"] += 1
    if tick % 33 == 0:
        camera.send(horus.Image.from_numpy(pixels))
        sent["camera"] += 1
elapsed = time.monotonic() - start
print(json.dumps({topic: count / elapsed for topic, count in sent.items()}), flush=True)
"""


def test_a_stalled_client_costs_the_others_nothing(view_server, namespace, children):
    publisher = children.python(FLOOD_PUBLISHER, dict(os.environ), "14")
    assert publisher.stdout.readline().strip() == "ready", publisher.errors.text()

    # The stalled viewer: subscribes to both topics, then never reads again.
    connection = socket.socket()
    # A small receive buffer: the server's writes back up soon once this stops reading.
    connection.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    connection.settimeout(10)
    connection.connect(("127.0.0.1", view_server.port))
    stalled = RawWebSocket(connection, view_server.port)
    channel_ids = {}
    while not {"fast", "camera"} <= channel_ids.keys():
        opcode, payload = stalled.read_frame()
        if opcode == 1:
            message = json.loads(payload)
            if message.get("op") == "advertise":
                channel_ids.update({c["topic"]: c["id"] for c in message["channels"]})
    stalled.send_text(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": 1, "channelId": channel_ids["fast"]}, {"id": 2, "channelId": channel_ids["camera"]}]}))

    time.sleep(1.5)  # the stalled socket's buffers fill; the server's heap settles
    baseline = rss_bytes(view_server.process.pid)
    peak = [baseline]
    sampling = threading.Event()

    def sample() -> None:
        while not sampling.wait(0.1):
            peak[0] = max(peak[0], rss_bytes(view_server.process.pid))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    try:
        result = run_node_client(view_server.url, {
            "topics": ["fast", "camera"],
            "measure": {"topics": ["fast", "camera"], "warmup_s": 1, "seconds": 5}})
    finally:
        sampling.set()
        sampler.join()
    status = view_status(namespace)
    published = json.loads(publisher.stdout.readline() or "null")
    assert published, f"the publisher ended without its rates: {publisher.errors.text()}"
    stalled.close()

    # The robot's publisher kept its rates: a viewer never makes send() wait.
    for topic, target in (("fast", 1000.0), ("camera", 1000.0 / 33)):
        assert published[topic] >= 0.8 * target, (
            f"{topic}: the publisher managed {published[topic]:.1f}/s of {target:.1f}/s "
            "while a client stalled")
    run = result["runs"][SUBPROTOCOLS[0]]
    assert "error" not in run, run
    # A server blocked by the stalled socket would leave the reading client next to nothing; half
    # the rate leaves room for a loaded machine, where the reading client itself falls behind.
    for topic in ("fast", "camera"):
        received = run["measured"][topic]["rate"]
        assert received >= 0.5 * published[topic], (
            f"{topic}: published {published[topic]:.1f}/s, the reading client got "
            f"{received:.1f}/s while another client stalled")
    growth = peak[0] - baseline
    assert growth < 64 * 2**20, f"horus-view grew by {growth / 2**20:.1f} MiB in 6 s"
    # The stalled client's messages were dropped (latest wins), and counted.
    assert status["counters"]["messages_dropped"] > 0, status
