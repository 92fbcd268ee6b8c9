"""The live view served from inside a scheduler's process, read by a Foxglove client
(client_check.mjs): Python's `horus.Scheduler(view=...)` (with simulated time when
deterministic) and its argument errors, and a C++ program's `SchedulerConfig::view()`
(view_in_process.cpp): serving, refusing a taken port, and refusing to start unlinked."""
from __future__ import annotations

import os

import horus
import pytest
from conftest import run_node_client
from processes import stderr_after_kill, wait_line

# Set by tests/view/CMakeLists.txt: view_in_process.cpp linked with horus::view, and without.
PROGRAM = os.environ.get("HORUS_VIEW_IN_PROCESS", "")
UNLINKED_PROGRAM = os.environ.get("HORUS_VIEW_IN_PROCESS_UNLINKED", "")
# Far below any wall-clock time in nanoseconds (1.7e18 in 2023): simulated time starts at 0.
SIMULATED_TIME_LIMIT = 10**15

# A Python scheduler serving its namespace while a node publishes CmdVel at 50 Hz of its ticks;
# argv[1] "1" makes it deterministic, its ticks paced so that simulated time moves at about the
# wall clock's pace, from 0.
PYTHON_PROGRAM = """
import sys, time
import horus
from horus.msg import CmdVel

deterministic = sys.argv[1] == "1"
count = 0

def command(node):
    global count
    count += 1
    node.send("cmd_vel", CmdVel(stamp_nanos=count, linear=1.5, angular=-0.25))
    if deterministic:
        time.sleep(0.02)

scheduler = horus.Scheduler(tick_rate=50, deterministic=deterministic, view=0)
scheduler.add(horus.Node(name="commander", tick=command, pubs={"cmd_vel": CmdVel}))
scheduler.run()
"""


def view_url(process) -> str:
    """The URL of the `live view: ws://ADDR:PORT/` line the scheduler prints once listening."""
    return wait_line(process, "live view: ws://").split(" ", 2)[2]


def decoded_cmd_vels(url: str) -> dict:
    result = run_node_client(url, {"topics": ["cmd_vel"], "subscribe": {"cmd_vel": 3},
                                   "time": {"count": 3}})
    (run,) = result["runs"].values()
    assert "error" not in run, run
    channels = {channel["topic"]: channel for channel in run["channels"]}
    assert channels["cmd_vel"]["schemaName"] == "horus.msg.CmdVel"
    received = run["messages"]["cmd_vel"]
    assert [(m["linear"], m["angular"]) for m in received["decoded"]] == [(1.5, -0.25)] * 3
    stamps = [int(m["stamp_nanos"]) for m in received["decoded"]]
    assert stamps == sorted(stamps) and len(set(stamps)) == 3, stamps
    return run


def test_python_scheduler_serves_its_namespace(namespace, children):
    process = children.python(PYTHON_PROGRAM, dict(os.environ), "0")
    run = decoded_cmd_vels(view_url(process))
    # The wall clock, not simulated time.
    assert all(int(t) > SIMULATED_TIME_LIMIT for t in run["times"]), run["times"]


def test_a_deterministic_schedulers_view_tells_simulated_time(namespace, children):
    process = children.python(PYTHON_PROGRAM, dict(os.environ), "1")
    run = decoded_cmd_vels(view_url(process))
    times = [int(t) for t in run["times"]]
    assert all(0 < t < SIMULATED_TIME_LIMIT for t in times), times
    assert times == sorted(times), times
    stamps = [int(t) for t in run["messages"]["cmd_vel"]["timestamps"]]
    assert all(0 < t < SIMULATED_TIME_LIMIT for t in stamps), stamps


@pytest.mark.parametrize("view, error, text", [
    (-1, ValueError, "port must be a TCP port (0..65535, 0: any free one), got -1"),
    (70000, ValueError, "port must be a TCP port (0..65535, 0: any free one), got 70000"),
    ("8765", TypeError, "view takes True, a port number or a horus.View, got str"),
])
def test_python_view_argument_errors(namespace, view, error, text):
    with pytest.raises(error) as raised:
        horus.Scheduler(view=view)
    assert str(raised.value) == text


def test_horus_view_argument_errors():
    with pytest.raises(ValueError, match=r"^listen must be an IP address of this machine, got "
                                         r"'localhost'$"):
        horus.View(listen="localhost")
    with pytest.raises(ValueError, match=r"^discovery_interval must be at least 0.001 s"):
        horus.View(discovery_interval=0)
    with pytest.raises(ValueError, match=r"^port must be a TCP port"):
        horus.View(port=True)
    assert repr(horus.View(port=0)) == \
        "View(port=0, listen='127.0.0.1', discovery_interval=0.25)"


def test_a_python_view_that_cannot_listen_fails_the_schedulers_construction(namespace,
                                                                             children):
    first = children.python(PYTHON_PROGRAM, dict(os.environ), "0")
    port = view_url(first).rstrip("/").rsplit(":", 1)[1]
    with pytest.raises(horus.HorusError) as raised:
        horus.Scheduler(view=int(port))
    assert "view: " in str(raised.value) and port in str(raised.value), str(raised.value)


def test_cpp_scheduler_serves_its_namespace(namespace, children):
    assert PROGRAM, "HORUS_VIEW_IN_PROCESS names view_in_process; run this suite through ctest"
    process = children.start([PROGRAM, "0"], dict(os.environ))
    run = decoded_cmd_vels(view_url(process))
    assert all(int(t) > SIMULATED_TIME_LIMIT for t in run["times"]), run["times"]


def test_a_cpp_view_that_cannot_listen_fails_the_schedulers_construction(namespace, children):
    first = children.start([PROGRAM, "0"], dict(os.environ))
    port = view_url(first).rstrip("/").rsplit(":", 1)[1]
    second = children.start([PROGRAM, port], dict(os.environ))
    assert second.wait(timeout=60) == 1
    second.errors.wait_closed()
    errors = second.errors.text()
    assert errors.startswith("view_in_process: ") and "view: " in errors and port in errors, \
        errors
    assert second.stdout.read() == ""  # no `live view:` line


def test_a_cpp_program_not_linked_with_the_view_is_told_so(namespace, children):
    process = children.start([UNLINKED_PROGRAM, "0"], dict(os.environ))
    assert process.wait(timeout=60) == 1, stderr_after_kill(process)
    process.errors.wait_closed()
    errors = process.errors.text()
    assert "this program has no live view: link it with horus::view" in errors, errors
