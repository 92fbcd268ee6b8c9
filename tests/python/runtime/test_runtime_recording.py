"""Session recordings read by a reader that is not ours: PyPI `mcap`, from the test-only
venv of scripts/dev-venv (ctest entry pytest_runtime_recording). A Python session recorded by
Scheduler(recording=True), a C++ one by horus-record, and a horus-record killed with kill -9."""
from __future__ import annotations

import io
import os
import signal
import struct
import subprocess
import time

import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, Message, Metadata

import horus
from horus import Node, Scheduler
from horus.msg import CmdVel, CompressedImage
from .mcap_check import check_file, records_until_end

RECORD = os.environ.get("HORUS_RECORD_PROGRAM", "")


@pytest.fixture(autouse=True)
def recordings(monkeypatch, tmp_path):
    folder = tmp_path / "recordings"
    monkeypatch.setenv("HORUS_RECORDINGS", str(folder))
    return folder


def metadata(path) -> dict:
    with open(path, "rb") as f:
        return {m.name: m.metadata for m in make_reader(f).iter_metadata()}


def test_python_session_is_recorded_listed_and_read_by_an_independent_reader():
    sent = []

    def drive(node):
        msg = CmdVel(linear=float(len(sent)), angular=-0.5)
        sent.append(msg)
        node.send("cmd", msg)

    received = []
    sched = Scheduler(tick_rate=100, recording=True)
    sched.add(Node(name="driver", tick=drive, order=0, pubs={"cmd": CmdVel}))
    sched.add(Node(name="motor", tick=lambda n: received.extend(iter(lambda: n.recv("cmd"), None)),
                   order=1, subs={"cmd": CmdVel}))
    assert not sched.is_recording()
    for _ in range(40):
        sched.tick_once()
    assert sched.is_recording()
    files = sched.stop_recording()
    assert len(files) == 1 and not sched.is_recording()
    name = os.path.basename(files[0])[:-len(".mcap")]
    assert name.startswith("session_") and name in sched.list_recordings()

    topics = check_file(files[0])
    cmd = topics["cmd"]
    assert [CmdVel.from_bytes(data) for _, _, data, _, _ in cmd] == sent
    schema, channel = cmd[0][3], cmd[0][4]
    assert schema.name == CmdVel.__horus__.name and schema.encoding == "horus.hmsg"
    assert channel.message_encoding == "horus.pod"
    assert channel.metadata["horus.fingerprint"] == f"{CmdVel.__horus__.fingerprint:016x}"
    assert [seq for seq, *_ in cmd] == list(range(cmd[0][0], cmd[0][0] + len(sent)))
    ticks = [data for _, _, data, _, _ in topics["/horus/ticks"]]
    assert len(ticks) == 80 and b'"node":"driver"' in ticks[0] and b'"outcome":"ok"' in ticks[0]
    meta = metadata(files[0])
    assert meta["horus.session"]["session"] == name
    assert meta["horus.recorder"]["lost_total"] == "0"

    assert sched.delete_recording(name) is True
    assert name not in sched.list_recordings() and not os.path.exists(files[0])


def _listener(name: str, order: int, arrivals: list) -> Node:
    """A node that notes on which of its ticks each CmdVel on "cmd" arrived."""
    ticks = [0]

    def tick(node):
        while (msg := node.recv("cmd")) is not None:
            arrivals.append((msg.linear, ticks[0]))
        ticks[0] += 1
    return Node(name=name, tick=tick, order=order, subs={"cmd": CmdVel})


def test_a_python_session_replayed_deterministically_gives_the_same_arrivals_twice():
    def drive(node):
        drive.ticks += 1
        if drive.ticks % 3 != 2:
            node.send("cmd", CmdVel(linear=float(drive.ticks), angular=0.0))
    drive.ticks = 0

    live_early, live_late = [], []
    sched = Scheduler(tick_rate=100, recording=True)
    sched.add(_listener("early", 0, live_early))
    sched.add(Node(name="driver", tick=drive, order=1, pubs={"cmd": CmdVel}))
    sched.add(_listener("late", 2, live_late))
    for _ in range(30):
        sched.tick_once()
    [path] = sched.stop_recording()
    assert len(live_late) == 20 and live_late[0] == (1.0, 0) and live_early[0] == (1.0, 1)

    def replay():
        early, late = [], []
        again = Scheduler(tick_rate=100, deterministic=True, replay=path)
        again.add(_listener("early", 0, early))
        again.add(_listener("late", 2, late))
        for _ in range(30):
            again.tick_once()
        return early, late

    first = replay()
    assert first == (live_early, live_late)  # each message on the tick it was received live
    assert replay() == first
    with pytest.raises(horus.HorusError, match="needs deterministic"):
        Scheduler(replay=path)


