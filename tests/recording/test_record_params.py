"""Parameter changes in session recordings: a deterministic scheduler records a node's parameter
changes (made from another thread through set_param) and its starting values on /horus/params,
and a replay applies them before the same ticks (tests/recording/param_replay.cpp, and a Python
node); the channel is read by PyPI `mcap`, listed by `horus record info`, kept by the Foxglove
export, and `horus record -a` records the changes of every store of the namespace."""
from __future__ import annotations

import base64
import json
import os
import signal
import subprocess
import threading
import time

import jsonschema
from mcap.reader import make_reader

import horus

from conftest import check_file

PROGRAM = os.environ.get("HORUS_PARAM_REPLAY", "")
HORUS = os.environ.get("HORUS_CLI", "")
PARAMS = "/horus/params"


def run_program(*args: str) -> tuple[list[str], list[str], str, str]:
    """The program's tick lines, change lines, the recording it wrote and its tick count."""
    assert PROGRAM, "HORUS_PARAM_REPLAY names the test program; run this suite through ctest"
    done = subprocess.run([PROGRAM, *args], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    ticks = [line for line in lines if line.startswith("tick ")]
    changes = [line for line in lines if line.startswith("change ")]
    count = next(line.split()[1] for line in lines if line.startswith("ticks "))
    recording = next(line.split(" ", 1)[1] for line in lines if line.startswith("recording "))
    return ticks, changes, recording, count


def param_records(path: str) -> list[dict]:
    """The /horus/params records, read by PyPI mcap (CRCs checked), each validated against the
    channel's JSON Schema."""
    check_file(path)
    records = []
    with open(path, "rb") as stream:
        for schema, channel, message in make_reader(stream, validate_crcs=True).iter_messages(
                topics=[PARAMS]):
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            value = json.loads(message.data)
            jsonschema.validate(value, json.loads(schema.data))
            records.append(value)
    return records


def without_source(records: list[dict]) -> list[tuple]:
    return [(r["node"], r["name"], r["version"], r.get("cycle"), r.get("start", False), r["value"],
             r["msgpack"]) for r in records]


def test_replay_applies_recorded_changes_before_the_same_ticks(namespace, tmp_path):
    ticks, changes, recorded, count = run_program("record", "60")
    assert [line.split()[1:3] for line in changes] == [["gain", "2.500000"], ["label", "boosted"]]
    assert all(line.endswith("param_replay writer") for line in changes)
    gains = {line.split()[3] for line in ticks}
    assert gains == {"1", "2.5"}, "the gain changed during the run"

    replay_ticks, replay_changes, replayed, _ = run_program("replay", count, recorded)
    assert replay_ticks == ticks, "the replayed node saw the same values at the same ticks"
    assert [line.split()[1:3] for line in replay_changes] == [line.split()[1:3] for line in changes]
    assert all(line.endswith(" replay") for line in replay_changes), replay_changes

    live, again = param_records(recorded), param_records(replayed)
    starts = [r for r in live if r.get("start")]
    assert {(r["name"], r["version"], json.dumps(r["value"])) for r in starts} == {
        ("gain", 1, "1.0"), ("label", 1, '"plain"')}
    moved = [r for r in live if not r.get("start")]
    assert [(r["name"], r["value"], r["version"], r["source"]) for r in moved] == [
        ("gain", 2.5, 2, "param_replay writer"), ("label", "boosted", 2, "param_replay writer")]
    assert all(isinstance(r["cycle"], int) for r in moved)
    # The exact MessagePack VALUE bytes (a float 64 of 2.5) are what a replay applies.
    assert base64.b64decode(moved[0]["msgpack"]) == bytes.fromhex("cb4004000000000000")
    # The replayed run's recording lists the same changes at the same cycles, written by "replay".
    assert without_source(again) == without_source(live)
    assert [r["source"] for r in again if not r.get("start")] == ["replay", "replay"]


def test_a_replay_starts_from_the_recorded_starting_values(namespace, tmp_path):
    params = tmp_path / "robot.yaml"
    params.write_text("gain_node:\n  gain: 4.0\n  label: from_file\n")
    ticks, _, recorded, count = run_program("record", "30", str(params))
    assert ticks[0].split()[3:6] == ["4", "label", "from_file"]
    starts = {r["name"]: r for r in param_records(recorded) if r.get("start")}
    assert (starts["gain"]["value"], starts["gain"]["version"]) == (4.0, 1)
    # No parameter file this time: the stores start from what the recording says.
    replay_ticks, _, _, _ = run_program("replay", count, recorded)
    assert replay_ticks == ticks


def test_record_info_and_the_foxglove_export_show_the_params_channel(namespace):
    _, _, recorded, _ = run_program("record", "30")
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_record)"
    info = subprocess.run([HORUS, "record", "info", recorded, "--json"], capture_output=True,
                          text=True, timeout=60)
    assert info.returncode == 0, info.stderr
    topics = {t["topic"]: t for t in json.loads(info.stdout)["topics"]}
    assert topics[PARAMS]["type"] == "horus.recording.ParamChange"
    assert topics[PARAMS]["encoding"] == "json"
    assert topics[PARAMS]["messages"] == 4  # two starting values, two changes
    # The Foxglove export copies the channel as it is, still valid against its schema.
    out = os.path.join(os.path.dirname(recorded), "foxglove.mcap")
    exported = subprocess.run([HORUS, "record", "export", recorded, "--foxglove", out],
                              capture_output=True, text=True, timeout=60)
    assert exported.returncode == 0, exported.stderr
    assert len(param_records(out)) == 4


