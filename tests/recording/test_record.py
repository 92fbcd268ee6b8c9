"""`horus record` over recordings written by horus.mcap (runtime/python/horus/mcap.py), checked
with PyPI `mcap` (an MCAP reader that is not ours) and `jsonschema`; replay into a live subscriber
process."""
from __future__ import annotations

import base64
import functools
import json
import os
import subprocess
import zlib

import jsonschema
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd, Footer, MessageIndex
from mcap.stream_reader import StreamReader

from horus import mcap as horus_mcap
from horus.msg import CmdVel, CompressedImage, LaserScan, Path, PoseStamped, TransformStamped

HORUS = os.environ.get("HORUS_CLI", "")


def run_horus(*args: str) -> subprocess.CompletedProcess:
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_record)"
    return subprocess.run([HORUS, *args], capture_output=True, text=True, timeout=60)


def write_recording(path, topics: dict, *, fingerprint_of=None, chunk_size=4096,
                    schema_text_of=None, description_of=None) -> None:
    """A recording as the recorder writes it: `topics` maps a topic to (class, [messages]);
    `schema_text_of` replaces a topic's stored schema text, `description_of` gives it a type
    description (channel metadata horus.description)."""
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream, chunk_size=chunk_size)
        writer.add_metadata("horus.session", {"session": "test", "namespace": "t"})
        channels = {}
        for topic, (cls, _) in topics.items():
            meta = cls.__horus__
            text = (schema_text_of or {}).get(topic, meta.schema)
            schema = writer.add_schema(meta.name, "horus.hmsg", text.encode())
            fingerprint = (fingerprint_of or {}).get(topic, meta.fingerprint)
            metadata = {"horus.fingerprint": f"{fingerprint:016x}", "horus.type": meta.name}
            metadata.update(horus_mcap.description_metadata((description_of or {}).get(topic, b"")))
            if meta.is_pod:
                metadata["horus.payload_size"] = str(meta.size)
            channels[topic] = writer.add_channel(
                topic, "horus.pod" if meta.is_pod else "horus.msgpack", schema, metadata)
        time_ns = 1_000_000_000
        for index in range(max(len(m) for _, m in topics.values())):
            for topic, (_, messages) in topics.items():
                if index < len(messages):
                    writer.add_message(channels[topic], time_ns, messages[index].to_bytes(),
                                       sequence=index)
                    time_ns += 1_000_000
        writer.add_metadata("horus.recorder", {"lost_total": "0"})
        writer.finish()


@functools.cache
def foxglove_schemas() -> dict:
    """Foxglove's own JSON Schemas by name ("foxglove.RawImage": {...}), from npm
    @foxglove/schemas (the ctest fixture foxglove_schemas fetches them)."""
    path = os.environ.get("HORUS_FOXGLOVE_SCHEMAS", "")
    assert path and os.path.isfile(path), (
        "HORUS_FOXGLOVE_SCHEMAS names Foxglove's schemas; run this suite through ctest "
        "(pytest_record, after its fixture foxglove_schemas)")
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def export_validated(path, out) -> list[tuple[str, str, object]]:
    """Exports `path` for Foxglove into `out`, reads it back with PyPI mcap (CRCs checked) and
    validates every JSON message: a message of a Foxglove well-known schema against Foxglove's
    published one, any other against its channel's schema. (topic, schema name, value)."""
    exported = run_horus("record", "export", str(path), "--foxglove", str(out))
    assert exported.returncode == 0, exported.stderr
    messages = []
    with open(out, "rb") as stream:
        for schema, channel, message in make_reader(stream, validate_crcs=True).iter_messages():
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            value = json.loads(message.data)
            if schema.name.startswith("foxglove."):
                assert schema.name in foxglove_schemas(), f"Foxglove has no schema {schema.name}"
                jsonschema.validate(value, foxglove_schemas()[schema.name])
            else:
                jsonschema.validate(value, json.loads(schema.data))
            messages.append((channel.topic, schema.name, value))
    return messages


def cmd_vels(count: int, offset: float = 0.0) -> list:
    return [CmdVel(linear=i + offset, angular=-i) for i in range(count)]