def _start_recorder(*args):
    assert RECORD, "HORUS_RECORD_PROGRAM names horus-record; run this suite through ctest"
    return subprocess.Popen([RECORD, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _wait_recording(topic, probe, limit=10.0):
    """Sends probes until the recorder has opened the topic (its handle is one more user)."""
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        info = {t["name"]: t for t in horus._core.list_topics("")}.get(topic)
        if info and info.get("subscribers", 0) >= 1:
            return
        probe()
        time.sleep(0.01)
    raise AssertionError(f"horus-record never subscribed to {topic}")


def test_horus_record_finishes_the_file_on_sigint_with_every_message(tmp_path):
    out = tmp_path / "cpp.mcap"
    pub = horus.Topic(CmdVel, "vel", capacity=1024)
    recorder = _start_recorder("vel", "-o", str(out))
    _wait_recording("vel", lambda: pub.send(CmdVel(linear=-1.0, angular=0.0)))
    sent = [CmdVel(linear=float(i), angular=1.0) for i in range(500)]
    for msg in sent:
        assert pub.send(msg)
    time.sleep(0.2)
    recorder.send_signal(signal.SIGINT)
    stdout, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr
    assert "0 lost" in stdout
    topics = check_file(out)
    recorded = [CmdVel.from_bytes(data) for _, _, data, _, _ in topics["vel"]]
    assert recorded[-len(sent):] == sent
    assert all(m == CmdVel(linear=-1.0, angular=0.0) for m in recorded[:-len(sent)])


def test_horus_record_killed_with_kill_9_leaves_its_complete_chunks_readable(tmp_path):
    out = tmp_path / "cut.mcap"
    big = horus.Topic(CompressedImage, "frames", capacity=256, max_message_size=64 * 1024)
    recorder = _start_recorder("frames", "-o", str(out))
    _wait_recording("frames", lambda: big.send(CompressedImage(format="probe")))
    i = 0
    deadline = time.monotonic() + 30
    while (not out.exists() or out.stat().st_size < 3 * 1024 * 1024) and time.monotonic() < deadline:
        big.send(CompressedImage(format="jpeg", width=i, data=os.urandom(32 * 1024)))
        i += 1
        if i % 16 == 0:
            time.sleep(0.002)
    recorder.kill()
    recorder.wait(timeout=30)
    assert out.stat().st_size >= 3 * 1024 * 1024

    whole = complete_records(out.read_bytes())
    assert not out.read_bytes().endswith(b"\x89MCAP0\r\n")  # no summary, no footer
    chunks = sum(isinstance(r, Chunk) for r in
                 records_until_end(io.BytesIO(whole), validate_crcs=True, emit_chunks=True))
    got = [r for r in records_until_end(io.BytesIO(whole), validate_crcs=True)
           if isinstance(r, Message)]
    assert chunks >= 2
    frames = [CompressedImage.from_bytes(m.data) for m in got]
    indexes = [f.width for f in frames if f.format == "jpeg"]
    assert indexes and indexes == list(range(indexes[0], indexes[0] + len(indexes)))
    assert "horus.recorder" not in metadata_linear(out)


def complete_records(data: bytes) -> bytes:
    """The file up to the end of its last complete record (a kill -9 may cut the last one)."""
    at = 8
    while at + 9 <= len(data):
        length = struct.unpack_from("<Q", data, at + 1)[0]
        if at + 9 + length > len(data):
            break
        at += 9 + length
    return data[:at]


def metadata_linear(path) -> dict:
    whole = complete_records(path.read_bytes())
    return {r.name: r.metadata for r in records_until_end(io.BytesIO(whole))
            if isinstance(r, Metadata)}


def test_horus_record_duration_and_sigterm_finish_the_file_and_usage_errors_say_why(tmp_path):
    timed = subprocess.run([RECORD, "-a", "-o", str(tmp_path / "timed.mcap"), "--duration", "0.3"],
                           capture_output=True, text=True, timeout=30)
    assert timed.returncode == 0, timed.stderr
    assert "horus.recorder" in metadata(tmp_path / "timed.mcap")

    terminated = _start_recorder("-a", "-o", str(tmp_path / "term.mcap"))
    deadline = time.monotonic() + 10
    while not (tmp_path / "term.mcap").exists() and time.monotonic() < deadline:
        time.sleep(0.01)  # the file exists once the signals are blocked for sigwait
    terminated.send_signal(signal.SIGTERM)
    _, stderr = terminated.communicate(timeout=30)
    assert terminated.returncode == 0, stderr
    assert "horus.recorder" in metadata(tmp_path / "term.mcap")

    for args, reason in ((["-o", "x.mcap"], "name topics to record"),
                         (["t", "--duration", "soon"], "--duration needs a positive number"),
                         (["t", "--bogus"], "unknown option --bogus")):
        bad = subprocess.run([RECORD, *args], capture_output=True, text=True, timeout=30)
        assert bad.returncode == 2 and reason in bad.stderr
    existing = tmp_path / "timed.mcap"
    refused = subprocess.run([RECORD, "t", "-o", str(existing)], capture_output=True, text=True,
                             timeout=30)
    assert refused.returncode == 1 and str(existing) in refused.stderr