def test_horus_record_all_records_the_changes_of_the_namespace_stores(namespace, tmp_path):
    assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest (pytest_record)"
    out = tmp_path / "all.mcap"
    recorder = subprocess.Popen([HORUS, "record", "-a", "-o", str(out)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(0.5)  # the recorder runs before the node's store appears
        # 1 ms a tick: the writes come a second or more after the store appears, which the
        # recorder looks for five times a second.
        run_program("record", "3000")
    finally:
        recorder.send_signal(signal.SIGINT)
        recorder.communicate(timeout=30)
    assert recorder.returncode == 0
    records = param_records(str(out))
    starts = {(r["name"], r["version"], json.dumps(r["value"])) for r in records if r.get("start")}
    assert starts == {("gain", 1, "1.0"), ("label", 1, '"plain"')}
    changes = [(r["name"], r["version"], r["value"]) for r in records if not r.get("start")]
    assert changes == [("gain", 2, 2.5), ("label", 2, "boosted")]
    # Seen through the store's change counter: no cycle, no writer.
    assert all("cycle" not in r and r["source"] == "" for r in records)


class PyGain(horus.Node):
    """A Python node whose ticks log its parameter, as param_replay.cpp's."""

    def __init__(self, log: list) -> None:
        super().__init__(name="py_gain")
        self.declare_param("gain", 1.0, min=0.0, max=10.0)
        self.log = log

    def tick(self) -> None:
        self.log.append(("tick", self.params.gain))

    def on_param_change(self, change):
        self.log.append(("change", change.name, change.value, change.source))


def run_python_node(replay=None, ticks: int = 30) -> tuple[list, str]:
    """Ticks PyGain `ticks` times (recording: until a write from another thread took effect
    too), returning its log and the recording."""
    log, written = [], threading.Event()
    scheduler = horus.Scheduler(tick_rate=100, deterministic=True, recording=True, replay=replay)
    scheduler.add(PyGain(log))

    def write() -> None:
        while sum(1 for entry in log if entry[0] == "tick") < ticks // 3:
            time.sleep(0.001)
        with horus.Params("py_gain") as params:
            assert params.set("gain", 3.0, source="test writer").accepted
        written.set()

    if replay is None:
        threading.Thread(target=write, daemon=True).start()
    else:
        written.set()
    done = 0
    while done < ticks or not written.is_set():
        scheduler.tick_once()
        done += 1
        if replay is None:
            time.sleep(0.002)
    return log, scheduler.stop_recording()[0]


def test_a_python_node_replays_its_parameter_changes(namespace):
    live, recorded = run_python_node()
    assert [e for e in live if e[0] == "change"] == [("change", "gain", 3.0, "test writer")]
    ticks = [e for e in live if e[0] == "tick"]
    replayed, _ = run_python_node(recorded, ticks=len(ticks))
    assert [e for e in replayed if e[0] == "change"] == [("change", "gain", 3.0, "replay")]
    assert [e for e in replayed if e[0] == "tick"] == ticks
