"""`horus record` over files the C++ recorder writes (a Python and a C++ Scheduler(recording=True)
session, and horus-record run by `horus record`, finished or killed with kill -9), checked again
with PyPI `mcap` and `jsonschema`."""
from __future__ import annotations

import json
import os
import signal
import subprocess

import pytest
from mcap.exceptions import McapError
from mcap.reader import make_reader

import horus
from horus import Node, Scheduler
from horus.msg import CmdVel, CompressedImage

from horus import mcap as horus_mcap

from conftest import check_file
from processes import wait_until
from test_record import SUBSCRIBER, cmd_vels, export_validated, run_horus, write_recording

HORUS = os.environ.get("HORUS_CLI", "")
PEER = os.environ.get("HORUS_PY_PEER", "")


def record_python_session(count: int) -> tuple[str, list]:
    sent = []

    def drive(node):
        message = CmdVel(linear=float(len(sent)) + 0.25, angular=-0.5)
        sent.append(message)
        node.send("cmd", message)

    scheduler = Scheduler(tick_rate=100, recording=True)
    scheduler.add(Node(name="driver", tick=drive, order=0, pubs={"cmd": CmdVel}))
    scheduler.add(Node(name="motor", tick=lambda n: list(iter(lambda: n.recv("cmd"), None)),
                       order=1, subs={"cmd": CmdVel}))
    for _ in range(count):
        scheduler.tick_once()
    files = scheduler.stop_recording()
    assert len(files) == 1
    return files[0], sent


def test_a_python_session_reads_lists_diffs_and_exports(tmp_path):
    path, sent = record_python_session(40)
    name = os.path.basename(path)[:-len(".mcap")]
    assert name in run_horus("record", "list").stdout.split()
    for extra in ([], ["--check"]):  # from the summary, then walking every record and CRC
        info = run_horus("record", "info", name, "--json", *extra)
        assert info.returncode == 0, info.stderr
        described = json.loads(info.stdout)
        assert described["summary"] is True and described["lost"] == 0
        counts = {t["topic"]: t["messages"] for t in described["topics"]}
        assert counts == {"cmd": len(sent), "/horus/ticks": 2 * len(sent)}
        cmd = next(t for t in described["topics"] if t["topic"] == "cmd")
        assert cmd["type"] == "horus.msg.CmdVel" and cmd["lost"] == 0
        assert cmd["fingerprint"] == f"{CmdVel.__horus__.fingerprint:016x}"
        assert described["session"]["session"] == name
    same = run_horus("record", "diff", name, path)
    assert same.returncode == 0, same.stdout + same.stderr

    out = tmp_path / "session_foxglove.mcap"
    messages = export_validated(path, out)
    assert [value["linear"] for topic, _, value in messages if topic == "cmd"] == [
        m.linear for m in sent]
    ticks = [value for topic, _, value in messages if topic == "/horus/ticks"]
    assert len(ticks) == 2 * len(sent) and {t["node"] for t in ticks} == {"driver", "motor"}


def test_a_python_session_replays_into_a_live_subscriber(children):
    path, sent = record_python_session(60)
    subscriber = children.python(SUBSCRIBER.format(count=len(sent)))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", path, "--rate", "10")
    assert replayed.returncode == 0, replayed.stderr
    out, _ = subscriber.communicate(timeout=60)
    assert out.split() == [m.to_bytes().hex() for m in sent]