def test_independent_reader_accepts_crcs_index_and_summary(tmp_path):
    path = tmp_path / "a.mcap"
    write_recording(path, {"cmd": (CmdVel, cmd_vels(500))})
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        assert summary.statistics.message_count == 500
        assert len(summary.chunk_indexes) > 1
        received = [CmdVel.from_bytes(m.data).linear for _, _, m in reader.iter_messages()]
    assert received == [float(i) for i in range(500)]
    # Every record, chunk CRCs included; each message index entry points at a message record.
    with open(path, "rb") as stream:
        records = list(StreamReader(stream, validate_crcs=True, emit_chunks=True).records)
    chunks = [r for r in records if isinstance(r, Chunk)]
    indexes = [r for r in records if isinstance(r, MessageIndex)]
    assert len(indexes) == len(chunks)
    import zstandard
    for chunk, index in zip(chunks, indexes):
        data = zstandard.ZstdDecompressor().decompress(chunk.data,
                                                       max_output_size=chunk.uncompressed_size)
        assert zlib.crc32(data) == chunk.uncompressed_crc
        for _, offset in index.records:
            assert data[offset] == horus_mcap.OP_MESSAGE
    data_end = next(r for r in records if isinstance(r, DataEnd))
    raw = path.read_bytes()
    footer = next(r for r in records if isinstance(r, Footer))
    assert data_end.data_section_crc == zlib.crc32(raw[:footer.summary_start - 13])
    assert footer.summary_crc == zlib.crc32(raw[footer.summary_start:-8 - 4])


