"""`horus record` over files the C++ recorder writes (a Python Scheduler(recording=True) session,
and horus-record run by `horus record`, finished or killed with kill -9), checked again with PyPI
`mcap` and `jsonschema`."""
from __future__ import annotations

import json
import os
import signal
import subprocess

from mcap.reader import make_reader

import horus
from horus import Node, Scheduler
from horus.msg import CmdVel, CompressedImage

import horus_mcap

from conftest import wait_until
from test_record import SUBSCRIBER, export_validated, run_horus

HORUS = os.environ.get("HORUS_CLI", "")


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