def start_recording(*args: str) -> subprocess.Popen:
    """`horus record ARGS...` (which runs horus-record)."""
    return subprocess.Popen([HORUS, "record", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def subscribers(topic: str) -> int:
    return next((t["subscribers"] for t in horus._core.list_topics("") if t["name"] == topic), 0)


def test_horus_record_runs_the_cpp_recorder_whose_file_info_reads(tmp_path):
    out = tmp_path / "vel.mcap"
    publisher = horus.Topic(CmdVel, "vel", capacity=1024)
    recorder = start_recording("vel", "-o", str(out))
    wait_until(lambda: subscribers("vel") >= 1, "horus-record to subscribe to vel", limit=30)
    sent = [CmdVel(linear=float(i)) for i in range(300)]
    for message in sent:  # fewer than the topic's slots: the recorder drains them all at SIGINT
        assert publisher.send(message)
    recorder.send_signal(signal.SIGINT)
    _, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr
    described = json.loads(run_horus("record", "info", str(out), "--json").stdout)
    vel = next(t for t in described["topics"] if t["topic"] == "vel")
    with open(out, "rb") as stream:
        recorded = [CmdVel.from_bytes(m.data)
                    for _, _, m in make_reader(stream, validate_crcs=True).iter_messages()]
    assert recorded == sent and vel["messages"] == len(sent)
    assert described["lost"] == vel["lost"] == 0


def test_a_cpp_recording_cut_short_is_read_and_repaired(tmp_path):
    """A session of several chunks, cut inside its last chunk as a kill -9 leaves it: complete
    chunks, then part of one, no summary."""
    def film(node):
        node.send("frames", CompressedImage(format="jpeg", width=node.frames, data=os.urandom(12_000)))
        node.frames += 1

    camera = Node(name="camera", tick=film, pubs={"frames": CompressedImage})
    camera.frames = 0
    scheduler = Scheduler(tick_rate=100, recording=True)
    scheduler.add(camera)
    for _ in range(400):  # about 5 MB: chunks are written at each MiB
        scheduler.tick_once()
    path = scheduler.stop_recording()[0]
    walked = horus_mcap.Reader(path)
    for _ in walked:
        pass
    chunks = walked.chunk_indexes
    assert len(chunks) >= 2
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(open(path, "rb").read()[:chunks[-1].chunk_start_offset
                                            + chunks[-1].chunk_length // 2])

    info = run_horus("record", "info", str(cut), "--json")
    assert info.returncode == 0, info.stderr
    described = json.loads(info.stdout)
    assert described["summary"] is False and described["lost"] is None
    assert described["cut_bytes"] > 0 and described["chunks"] == len(chunks) - 1
    kept = described["messages"]
    kept_frames = next(t["messages"] for t in described["topics"] if t["topic"] == "frames")
    assert 0 < kept_frames < camera.frames

    repaired = run_horus("record", "repair", str(cut), "-o", str(tmp_path / "fixed.mcap"))
    assert repaired.returncode == 0, repaired.stderr
    with open(tmp_path / "fixed.mcap", "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        assert reader.get_summary().statistics.message_count == kept
        frames = [CompressedImage.from_bytes(m.data) for _, c, m in reader.iter_messages()
                  if c.topic == "frames"]
    widths = [f.width for f in frames]  # the recorder may lose some: never out of order
    assert len(widths) == kept_frames and widths == sorted(set(widths))


def cpp_session(kind: str, topic: str, count: int) -> subprocess.Popen:
    """tests/python/runtime/peer.cpp's `session`: a C++ Scheduler with recording(true) whose C++
    nodes publish value i = 1..count on `topic` (one a tick) and subscribe to it."""
    assert PEER, "HORUS_PY_PEER names the C++ peer; run this suite through ctest (pytest_record)"
    return subprocess.Popen([PEER, "session", kind, topic, str(count)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def test_a_cpp_session_is_read_by_pypi_mcap_listed_and_replayed_into_a_live_subscriber(
        recordings, children):
    count = 60  # fewer than a topic's 64 slots: a recorder thread starved a while loses nothing
    session = cpp_session("cmdvel", "cmd", count)
    out, err = session.communicate(timeout=60)
    assert session.returncode == 0, err
    [path] = out.split()
    assert os.path.dirname(path) == str(recordings)
    name = os.path.basename(path)[:-len(".mcap")]
    assert run_horus("record", "list").stdout.split() == [name]
    sent = [CmdVel(linear=i, angular=-i) for i in range(1, count + 1)]

    checked = check_file(path)  # every CRC, the summary's too, and every index
    assert [data for _, _, data, _, _ in checked["cmd"]] == [m.to_bytes() for m in sent]
    with open(path, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.chunk_indexes
        topics = {channel.topic: summary.statistics.channel_message_counts.get(id_, 0)
                  for id_, channel in summary.channels.items()}
        assert topics == {"cmd": count, "/horus/ticks": 2 * count}
        cmd_schema = next(summary.schemas[c.schema_id] for c in summary.channels.values()
                          if c.topic == "cmd")
        assert cmd_schema.name == "horus.msg.CmdVel" and cmd_schema.data
        recorded = [m.data for _, c, m in reader.iter_messages()
                    if c.topic == "cmd"]
    assert recorded == [m.to_bytes() for m in sent]
    described = json.loads(run_horus("record", "info", name, "--json", "--check").stdout)
    assert described["summary"] is True and described["lost"] == 0

    subscriber = children.python(SUBSCRIBER.format(count=count))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", name, "--rate", "5")
    assert replayed.returncode == 0, replayed.stderr
    assert f"replayed {count} messages on 1 topics" in replayed.stdout
    received, _ = subscriber.communicate(timeout=60)
    assert received.split() == [m.to_bytes().hex() for m in sent]


def test_a_looped_replay_delivers_the_recording_again_and_again_in_order(tmp_path, children):
    messages = cmd_vels(20, offset=0.5)
    path = tmp_path / "loop.mcap"
    write_recording(path, {"cmd": (CmdVel, messages)})
    wanted = 3 * len(messages) + 7  # three whole passes and part of a fourth
    subscriber = children.python(SUBSCRIBER.format(count=wanted))
    assert subscriber.stdout.readline().strip() == "ready"
    replay = subprocess.Popen([HORUS, "record", "replay", str(path), "--loop"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        received, _ = subscriber.communicate(timeout=60)
        assert replay.poll() is None  # a looped replay runs until stopped
    finally:
        replay.send_signal(signal.SIGINT)
        replay.communicate(timeout=30)
    assert received.split() == [m.to_bytes().hex() for m in (messages * 4)[:wanted]]


@pytest.mark.parametrize("rate", ["2", "0.5"])
def test_replay_at_another_rate_keeps_every_message_and_its_order(tmp_path, children, rate):
    messages = cmd_vels(40, offset=0.25)  # 1 ms apart: 20 ms at --rate 2, 80 ms at 0.5
    path = tmp_path / "rate.mcap"
    write_recording(path, {"cmd": (CmdVel, messages)})
    subscriber = children.python(SUBSCRIBER.format(count=len(messages)))
    assert subscriber.stdout.readline().strip() == "ready"
    replayed = run_horus("record", "replay", str(path), "--rate", rate)
    assert replayed.returncode == 0, replayed.stderr
    assert f"replayed {len(messages)} messages on 1 topics" in replayed.stdout
    received, _ = subscriber.communicate(timeout=60)
    assert received.split() == [m.to_bytes().hex() for m in messages]


def test_a_cpp_recording_scheduler_killed_mid_write_is_read_and_repaired(recordings, tmp_path):
    session = cpp_session("image", "imgs", 1_000_000)  # runs until killed
    try:
        def chunks_written():
            files = list(recordings.glob("*.mcap"))
            if not files:
                return None
            info = run_horus("record", "info", str(files[0]), "--json")
            return files[0] if info.returncode == 0 and json.loads(info.stdout)["chunks"] >= 2 else None
        path = wait_until(chunks_written, "the session to write two chunks", limit=60)
    finally:
        session.kill()  # SIGKILL: no summary, whatever was being written stays as it was
        session.communicate(timeout=30)
    assert session.returncode == -signal.SIGKILL

    info = run_horus("record", "info", str(path), "--json")
    assert info.returncode == 0, info.stderr
    described = json.loads(info.stdout)
    assert described["summary"] is False and described["lost"] is None
    assert described["chunks"] >= 2
    kept = described["messages"]
    kept_images = next(t["messages"] for t in described["topics"] if t["topic"] == "imgs")
    assert kept_images > 0
    with open(path, "rb") as stream, pytest.raises(McapError):  # no footer: nothing to find
        make_reader(stream, validate_crcs=True).get_summary()

    fixed = tmp_path / "fixed.mcap"
    repaired = run_horus("record", "repair", str(path), "-o", str(fixed))
    assert repaired.returncode == 0, repaired.stderr
    with open(fixed, "rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == kept
        images = [CompressedImage.from_bytes(m.data) for _, c, m in reader.iter_messages()
                  if c.topic == "imgs"]
    assert len(images) == kept_images
    widths = [image.width for image in images]  # the recorder may lose some: never out of order
    assert widths == sorted(set(widths))
    assert all(image.data == bytes([0xAB]) * image.width for image in images)