def test_info_reads_a_cut_file_and_repair_gives_it_a_valid_summary(tmp_path):
    path = tmp_path / "cut.mcap"
    write_recording(path, {"cmd": (CmdVel, cmd_vels(1000))})
    whole = path.read_bytes()
    path.write_bytes(whole[:len(whole) // 2])  # as kill -9 leaves it: half a chunk at the end

    info = run_horus("record", "info", str(path), "--json")
    assert info.returncode == 0, info.stderr
    described = json.loads(info.stdout)
    assert described["summary"] is False and described["cut_bytes"] > 0
    assert described["lost"] is None  # no horus.recorder metadata: the recorder did not finish
    kept = described["messages"]
    assert 0 < kept < 1000
    with pytest.raises(Exception):
        with open(path, "rb") as stream:
            make_reader(stream, validate_crcs=True).get_summary().statistics

    repaired = run_horus("record", "repair", str(path))
    assert repaired.returncode == 0, repaired.stderr
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        assert reader.get_summary().statistics.message_count == kept
        values = [CmdVel.from_bytes(m.data).linear for _, _, m in reader.iter_messages()]
    assert values == [float(i) for i in range(kept)]
    again = run_horus("record", "repair", str(path))
    assert again.returncode == 1 and "nothing to repair" in again.stderr


def test_list_info_and_delete_by_name(recordings):
    write_recording(recordings / "session_2026_01_02_030405.mcap",
                    {"cmd": (CmdVel, cmd_vels(10)), "scan": (LaserScan, [LaserScan()] * 3)})
    listed = run_horus("record", "list")
    assert listed.stdout.split() == ["session_2026_01_02_030405"]
    info = json.loads(run_horus("record", "info", "session_2026_01_02_030405", "--json").stdout)
    assert info["summary"] is True and info["lost"] == 0
    assert {t["topic"]: t["messages"] for t in info["topics"]} == {"cmd": 10, "scan": 3}
    assert {t["type"] for t in info["topics"]} == {"horus.msg.CmdVel", "horus.msg.LaserScan"}
    assert run_horus("record", "delete", "session_2026_01_02_030405").returncode == 0
    assert run_horus("record", "list").stdout == ""
    missing = run_horus("record", "delete", "session_2026_01_02_030405")
    assert missing.returncode == 1 and "no recording" in missing.stderr
    assert run_horus("record", "info", "nope").returncode == 1


SUBSCRIBER = """
import horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd", capacity=1024)
print("ready", flush=True)
for _ in range({count}):
    message = topic.recv(timeout=30)
    if message is None:
        print("timeout", flush=True)
        break
    print(message.to_bytes().hex(), flush=True)
"""


def test_export_and_replay_decode_with_the_description_a_channel_carries(tmp_path, children):
    # A schema text that does not compile: only the carried description can decode the topic.
    path = tmp_path / "described.mcap"
    broken = {"cmd": "message horus.msg.CmdVel {\n  linear: f33,\n}\n"}
    write_recording(path, {"cmd": (CmdVel, cmd_vels(5))}, schema_text_of=broken,
                    description_of={"cmd": CmdVel.__horus__.description})
    exported = export_validated(path, tmp_path / "described_foxglove.mcap")
    assert [value["linear"] for _, _, value in exported] == [m.linear for m in cmd_vels(5)]
    subscriber = children.python(SUBSCRIBER.format(count=5))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--rate", "20")
    assert replayed.returncode == 0, replayed.stderr
    received, _ = subscriber.communicate(timeout=60)
    assert received.split() == [m.to_bytes().hex() for m in cmd_vels(5)]

    # A description of another type than the channel names is refused, naming both.
    path = tmp_path / "mismatched.mcap"
    write_recording(path, {"cmd": (CmdVel, cmd_vels(2))},
                    description_of={"cmd": LaserScan.__horus__.description})
    for action in (["export", str(path), "--foxglove", str(tmp_path / "out.mcap")],
                   ["replay", str(path)]):
        refused = run_horus("record", *action)
        assert refused.returncode == 1 and refused.stderr.count("\n") == 1, refused
        assert "horus.msg.LaserScan" in refused.stderr and "horus.msg.CmdVel" in refused.stderr, \
            refused.stderr


def test_replay_delivers_every_message_in_order_to_a_live_subscriber(tmp_path, children):
    messages = cmd_vels(200, offset=0.5)
    path = tmp_path / "r.mcap"
    write_recording(path, {"cmd": (CmdVel, messages)})
    subscriber = children.python(SUBSCRIBER.format(count=len(messages)))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--rate", "20")
    assert replayed.returncode == 0, replayed.stderr
    assert "replayed 200 messages on 1 topics" in replayed.stdout
    out, _ = subscriber.communicate(timeout=60)
    assert out.split() == [m.to_bytes().hex() for m in messages]


def test_replay_refuses_a_type_whose_fingerprint_changed(tmp_path):
    path = tmp_path / "old.mcap"
    old = CmdVel.__horus__.fingerprint ^ 0x1
    write_recording(path, {"cmd": (CmdVel, cmd_vels(3))}, fingerprint_of={"cmd": old})
    refused = run_horus("record", "replay", str(path))
    assert refused.returncode == 1
    assert "horus.msg.CmdVel changed since the recording" in refused.stderr
    assert f"{old:016x}" in refused.stderr


def test_diff_reports_the_first_differing_message_per_topic(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    first = cmd_vels(50)
    second = list(first)
    second[17] = CmdVel(linear=99.0, angular=0.0)
    write_recording(a, {"cmd": (CmdVel, first), "scan": (LaserScan, [LaserScan()] * 4)})
    write_recording(b, {"cmd": (CmdVel, second), "scan": (LaserScan, [LaserScan()] * 4)})
    result = run_horus("record", "diff", str(a), str(b), "--json")
    assert result.returncode == 1
    rows = json.loads(result.stdout)
    assert [(r["topic"], r["index"]) for r in rows] == [("cmd", 17)]
    same = run_horus("record", "diff", str(a), str(a))
    assert same.returncode == 0 and "no difference" in same.stdout


def test_foxglove_export_validates_every_message_against_its_schema(tmp_path):
    scan = LaserScan(angle_min=-1.0, angle_max=1.0, timestamp_ns=5_000_000_123)
    scan.ranges[0] = float("nan")
    scan.ranges[1] = 2.5
    pose = PoseStamped(frame_id="map", timestamp_ns=7)
    pose.pose.position.x = 1.5
    transform = TransformStamped(translation=[1.0, 2.0, 3.0], rotation=[0.0, 0.0, 0.0, 1.0])
    jpeg = CompressedImage(format="jpeg", width=2, height=1, data=b"\xff\xd8\xff\xd9")
    route = Path(waypoint_count=2, timestamp_ns=9)
    route.waypoints[0].pose.x = 2.0
    route.waypoints[1].pose.theta = float("nan")
    path, out = tmp_path / "f.mcap", tmp_path / "foxglove.mcap"
    write_recording(path, {"scan": (LaserScan, [scan] * 3), "pose": (PoseStamped, [pose] * 2),
                           "tf": (TransformStamped, [transform]), "jpeg": (CompressedImage, [jpeg]),
                           "route": (Path, [route]), "cmd": (CmdVel, cmd_vels(5))})
    seen = {}
    for topic, schema_name, value in export_validated(path, out):
        seen.setdefault(topic, (schema_name, value))
    assert {t: s for t, (s, _) in seen.items()} == {
        "scan": "foxglove.LaserScan", "pose": "foxglove.PoseInFrame",
        "tf": "foxglove.FrameTransform", "jpeg": "foxglove.CompressedImage",
        "route": "foxglove.PosesInFrame", "cmd": "horus.msg.CmdVel"}
    assert seen["jpeg"][1]["format"] == "jpeg"
    assert base64.b64decode(seen["jpeg"][1]["data"]) == b"\xff\xd8\xff\xd9"
    scan_json = seen["scan"][1]
    assert scan_json["timestamp"] == {"sec": 5, "nsec": 123}
    assert scan_json["ranges"][:2] == [0.0, 2.5] and len(scan_json["ranges"]) == 360
    assert seen["pose"][1]["frame_id"] == "map"
    assert seen["pose"][1]["pose"]["position"]["x"] == 1.5
    assert seen["tf"][1]["translation"] == {"x": 1.0, "y": 2.0, "z": 3.0}
    # The path's two valid waypoints of 256, named after the topic; no heading (NaN): no turn.
    route_json = seen["route"][1]
    assert route_json["frame_id"] == "route" and route_json["timestamp"] == {"sec": 0, "nsec": 9}
    assert [p["position"] for p in route_json["poses"]] == [{"x": 2.0, "y": 0.0, "z": 0.0},
                                                             {"x": 0.0, "y": 0.0, "z": 0.0}]
    assert route_json["poses"][1]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    assert seen["cmd"][1] == {"linear": 0.0, "angular": 0.0, "stamp_nanos": "0"}


def test_a_file_that_is_not_mcap_is_refused_clearly(tmp_path):
    path = tmp_path / "junk.mcap"
    path.write_bytes(b"not an mcap file at all")
    result = run_horus("record", "info", str(path), "--check")
    assert result.returncode == 1 and "not an MCAP file" in result.stderr
    corrupt = tmp_path / "corrupt.mcap"
    write_recording(corrupt, {"cmd": (CmdVel, cmd_vels(200))})
    walked = horus_mcap.Reader(str(corrupt))
    for _ in walked:
        pass
    chunk = walked.chunk_indexes[0]
    raw = bytearray(corrupt.read_bytes())
    raw[chunk.chunk_start_offset + chunk.chunk_length - 10] ^= 0xFF  # in its compressed records
    corrupt.write_bytes(bytes(raw))
    result = run_horus("record", "info", str(corrupt), "--check")
    assert result.returncode == 1
    assert f"offset {chunk.chunk_start_offset}" in result.stderr


def generate(tmp_path, language: str, *files: str) -> str:
    out = tmp_path / f"out_{language}"
    subprocess.run([os.environ["HORUS_GEN_PROGRAM"], "generate", "--lang", language, "--out",
                    str(out), "-I", os.environ["HORUS_SCHEMA_DIR"], *files], check=True)
    return str(out)


def standard_schema_files() -> list[str]:
    folder = os.path.join(os.environ["HORUS_SCHEMA_DIR"], "horus", "msg")
    return sorted(os.path.join(folder, f) for f in os.listdir(folder) if f.endswith(".hmsg"))


def without_descriptions(schema):
    if isinstance(schema, dict):
        return {k: without_descriptions(v) for k, v in schema.items() if k != "description"}
    if isinstance(schema, list):
        return [without_descriptions(v) for v in schema]
    return schema


def test_horus_gen_jsonschema_describes_what_the_export_writes_for_every_standard_type(tmp_path):
    import horus.msg
    from horus import foxglove as horus_foxglove
    from horus import typedesc
    first = generate(tmp_path, "jsonschema", *standard_schema_files())
    schemas = {}
    for folder, _, names in os.walk(os.path.join(first, "jsonschema")):
        for name in names:
            with open(os.path.join(folder, name), encoding="utf-8") as handle:
                text = handle.read()
            schema = json.loads(text)
            jsonschema.Draft202012Validator.check_schema(schema)
            schemas[schema["title"]] = (text, schema)
    assert len(schemas) > 50
    # Deterministic: a second run writes the same bytes.
    second = generate(tmp_path / "again", "jsonschema", *standard_schema_files())
    for title, (text, _) in schemas.items():
        package, name = title.rsplit(".", 1)
        with open(os.path.join(second, "jsonschema", *package.split("."), f"{name}.schema.json"),
                  encoding="utf-8") as handle:
            assert handle.read() == text
    checked = 0
    for title, (_, schema) in schemas.items():
        cls = getattr(horus.msg, title.rsplit(".", 1)[1], None)
        if cls is None or not hasattr(cls.__horus__, "fields"):
            continue  # an enum
        value = horus_foxglove.plain_json(typedesc.to_plain(cls()))
        jsonschema.validate(value, schema)
        # The export makes the same schema from the type's description (the schema text a
        # recording stores has no doc comments: descriptions aside).
        info = cls.__horus__
        exported = horus_foxglove.generated_json_schema(
            title, typedesc.load_type(info.name, info.schema, info.fingerprint))
        assert without_descriptions(exported) == without_descriptions(
            {k: v for k, v in schema.items() if k != "$comment"}), title
        checked += 1
    assert checked > 50
    # A value of the wrong kind is rejected, so the validation above can fail.
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"linear": "fast", "angular": 0.0, "stamp_nanos": 0},
                            schemas["horus.msg.CmdVel"][1])


USER_TYPES = """package demo;

import "horus/msg/vision.hmsg";

/// A camera frame that carries its pixels.
Frame {
    width: u32,
    height: u32,
    step: u32,
    encoding: horus.msg.ImageEncoding,
    data: bytes,
    frame_id: string<16>,
    timestamp_ns: u64,
}

/// A point cloud that carries its points.
Cloud {
    point_count: u64,
    fields_per_point: u32,
    dtype: horus.msg.TensorDtype,
    data: bytes,
    frame_id: string<16>,
    timestamp_ns: u64,
}
"""


def test_foxglove_export_maps_messages_carrying_pixels_or_points_by_shape(tmp_path):
    schema_file = tmp_path / "demo" / "types.hmsg"
    schema_file.parent.mkdir()
    schema_file.write_text(USER_TYPES)
    sys_path = generate(tmp_path, "python", str(schema_file))
    import sys
    sys.path.insert(0, os.path.join(sys_path, "python"))
    try:
        from demo import Cloud, Frame
    finally:
        sys.path.pop(0)
    from horus.msg import ImageEncoding, TensorDtype
    pixels = bytes(range(12))
    frame = Frame(width=2, height=2, step=6, encoding=ImageEncoding.Rgb8, data=pixels,
                  frame_id="cam", timestamp_ns=3)
    points = b"".join(v.to_bytes(4, "little") for v in range(6))  # two XYZ points, as f32 bits
    cloud = Cloud(point_count=2, fields_per_point=3, dtype=TensorDtype.F32, data=points,
                  frame_id="lidar", timestamp_ns=4)
    path, out = tmp_path / "user.mcap", tmp_path / "user_foxglove.mcap"
    write_recording(path, {"camera": (Frame, [frame]), "cloud": (Cloud, [cloud])})
    seen = {topic: (name, value) for topic, name, value in export_validated(path, out)}
    name, image = seen["camera"]
    assert name == "foxglove.RawImage"
    assert (image["width"], image["height"], image["step"], image["encoding"],
            image["frame_id"]) == (2, 2, 6, "rgb8", "cam")
    assert base64.b64decode(image["data"]) == pixels
    name, cloud_json = seen["cloud"]
    assert name == "foxglove.PointCloud"
    assert cloud_json["point_stride"] == 12
    assert [(f["name"], f["offset"], f["type"]) for f in cloud_json["fields"]] == [
        ("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    assert base64.b64decode(cloud_json["data"]) == points


def test_replay_selects_topics_and_a_time_window(tmp_path, children):
    # 100 messages on each topic, 2 ms apart (cmd and scan alternate, 1 ms apart).
    path = tmp_path / "w.mcap"
    write_recording(path, {"cmd": (CmdVel, cmd_vels(100)), "scan": (LaserScan, [LaserScan()] * 100)})
    subscriber = children.python(SUBSCRIBER.format(count=1000))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--topics", "cmd", "--start", "0.05",
                         "--end", "0.1")
    assert replayed.returncode == 0, replayed.stderr
    subscriber.kill()
    out, _ = subscriber.communicate(timeout=60)
    # cmd message i is at 2*i ms: the window [50 ms, 100 ms] holds i = 25..50.
    assert out.split() == [m.to_bytes().hex() for m in cmd_vels(100)[25:51]]
    missing = run_horus("record", "replay", str(path), "--topics", "nope")
    assert missing.returncode == 1 and "not in the recording: nope" in missing.stderr


def test_record_runs_horus_record_with_the_arguments(tmp_path):
    fake = tmp_path / "horus-record"
    fake.write_text("#!/bin/sh\necho \"$@\"\n")
    fake.chmod(0o755)
    env = dict(os.environ, HORUS_RECORD_PROGRAM=str(fake))
    ran = subprocess.run([HORUS, "-n", "ns1", "record", "-a", "-o", "x.mcap", "--duration", "2"],
                         capture_output=True, text=True, env=env, timeout=30)
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.split() == ["-a", "-o", "x.mcap", "--duration", "2.0", "--namespace", "ns1"]
    ran = subprocess.run([HORUS, "record", "--", "list", "cmd"], capture_output=True, text=True,
                         env=env, timeout=30)
    assert ran.stdout.split()[:2] == ["list", "cmd"]
    assert run_horus("record").returncode == 2
    assert run_horus("record", "-a", "cmd").returncode == 2
    env["HORUS_RECORD_PROGRAM"] = str(tmp_path / "missing")
    ran = subprocess.run([HORUS, "record", "-a"], capture_output=True, text=True, env=env,
                         timeout=30)
    assert ran.returncode == 1 and "cannot run" in ran.stderr


def test_replay_into_cpp_subscribers_pod_and_serialized(tmp_path, children):
    from horus.msg import CompressedImage
    peer = os.environ["HORUS_PY_PEER"]
    count = 50  # fewer than a topic's 64 slots: a subscriber that stalls still loses nothing
    commands = [CmdVel(linear=i, angular=-i) for i in range(1, count + 1)]
    images = [CompressedImage(format="png", width=i, height=2, data=bytes([0xAB]) * i)
              for i in range(1, count + 1)]
    path = tmp_path / "cross.mcap"
    write_recording(path, {"cmd": (CmdVel, commands), "imgs": (CompressedImage, images)})
    subscribers = [children.program(peer, "sub", "cmdvel", "cmd", str(count)),
                   children.program(peer, "sub", "image", "imgs", str(count))]
    for subscriber in subscribers:
        assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--rate", "5")
    assert replayed.returncode == 0, replayed.stderr
    for subscriber in subscribers:
        out, err = subscriber.communicate(timeout=60)
        assert subscriber.returncode == 0, err
        assert out.split() == [str(i) for i in range(1, count + 1)]


def test_foxglove_export_leaves_out_a_type_it_cannot_decode_and_says_so(tmp_path):
    path, out = tmp_path / "odd.mcap", tmp_path / "odd_foxglove.mcap"
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream)
        odd = writer.add_schema("[u8; 4]", "horus.hmsg", b"[u8; 4]")
        raw = writer.add_channel("raw", "horus.pod", odd, {"horus.fingerprint": "00000000000000ab",
                                                           "horus.type": "[u8; 4]"})
        meta = CmdVel.__horus__
        cmd = writer.add_channel("cmd", "horus.pod",
                                 writer.add_schema(meta.name, "horus.hmsg", meta.schema.encode()),
                                 {"horus.fingerprint": f"{meta.fingerprint:016x}",
                                  "horus.type": meta.name})
        writer.add_message(raw, 1, b"abcd")
        writer.add_message(cmd, 2, CmdVel(linear=3.0).to_bytes())
        writer.finish()
    exported = run_horus("record", "export", str(path), "--foxglove", str(out))
    assert exported.returncode == 1
    assert "left out of the export: topic 'raw': cannot decode [u8; 4]" in exported.stderr
    with open(out, "rb") as stream:
        messages = [(c.topic, json.loads(m.data)) for s, c, m in
                    make_reader(stream, validate_crcs=True).iter_messages()]
    assert messages == [("cmd", {"linear": 3.0, "angular": 0.0, "stamp_nanos": "0"})]
