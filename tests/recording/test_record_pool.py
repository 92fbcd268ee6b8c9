"""Pool-backed topics (Image, DepthImage, PointCloud) in a recorded session: kept with their data
(encoding horus.pool: the descriptor, then the bytes it covers), read back by PyPI `mcap`, shown
by `horus record info`, replayed into a live subscriber with the recorded pixels, and exported for
Foxglove as RawImage and PointCloud validated against their schemas."""
from __future__ import annotations

import base64
import json
import signal
import struct

import numpy as np
from mcap.reader import make_reader

import horus
from horus import Node, Scheduler
from horus.msg import ImageDescriptor

from processes import wait_until
from test_record import export_validated, run_horus
from test_record_sessions import start_recording, subscribers

FRAMES = 3  # fewer than a pool topic's 4 slots: neither the recorder nor a subscriber can lag


def pixels(i: int) -> np.ndarray:
    return ((np.arange(24 * 32 * 3).reshape(24, 32, 3) * 7 + i) % 251).astype(np.uint8)


def depths(i: int) -> np.ndarray:
    return (np.arange(6 * 8, dtype=np.float32).reshape(6, 8) + i) / 4


def points(i: int) -> np.ndarray:
    return (np.arange(50 * 3, dtype=np.float32).reshape(50, 3) - i) / 2


def record_pool_session() -> str:
    ticks = []

    def film(node):
        i = len(ticks)
        ticks.append(i)
        node.send("camera", horus.Image.from_numpy(pixels(i)))
        node.send("depth", horus.DepthImage.from_numpy(depths(i)))
        node.send("lidar", horus.PointCloud.from_numpy(points(i)))

    scheduler = Scheduler(tick_rate=100, recording=True)
    scheduler.add(Node(name="sensors", tick=film, order=0,
                       pubs={"camera": horus.Image, "depth": horus.DepthImage,
                             "lidar": horus.PointCloud}))
    for _ in range(FRAMES):
        scheduler.tick_once()
    [path] = scheduler.stop_recording()
    return path


def test_a_recorded_pool_session_keeps_the_data_and_info_shows_it():
    path = record_pool_session()
    data: dict[str, list[bytes]] = {}
    with open(path, "rb") as stream:
        for schema, channel, message in make_reader(stream, validate_crcs=True).iter_messages():
            if channel.topic == "/horus/ticks":
                continue
            assert channel.message_encoding == "horus.pool"
            assert schema.encoding == "horus.hmsg" and schema.name.endswith("Descriptor")
            size = int(channel.metadata["horus.payload_size"])
            assert channel.metadata["horus.type"] == schema.name
            if channel.topic == "camera":
                descriptor = ImageDescriptor.from_bytes(message.data[:size])
                assert (descriptor.width, descriptor.height) == (32, 24)
                assert descriptor.data_size == len(message.data) - size
                # The block it named ended with the run.
                assert (descriptor.block.pool_id, descriptor.block.generation) == (0, 0)
            data.setdefault(channel.topic, []).append(message.data[size:])
    assert data["camera"] == [pixels(i).tobytes() for i in range(FRAMES)]
    assert data["depth"] == [depths(i).tobytes() for i in range(FRAMES)]
    assert data["lidar"] == [points(i).tobytes() for i in range(FRAMES)]

    described = json.loads(run_horus("record", "info", path, "--json", "--check").stdout)
    topics = {t["topic"]: t for t in described["topics"]}
    assert topics["camera"]["type"] == "horus.msg.ImageDescriptor"
    assert topics["camera"]["encoding"] == "horus.pool"
    assert [topics[t]["messages"] for t in ("camera", "depth", "lidar")] == [FRAMES] * 3
    assert described["lost"] == 0


def test_horus_record_keeps_the_pixels_of_another_process_images(tmp_path):
    out = tmp_path / "camera.mcap"
    camera = horus.Topic(horus.Image, "camera")
    recorder = start_recording("camera", "-o", str(out))
    wait_until(lambda: subscribers("camera") >= 1, "horus-record to subscribe to camera", limit=30)
    for i in range(FRAMES):  # the ring keeps them alive until the recorder drains it at SIGINT
        assert camera.send(horus.Image.from_numpy(pixels(i)))
    recorder.send_signal(signal.SIGINT)
    _, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr
    with open(out, "rb") as stream:
        recorded = [(channel.message_encoding, message.data[
                     int(channel.metadata["horus.payload_size"]):])
                    for _, channel, message in make_reader(stream, validate_crcs=True)
                    .iter_messages()]
    assert recorded == [("horus.pool", pixels(i).tobytes()) for i in range(FRAMES)]


IMAGE_SUBSCRIBER = """
import numpy as np
import horus
topic = horus.Topic(horus.Image, "camera")
print("ready", flush=True)
for _ in range({count}):
    image = topic.recv(timeout=30)
    if image is None:
        print("timeout", flush=True)
        break
    print(image.width, image.height, np.asarray(image).tobytes().hex(), flush=True)
print("refused", topic.refused(), flush=True)
"""


def test_a_recorded_image_session_replays_into_a_live_subscriber_with_its_pixels(children):
    path = record_pool_session()
    subscriber = children.python(IMAGE_SUBSCRIBER.format(count=FRAMES))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", path, "--topics", "camera")
    assert replayed.returncode == 0, replayed.stderr
    assert f"replayed {FRAMES} messages on 1 topics" in replayed.stdout
    out, _ = subscriber.communicate(timeout=60)
    lines = out.splitlines()
    assert lines[:FRAMES] == [f"32 24 {pixels(i).tobytes().hex()}" for i in range(FRAMES)]
    assert lines[FRAMES:] == ["refused 0"]


def test_foxglove_export_draws_recorded_images_depth_and_clouds(tmp_path):
    path = record_pool_session()
    exported = export_validated(path, tmp_path / "foxglove.mcap")
    by_topic: dict[str, list] = {}
    for topic, schema, value in exported:
        by_topic.setdefault(topic, []).append((schema, value))

    camera = by_topic["camera"]
    assert [schema for schema, _ in camera] == ["foxglove.RawImage"] * FRAMES
    for i, (_, value) in enumerate(camera):
        assert (value["width"], value["height"], value["encoding"], value["step"]) == \
            (32, 24, "rgb8", 96)
        assert base64.b64decode(value["data"]) == pixels(i).tobytes()

    depth = by_topic["depth"]
    assert [schema for schema, _ in depth] == ["foxglove.RawImage"] * FRAMES
    for i, (_, value) in enumerate(depth):
        assert (value["width"], value["height"], value["encoding"], value["step"]) == \
            (8, 6, "32FC1", 32)
        assert base64.b64decode(value["data"]) == depths(i).tobytes()

    lidar = by_topic["lidar"]
    assert [schema for schema, _ in lidar] == ["foxglove.PointCloud"] * FRAMES
    for i, (_, value) in enumerate(lidar):
        assert value["point_stride"] == 12
        assert [f["name"] for f in value["fields"]] == ["x", "y", "z"]
        data = base64.b64decode(value["data"])
        assert struct.unpack(f"<{len(data) // 4}f", data) == tuple(points(i).ravel().tolist())
