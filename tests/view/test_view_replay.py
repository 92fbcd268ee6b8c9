"""`horus record replay FILE --view`: the replayed namespace served to a Foxglove client
(client_check.mjs) whose timeline is the recording's: each message stamped with its recorded log
time, and the server's `time` inside the recording's span."""
from __future__ import annotations

import os
import subprocess

from conftest import run_node_client
from horus import mcap as horus_mcap
from horus.msg import CmdVel
from processes import wait_line

# Set by tests/view/CMakeLists.txt: the build tree's bin/horus.
CLI = os.environ.get("HORUS_CLI", "")
# 2023-11-14, far from now: a stamp the wall clock gave could never pass for one of these.
FIRST_LOG_TIME = 1_700_000_000_000_000_000
INTERVAL_NS = 100_000_000
COUNT = 50


def log_time(index: int) -> int:
    return FIRST_LOG_TIME + index * INTERVAL_NS


def write_cmd_vels(path) -> None:
    """COUNT CmdVel messages 100 ms apart, message i's linear being i (what says which it is)."""
    meta = CmdVel.__horus__
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream)
        schema = writer.add_schema(meta.name, "horus.hmsg", meta.schema.encode())
        channel = writer.add_channel(
            "cmd_vel", "horus.pod", schema,
            {"horus.fingerprint": f"{meta.fingerprint:016x}", "horus.type": meta.name,
             "horus.payload_size": str(meta.size)})
        for index in range(COUNT):
            writer.add_message(channel, log_time(index),
                               CmdVel(linear=float(index), angular=0.0).to_bytes(), sequence=index)
        writer.finish()


def test_a_viewer_of_a_replay_sees_the_recorded_times(tmp_path, namespace, children):
    assert CLI, "HORUS_CLI names build/bin/horus; run this suite through ctest"
    path = tmp_path / "cmd_vel.mcap"
    write_cmd_vels(path)
    replay = children.start([CLI, "record", "replay", str(path), "--view", "--view-port", "0"],
                            dict(os.environ))
    url = wait_line(replay, "live view: ws://").split(" ", 2)[2]

    result = run_node_client(url, {"topics": ["cmd_vel"], "subscribe": {"cmd_vel": 3},
                                   "time": {"count": 3}})

    (run,) = result["runs"].values()
    assert "error" not in run, run
    received = run["messages"]["cmd_vel"]
    indexes = [int(message["linear"]) for message in received["decoded"]]
    assert [int(stamp) for stamp in received["timestamps"]] == [log_time(i) for i in indexes], \
        (indexes, received["timestamps"])
    times = [int(stamp) for stamp in run["times"]]
    assert all(FIRST_LOG_TIME <= t <= log_time(COUNT - 1) for t in times), times
    assert times == sorted(times), times

    out, errors = replay.communicate(timeout=30)
    assert replay.returncode == 0, errors
    assert f"replayed {COUNT} messages on 1 topics" in out


def test_view_port_without_view_is_a_usage_error(tmp_path, namespace):
    path = tmp_path / "cmd_vel.mcap"
    write_cmd_vels(path)
    done = subprocess.run([CLI, "record", "replay", str(path), "--view-port", "0"],
                          capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stderr) == (
        2, "horus: --view-port is the live view's: add --view\n")


def test_a_taken_port_is_refused_before_anything_is_replayed(tmp_path, namespace, children):
    path = tmp_path / "cmd_vel.mcap"
    write_cmd_vels(path)
    first = children.start([CLI, "record", "replay", str(path), "--view", "--view-port", "0"],
                           dict(os.environ))
    port = wait_line(first, "live view: ws://").rstrip("/").rsplit(":", 1)[1]
    # Into another namespace, so that what the refused replay leaves there can be seen.
    other = f"{namespace}_other"
    done = subprocess.run([CLI, "-n", other, "record", "replay", str(path), "--view",
                           "--view-port", port], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and done.stderr.startswith("horus: "), done
    assert port in done.stderr and done.stderr.count("\n") == 1, done.stderr
    assert "replayed" not in done.stdout
    listed = subprocess.run([CLI, "-n", other, "topic", "list"], capture_output=True, text=True,
                            timeout=60)
    assert (listed.returncode, listed.stdout) == (0, ""), listed
