"""Recordings carry each topic's type description (channel metadata `horus.description`,
docs/recording.md "The file"): horus-record of a C++ and of a Python publisher, a Python
session, read by PyPI `mcap` and by horus.mcap; the C++ deterministic replay giving a topic it
creates the recorded description; the readers preferring it to the schema text; and files written
before recordings carried it still read, replay and export."""
from __future__ import annotations

import base64
import signal
import time

import pytest
from mcap.reader import make_reader

import horus
from horus import Node, Scheduler
from horus import mcap as horus_mcap
from horus.msg import CmdVel, CompressedImage

from conftest import check_file
from processes import wait_until
from test_record import (SUBSCRIBER, cmd_vels, export_validated, run_horus,
                         write_recording)
from test_record_sessions import (PEER, cpp_session, record_python_session, start_recording,
                                  subscribers)


def descriptions_read_by_pypi_mcap(path) -> dict[str, bytes]:
    """Each channel's description as a reader that is not ours finds it (CRCs checked), by topic;
    channels without one are left out."""
    with open(path, "rb") as stream:
        summary = make_reader(stream, validate_crcs=True).get_summary()
    return {channel.topic: base64.b64decode(channel.metadata["horus.description"], validate=True)
            for channel in summary.channels.values() if "horus.description" in channel.metadata}


def descriptions_read_by_horus_mcap(path) -> dict[str, bytes]:
    reader = horus_mcap.Reader(str(path))
    for _ in reader:
        pass
    return {channel.topic: channel.description for channel in reader.channels.values()}


def record_with_horus_record(out, topics: list[str], publish) -> None:
    """Runs horus-record (through `horus record`) on `topics`, calls `publish()` once it reads
    them all, and finishes the file."""
    recorder = start_recording(*topics, "-o", str(out))
    for topic in topics:
        wait_until(lambda: subscribers(topic) >= 1, f"horus-record to subscribe to {topic}",
                   limit=30)
    publish()
    recorder.send_signal(signal.SIGINT)
    _, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr


def test_horus_record_of_a_cpp_publisher_carries_its_types_descriptions(tmp_path, children):
    assert PEER, "HORUS_PY_PEER names the C++ peer; run this suite through ctest (pytest_record)"
    for kind, topic in (("cmdvel", "vel"), ("image", "img")):
        talker = children.program(PEER, "node", kind, topic, "200")
        assert talker.stdout.readline().strip() == "ready"
    out = tmp_path / "cpp.mcap"
    record_with_horus_record(out, ["vel", "img"], lambda: time.sleep(0.5))
    # The C++ types' own bytes (TypeInfo<T>::description, which the generated Python classes
    # carry byte for byte), not something the recorder made up.
    expected = {"vel": CmdVel.__horus__.description, "img": CompressedImage.__horus__.description}
    assert all(expected.values())
    check_file(out)  # every CRC, the summary's too, and every index
    assert descriptions_read_by_pypi_mcap(out) == expected
    assert descriptions_read_by_horus_mcap(out) == expected


def test_horus_record_of_a_python_publisher_carries_its_types_descriptions(tmp_path):
    vel = horus.Topic(CmdVel, "vel", capacity=1024)
    img = horus.Topic(CompressedImage, "img", capacity=1024)

    def publish():
        for i in range(50):
            assert vel.send(CmdVel(linear=float(i)))
            assert img.send(CompressedImage(format="png", width=i, data=bytes(i)))

    out = tmp_path / "python.mcap"
    record_with_horus_record(out, ["vel", "img"], publish)
    expected = {"vel": CmdVel.__horus__.description, "img": CompressedImage.__horus__.description}
    check_file(out)
    assert descriptions_read_by_pypi_mcap(out) == expected
    assert descriptions_read_by_horus_mcap(out) == expected


def test_a_cpp_session_carries_its_in_process_topics_description(recordings):
    session = cpp_session("image", "img", 5)
    out, err = session.communicate(timeout=60)
    assert session.returncode == 0, err
    [path] = out.split()
    check_file(path)
    assert descriptions_read_by_pypi_mcap(path) == {"img": CompressedImage.__horus__.description}


def test_a_python_session_carries_its_topics_description_and_none_for_the_ticks():
    path, _ = record_python_session(5)
    check_file(path)
    assert descriptions_read_by_pypi_mcap(path) == {"cmd": CmdVel.__horus__.description}
    assert descriptions_read_by_horus_mcap(path) == {
        "cmd": CmdVel.__horus__.description, "/horus/ticks": b""}


def write_described(path, topics: dict, *, schema_text: dict | None = None,
                    description: dict | None = None) -> None:
    """A recording as the recorder writes it, descriptions included: `topics` maps a topic to
    (class, [messages]); `schema_text` and `description` replace a topic's stored ones."""
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream)
        channels = {}
        for topic, (cls, _) in topics.items():
            meta = cls.__horus__
            text = (schema_text or {}).get(topic, meta.schema)
            metadata = {"horus.fingerprint": f"{meta.fingerprint:016x}", "horus.type": meta.name}
            if meta.is_pod:
                metadata["horus.payload_size"] = str(meta.size)
            carried = (description or {}).get(topic, meta.description)
            metadata.update(horus_mcap.description_metadata(carried) if isinstance(carried, bytes)
                            else {horus_mcap.DESCRIPTION_KEY: carried})
            channels[topic] = writer.add_channel(
                topic, "horus.pod" if meta.is_pod else "horus.msgpack",
                writer.add_schema(meta.name, "horus.hmsg", text.encode()), metadata)
        for index in range(max(len(m) for _, m in topics.values())):
            for topic, (_, messages) in topics.items():
                if index < len(messages):
                    writer.add_message(channels[topic], 1_000_000_000 + index * 1_000_000,
                                       messages[index].to_bytes(), sequence=index)
        writer.finish()


