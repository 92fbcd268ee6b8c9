"""`horus record` over recordings written by tools/horus/horus_mcap.py, checked with PyPI `mcap`
(an MCAP reader that is not ours) and `jsonschema`; replay into a live subscriber process."""
from __future__ import annotations

import json
import os
import subprocess
import zlib

import jsonschema
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd, Footer, MessageIndex
from mcap.stream_reader import StreamReader

import horus_mcap
from horus.msg import CmdVel, LaserScan, PoseStamped, TransformStamped

HORUS = os.environ.get("HORUS_CLI", "")


def run_horus(*args: str) -> subprocess.CompletedProcess:
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_record)"
    return subprocess.run([HORUS, *args], capture_output=True, text=True, timeout=60)


def write_recording(path, topics: dict, *, fingerprint_of=None, chunk_size=4096) -> None:
    """A recording as the recorder writes it: `topics` maps a topic to (class, [messages])."""
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream, chunk_size=chunk_size)
        writer.add_metadata("horus.session", {"session": "test", "namespace": "t"})
        channels = {}
        for topic, (cls, _) in topics.items():
            meta = cls.__horus__
            schema = writer.add_schema(meta.name, "horus.hmsg", meta.schema.encode())
            fingerprint = (fingerprint_of or {}).get(topic, meta.fingerprint)
            metadata = {"horus.fingerprint": f"{fingerprint:016x}", "horus.type": meta.name}
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
    path, out = tmp_path / "f.mcap", tmp_path / "foxglove.mcap"
    write_recording(path, {"scan": (LaserScan, [scan] * 3), "pose": (PoseStamped, [pose] * 2),
                           "tf": (TransformStamped, [transform]), "cmd": (CmdVel, cmd_vels(5))})
    exported = run_horus("record", "export", str(path), "--foxglove", str(out))
    assert exported.returncode == 0, exported.stderr
    seen = {}
    with open(out, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        for schema, channel, message in reader.iter_messages():
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            value = json.loads(message.data)
            jsonschema.validate(value, json.loads(schema.data))
            seen.setdefault(channel.topic, (schema.name, value))
    assert {t: s for t, (s, _) in seen.items()} == {
        "scan": "foxglove.LaserScan", "pose": "foxglove.PoseInFrame",
        "tf": "foxglove.FrameTransform", "cmd": "horus.msg.CmdVel"}
    scan_json = seen["scan"][1]
    assert scan_json["timestamp"] == {"sec": 5, "nsec": 123}
    assert scan_json["ranges"][:2] == [0.0, 2.5] and len(scan_json["ranges"]) == 360
    assert seen["pose"][1]["frame_id"] == "map"
    assert seen["pose"][1]["pose"]["position"]["x"] == 1.5
    assert seen["tf"][1]["translation"] == {"x": 1.0, "y": 2.0, "z": 3.0}
    assert seen["cmd"][1] == {"linear": 0.0, "angular": 0.0, "stamp_nanos": 0}


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
