"""The `horus` command against live C++ processes: a C++ scheduler whose node publishes a
standard type at 100 Hz and logs with HORUS_LOG_INFO (horus_py_peer's `node` role), and a C++
process of the user package cli_user, built by this folder's CMakeLists.txt and unknown to the
command (horus_cli_user_peer)."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess

from conftest import HORUS, run_horus, wait_ready
from processes import wait_until


def _echo_json(topic: str) -> dict:
    result = run_horus("topic", "echo", topic, "--once", "--json", "--timeout", "10")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def _rows(listing: str) -> dict[str, list[str]]:
    return {line.split()[0]: line.split() for line in listing.splitlines()[1:]}


def test_a_live_cpp_scheduler_is_listed_echoed_measured_and_its_log_followed(children):
    talker = children.program(os.environ["HORUS_PY_PEER"], "node", "cmdvel", "cpp_cmd", "100")
    wait_ready(talker)

    row = _rows(run_horus("topic", "list", "-v").stdout)["cpp_cmd"]
    assert row[1:4] == ["horus.msg.CmdVel", "1", "0"], row
    assert float(row[4]) > 0, row  # it publishes every 10 ms

    def info_with_the_talker():
        info = run_horus("topic", "info", "cpp_cmd").stdout
        # A process's announcement is written a moment after its topics change (coalesced).
        return info if f"open in: pid {talker.pid} (horus_py_peer)" in info else None
    info = wait_until(info_with_the_talker, "the C++ process in topic info")
    assert "type: horus.msg.CmdVel" in info and "publishers: 1" in info

    nodes = wait_until(lambda: json.loads(run_horus("node", "list", "--json").stdout),
                       "the C++ scheduler's announcement")
    assert [(n["name"], n["pid"]) for n in nodes] == [("cpp_talker", talker.pid)]
    assert nodes[0]["publishers"] == [{"topic": "cpp_cmd", "type": "horus.msg.CmdVel"}]

    # The talker sends linear = i, angular = -i for its i-th message: two looks a moment apart
    # show what it sent, and that it is still sending.
    first = _echo_json("cpp_cmd")
    assert first["stamp_nanos"] == 0 and first["linear"] >= 1
    assert first["linear"] == int(first["linear"]) and first["angular"] == -first["linear"]

    def newer():
        message = _echo_json("cpp_cmd")
        return message if message["linear"] > first["linear"] else None
    later = wait_until(newer, "a newer message")
    assert later["angular"] == -later["linear"]

    # The acceptance bar: within 10 % of the publisher's 100 Hz.
    hz = json.loads(run_horus("topic", "hz", "cpp_cmd", "--once", "--window", "2",
                              "--json").stdout)
    assert 90 <= hz["rate_hz"] <= 110, hz

    records = wait_until(lambda: json.loads(run_horus("log", "--node", "cpp_talker",
                                                      "--json").stdout),
                         "cpp_talker's log lines")
    assert all(r["source"] == "cpp_talker" and r["pid"] == talker.pid and r["level"] == "INFO"
               and r["message"].startswith("sent ") for r in records), records
    newest = max(int(r["message"].split()[-1]) for r in records)
    follow = subprocess.Popen([HORUS, "log", "--follow", "--node", "cpp_talker"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # Lines the C++ node logs after the command started reach it without running it again.
        for _ in range(200):
            line = follow.stdout.readline()
            assert line, follow.stderr.read()
            assert " INFO cpp_talker: sent " in line, line
            if int(line.split()[-1]) > newest:
                break
        else:
            raise AssertionError("--follow never showed a new line")
    finally:
        follow.kill()
        follow.communicate()


POSE = {"gear": "Drive", "x": 1.5, "label": "dock", "corners": [[1.0, 2.0], [3.0, 4.0]]}
PARKED = {"gear": "Park", "x": -2.0, "label": "", "corners": [[0.0, 0.0], [0.0, 0.0]]}


def test_a_live_cpp_process_of_a_user_type_is_listed_echoed_and_fed(children):
    # The command's path holds the standard types only: cli_user reaches it as stored schemas.
    assert importlib.util.find_spec("cli_user") is None
    peer = children.program(os.environ["HORUS_CLI_USER_PEER"])
    wait_ready(peer)

    listing = {t["name"]: t for t in json.loads(run_horus("topic", "list", "--json").stdout)}
    assert sorted(listing) == ["pose", "pose_in", "route", "route_in"]
    assert listing["pose"]["type_name"] == "cli_user.Pose" and listing["pose"]["publishers"] == 1
    assert listing["route"]["type_name"] == "cli_user.Route"
    assert listing["pose_in"]["subscribers"] == 1 and listing["route_in"]["subscribers"] == 1
    rows = _rows(run_horus("topic", "list", "-v").stdout)
    assert rows["route"][1:4] == ["cli_user.Route", "1", "0"], rows

    def info_with_the_peer():
        info = json.loads(run_horus("topic", "info", "pose", "--json").stdout)
        return info if [p["pid"] for p in info["processes"]] == [peer.pid] else None
    info = wait_until(info_with_the_peer, "the C++ process in topic info")
    assert info["is_pod"] and "label: string<16>" in info["schema"]
    text = run_horus("topic", "info", "route").stdout
    assert "type: cli_user.Route" in text and "encoding: serialized" in text
    assert f"open in: pid {peer.pid} (" in text

    # What the C++ side sent (user_peer.cpp), decoded from the stored schemas alone.
    assert _echo_json("pose") == POSE
    assert _echo_json("route") == {
        "name": "to dock", "poses": [POSE, PARKED], "speed": 0.25,
        "accel": {"linear": [0.5, 0.0, 0.0], "angular": [0.0, 0.0, 0.0], "timestamp_ns": 0}}

    result = run_horus("topic", "pub", "pose_in", "{gear: Drive, x: 7.25, label: shelf}", "--once")
    assert result.returncode == 0, result.stderr
    assert peer.stdout.readline().strip() == "pose Drive 7.25 shelf"
    result = run_horus("topic", "pub", "route_in",
                       '{"name": "back", "poses": [{"x": 1}, {"x": 2}], "speed": null}', "--once")
    assert result.returncode == 0, result.stderr
    assert peer.stdout.readline().strip() == "route back 1 2 no speed"