def replayed_segment_descriptions(path, namespace: str) -> dict[str, bytes]:
    """The descriptions of the topics a deterministic replay of `path` creates (its node reads
    none of them: what their segments carry came from the file alone)."""
    scheduler = Scheduler(tick_rate=100, deterministic=True, replay=str(path))
    scheduler.add(Node(name="idle", order=0, tick=lambda node: None))
    scheduler.tick_once()
    return {t["name"]: t["description"] for t in horus._core.list_topics(namespace)}


def images(count: int) -> list:
    return [CompressedImage(format="png", width=i, data=bytes([i]) * i) for i in range(count)]


def test_deterministic_replay_gives_the_topics_it_creates_the_recorded_description(
        tmp_path, namespace):
    path = tmp_path / "described.mcap"
    write_described(path, {"cmd": (CmdVel, cmd_vels(3)), "img": (CompressedImage, images(3))})
    assert replayed_segment_descriptions(path, namespace) == {
        "cmd": CmdVel.__horus__.description, "img": CompressedImage.__horus__.description}


def test_a_recording_without_descriptions_still_reads_replays_and_exports(tmp_path, children):
    path = tmp_path / "old.mcap"  # as recorders wrote before descriptions: no horus.description
    write_recording(path, {"cmd": (CmdVel, cmd_vels(20))})
    assert descriptions_read_by_pypi_mcap(path) == {}
    assert descriptions_read_by_horus_mcap(path) == {"cmd": b""}
    info = run_horus("record", "info", str(path), "--json", "--check")
    assert info.returncode == 0, info.stderr
    exported = export_validated(path, tmp_path / "old_foxglove.mcap")
    assert [value["linear"] for _, _, value in exported] == [m.linear for m in cmd_vels(20)]

    subscriber = children.python(SUBSCRIBER.format(count=20))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--rate", "20")
    assert replayed.returncode == 0, replayed.stderr
    received, _ = subscriber.communicate(timeout=60)
    assert received.split() == [m.to_bytes().hex() for m in cmd_vels(20)]


def test_deterministic_replay_of_a_recording_without_descriptions_creates_topics_without_one(
        tmp_path, namespace):
    path = tmp_path / "old.mcap"
    write_recording(path, {"cmd": (CmdVel, cmd_vels(3))})
    assert replayed_segment_descriptions(path, namespace) == {"cmd": b""}


def test_a_description_that_is_not_base64_is_refused_naming_the_topic(tmp_path, namespace):
    path = tmp_path / "bad.mcap"
    write_described(path, {"cmd": (CmdVel, cmd_vels(3))}, description={"cmd": "not base64!"})
    reader = horus_mcap.Reader(str(path))
    for _ in reader:
        pass
    with pytest.raises(horus_mcap.McapError, match="channel 'cmd': horus.description is not base64"):
        reader.channels[0].description
    with pytest.raises(horus.HorusError, match="topic 'cmd': horus.description: not base64"):
        replayed_segment_descriptions(path, namespace)


def test_deterministic_replay_refuses_a_description_of_another_type_leaving_no_topic(
        tmp_path, namespace):
    path = tmp_path / "mismatched.mcap"
    write_described(path, {"cmd": (CmdVel, cmd_vels(3))},
                    description={"cmd": CompressedImage.__horus__.description})
    with pytest.raises(horus.HorusError, match="topic 'cmd': its type description is of "
                                               "horus.msg.CompressedImage .*refusing to replay it"):
        replayed_segment_descriptions(path, namespace)
    assert horus._core.list_topics(namespace) == []
    write_described(path := tmp_path / "garbled.mcap", {"cmd": (CmdVel, cmd_vels(3))},
                    description={"cmd": b"\x93\x01\x02"})
    with pytest.raises(horus.HorusError, match="topic 'cmd': its type description cannot be read"):
        replayed_segment_descriptions(path, namespace)
    assert horus._core.list_topics(namespace) == []


def test_replay_and_export_decode_from_the_carried_description_not_the_schema_text(
        tmp_path, children):
    # A schema text no compiler takes: only the description can give the types.
    path = tmp_path / "described.mcap"
    sent, frames = cmd_vels(20), images(4)
    write_described(path, {"cmd": (CmdVel, sent), "img": (CompressedImage, frames)},
                    schema_text={"cmd": "not a schema", "img": "not a schema"})
    exported = export_validated(path, tmp_path / "described_foxglove.mcap")
    assert [value["linear"] for topic, _, value in exported if topic == "cmd"] == [
        m.linear for m in sent]
    assert [(name, value["format"]) for topic, name, value in exported if topic == "img"] == [
        ("foxglove.CompressedImage", "png")] * len(frames)

    subscriber = children.python(SUBSCRIBER.format(count=len(sent)))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--rate", "20")
    assert replayed.returncode == 0, replayed.stderr
    received, _ = subscriber.communicate(timeout=60)
    assert received.split() == [m.to_bytes().hex() for m in sent]
    assert {t["name"]: t["description"] for t in horus._core.list_topics("")} == {
        "cmd": CmdVel.__horus__.description, "img": CompressedImage.__horus__.description}
