"""Verbose topics and the blackbox's ticks through the `horus` command: a Python program's
verbose topics (messages, plain values, dict values) reach `horus log` with their summaries,
rate-limited under a 1 kHz sender with a count of what was suppressed; a Python scheduler's
blackbox dump shows its last ticks (node, start, duration, topics) in `horus blackbox`."""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys

from conftest import run_horus

VERBOSE_SENDER = """
import time, horus
from horus.msg import CmdVel
cmd = horus.Topic(CmdVel, "cmd_vel", verbose=True)
cmd_in = horus.Topic(CmdVel, "cmd_vel", verbose=True)
status = horus.Topic(dict, "status", verbose=True)
quiet = horus.Topic(dict, "quiet")
cmd.send(CmdVel(linear=1.0, angular=0.5))
cmd_in.try_recv()
status.send("docking")
status.send({{"battery": 0.5, "ok": True}})
quiet.send(1)
speed = horus.Topic(float, "speed", verbose=True)
assert speed.verbose
start = time.monotonic()
next_send = start
for i in range({count}):
    next_send += 0.001
    time.sleep(max(0.0, next_send - time.monotonic()))
    speed.send(i + 0.5)
speed.verbose = False  # reports what it still held back
print(time.monotonic() - start, flush=True)
"""

PY_BLACKBOX = """
import horus
topic = horus.Topic(dict, "py.cmd")
inbox = horus.Topic(dict, "py.cmd")
def drive(node):
    topic.send({{"v": 1}})
def steer(node):
    while inbox.try_recv() is not None:
        pass
sched = horus.Scheduler(deterministic=True, blackbox_mb=1, name="pyrover")
sched.add(horus.Node(name="drive", tick=drive, order=0))
sched.add(horus.Node(name="steer", tick=steer, order=1))
for _ in range(3):
    sched.tick_once()
sched.dump_blackbox({path!r})
"""


def run_python(script: str) -> str:
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout


def log_records() -> list[dict]:
    result = run_horus("log", "--json")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_verbose_topics_lines_reach_horus_log_with_their_summaries():
    run_python(VERBOSE_SENDER.format(count=20))
    from horus.msg import CmdVel

    summary = CmdVel(linear=1.0, angular=0.5).log_summary()
    messages = [r["message"] for r in log_records()]
    assert f"cmd_vel send: {summary}" in messages, messages
    assert f"cmd_vel recv: {summary}" in messages, messages
    assert 'status send: "docking"' in messages, messages
    assert "status send: {battery: 0.5, ok: true}" in messages, messages
    assert "speed send: 0.5" in messages, messages
    assert not [m for m in messages if m.startswith("quiet")], "a quiet topic logged"
    text = run_horus("log").stdout
    assert re.search(r"Z INFO -: speed send: 0\.5$", text, re.M), text


def test_a_1khz_verbose_sender_is_rate_limited_with_a_suppressed_count():
    count = 1000
    seconds = float(run_python(VERBOSE_SENDER.format(count=count)))
    messages = [r["message"] for r in log_records()]
    logged = [m for m in messages if m.startswith("speed send: ")]
    reports = [m for m in messages if m.startswith("speed: ")]
    suppressed = 0
    for report in reports:
        found = re.fullmatch(r"speed: (\d+) lines suppressed \(a verbose topic logs at most 10 "
                             r"lines a second\)", report)
        assert found, report
        suppressed += int(found.group(1))
    assert reports, "no count of the suppressed lines"
    assert len(logged) + suppressed == count, (len(logged), suppressed)
    # Ten lines per one-second window begun, however fast the machine ran the sender.
    assert len(logged) <= 10 * (math.ceil(seconds) + 1), (len(logged), seconds)
    assert logged[0] == "speed send: 0.5"


def test_a_python_schedulers_blackbox_shows_its_last_ticks_in_horus_blackbox(tmp_path):
    path = tmp_path / "pyrover.blackbox"
    run_python(PY_BLACKBOX.format(path=str(path)))
    shown = run_horus("blackbox", str(path), "--ticks", "4")
    assert shown.returncode == 0, shown.stderr
    assert f"{path}: 6 ticks (4 shown)" in shown.stdout, shown.stdout
    rows = shown.stdout.split("tick start (UTC)", 1)[1].splitlines()[1:]
    assert len(rows) == 4, shown.stdout
    for row, (node, tick, topics) in zip(rows, [("drive", 1, "py.cmd 1/0"),
                                                ("steer", 1, "py.cmd 0/1"),
                                                ("drive", 2, "py.cmd 1/0"),
                                                ("steer", 2, "py.cmd 0/1")]):
        fields = row.split()
        assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z", fields[0]), row
        assert fields[1:3] == [node, str(tick)], row
        assert float(fields[3]) >= 0, row
        assert row.endswith(topics), row
    only_steer = run_horus("blackbox", str(path), "--node", "steer").stdout
    assert ": 6 ticks (3 shown)" in only_steer, only_steer
