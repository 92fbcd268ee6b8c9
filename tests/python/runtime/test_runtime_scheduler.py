"""The Python runtime's own guarantees: subclass nodes, C++ and Python nodes in one scheduler, the
GIL, tracebacks in the log, and Ctrl+C / SIGTERM stopping run() cleanly."""
from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

import horus
from horus import Node, Scheduler
from horus.msg import CmdVel

from .conftest import python_child


class Motor(Node):
    def __init__(self):
        super().__init__(name="motor", rate=100, order=5, subs={"cmd_vel": CmdVel})
        self.events = []

    def init(self):
        self.events.append("init")

    def tick(self):
        msg = self.recv("cmd_vel")
        if msg is not None:
            self.events.append(msg.linear)

    def shutdown(self):
        self.events.append("shutdown")


def test_subclass_style_node_with_typed_topics():
    motor = Motor()
    sched = Scheduler(tick_rate=100, deterministic=True).add(motor)
    sched.tick_once()
    horus.Topic(CmdVel, "cmd_vel").send(CmdVel(linear=0.75))
    sched.tick_once()
    del sched
    assert motor.events == ["init", 0.75, "shutdown"]


def test_a_node_without_tick_is_refused():
    with pytest.raises(ValueError, match="has no tick"):
        Scheduler().add(Node(name="idle"))


def test_bad_settings_are_refused_with_the_reason():
    with pytest.raises(ValueError, match="rate"):
        Node(name="x", tick=lambda n: None, rate=0)
    with pytest.raises(ValueError, match="budget"):
        Node(name="x", tick=lambda n: None, budget=-1.0)
    with pytest.raises(TypeError, match="subs"):
        Node(name="x", tick=lambda n: None, subs="scan")
    with pytest.raises(horus.HorusError, match="duplicate node name"):
        Scheduler().add(Node(name="x", tick=lambda n: None)).add(Node(name="x", tick=lambda n: None))


def test_python_and_cpp_nodes_in_one_scheduler():
    import horus_test_nodes
    got = []

    def source(node):
        node.send("raw", CmdVel(linear=float(horus.tick() + 1)))

    def sink(node):
        while (msg := node.recv("doubled")) is not None:
            got.append(msg.linear)

    doubler = horus_test_nodes.CmdVelDoubler("doubler", "raw", "doubled")
    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="source", tick=source, rate=100, order=0, pubs={"raw": CmdVel}))
    sched.add(doubler, order=10, rate=100)
    sched.add(Node(name="sink", tick=sink, rate=100, order=20, subs={"doubled": CmdVel}))
    for _ in range(5):
        sched.tick_once()
    assert got == [2.0, 4.0, 6.0, 8.0, 10.0]
    assert doubler.forwarded == 5
    assert sched.get_node_names() == ["source", "doubler", "sink"]


def test_cpp_node_keeps_ticking_while_python_holds_the_gil():
    import horus_test_nodes
    doubler = horus_test_nodes.CmdVelDoubler("doubler", "raw", "doubled")
    sched = Scheduler(tick_rate=1000).add(doubler, order=0, rate=1000)
    runner = threading.Thread(target=sched.run)
    runner.start()
    try:
        while (sched.get_node_stats("doubler") or {}).get("total_ticks", 0) == 0:
            time.sleep(0.001)
        before = sched.get_node_stats("doubler")["total_ticks"]
        # One long C call that holds the GIL throughout (sum() over a range never lets the
        # interpreter switch threads): a node that needed the GIL could not tick meanwhile.
        sum(range(30_000_000))
        assert sched.get_node_stats("doubler")["total_ticks"] >= before + 50
    finally:
        sched.stop()
        runner.join()


def test_exception_goes_to_policy_with_its_traceback_in_the_log(capfd):
    def tick(node):
        helper_that_fails()

    def helper_that_fails():
        raise KeyError("wheel_left")

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="wheels", tick=tick, rate=100, failure_policy="ignore"))
    sched.tick_once()
    horus._core.flush_log()
    err = capfd.readouterr().err
    assert "Traceback (most recent call last)" in err
    assert "helper_that_fails" in err and "KeyError: 'wheel_left'" in err
    # The exception's line comes first, so a one-line record (the blackbox) keeps what failed.
    assert "Node error: KeyError: 'wheel_left'\nTraceback" in err, err
    assert sched.get_node_stats("wheels")["errors_count"] == 1


@pytest.mark.parametrize("signo", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_run_cleanly_with_reverse_shutdown(signo):
    child = python_child(textwrap.dedent("""
        import horus
        def down(node):
            print("down", node.name, flush=True)
        def tick(node):
            if horus.tick() == 5 and node.name == "a":
                print("running", flush=True)
        nodes = [horus.Node(name=n, tick=tick, shutdown=down, rate=100) for n in ("a", "b", "c")]
        code = horus.run(*nodes, tick_rate=100)
        print("returned", code, flush=True)
    """))
    assert child.stdout.readline().strip() == "running"
    child.send_signal(signo)
    out, err = child.communicate(timeout=30)
    assert child.returncode == 0, err
    lines = [line for line in out.splitlines() if line != "running"]
    assert lines == ["down c", "down b", "down a", "returned 0"]


def test_run_from_a_python_thread_that_then_ends():
    # Callbacks on the thread that called run() use that thread's own Python state, which Python
    # frees when the thread ends; a C++ scheduler thread's state is freed by the runtime.
    child = python_child(textwrap.dedent("""
        import threading, horus
        ticks = []
        nodes = [horus.Node(name="main", tick=lambda n: ticks.append(1)),
                 horus.Node(name="rt", tick=lambda n: ticks.append(2), rate=200)]
        sched = horus.Scheduler(tick_rate=200)
        for node in nodes:
            sched.add(node)
        runner = threading.Thread(target=sched.run, kwargs={"duration": 0.2})
        runner.start()
        runner.join()
        again = horus.Scheduler(tick_rate=200).add(horus.Node(name="x", tick=lambda n: None))
        again.run(duration=0.05)
        print(1 in ticks, 2 in ticks, flush=True)
    """))
    out, err = child.communicate(timeout=60)
    assert child.returncode == 0, err
    assert out.split() == ["True", "True"]


def test_a_failed_test_holding_a_scheduler_does_not_crash_pytest_at_exit(tmp_path):
    # The failed test's traceback keeps its scheduler until the interpreter finalizes; the node
    # shutdowns then ran on threads CPython ends, and the process aborted instead of reporting.
    test_file = tmp_path / "test_holds_a_scheduler.py"
    test_file.write_text(textwrap.dedent("""
        import horus

        class Lidar(horus.Node):
            def tick(self):
                pass

        def test_fails_holding_its_scheduler():
            sched = horus.Scheduler(tick_rate=100)
            sched.add(Lidar(name="lidar", rate=100))
            sched.tick_once()
            assert sched is None
    """))
    child = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                            str(test_file)], capture_output=True, text=True, timeout=120)
    assert child.returncode == 1, child.stdout + child.stderr  # one failed test, no abort
    assert "1 failed" in child.stdout and "FATAL" not in child.stderr, child.stderr


def test_a_dropped_scheduler_releases_its_python_nodes():
    import gc
    import weakref

    node = Node(name="n", tick=lambda n: None, shutdown=lambda n: None)
    sched = Scheduler(tick_rate=100, deterministic=True).add(node)
    sched.tick_once()
    alive = weakref.ref(node)
    del node, sched
    gc.collect()
    assert alive() is None


def test_a_python_nodes_messages_count_in_its_metrics():
    # As a C++ node's: what its topics send and return inside its callbacks, typed, dict and
    # loaned alike; nothing outside callbacks.
    def publish(node):
        node.send("cmd_vel", CmdVel(linear=0.5))
        node.send("status", {"ok": True})
        topic = node._topics["cmd_vel"]
        topic.publish(topic.loan())

    got = []

    def listen(node):
        while (msg := node.recv("cmd_vel")) is not None:
            got.append(msg)
        while (msg := node.recv("status")) is not None:
            got.append(msg)

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="pub", tick=publish, order=0, pubs={"cmd_vel": CmdVel, "status": dict}))
    sched.add(Node(name="sub", tick=listen, order=1, subs={"cmd_vel": CmdVel, "status": dict}))
    horus.Topic(CmdVel, "cmd_vel").send(CmdVel())  # not in a callback: counted for no node
    for _ in range(3):
        sched.tick_once()
    assert len(got) == 9
    pub, sub = sched.get_node_stats("pub"), sched.get_node_stats("sub")
    assert (pub["messages_sent"], pub["messages_received"]) == (9, 0)
    assert (sub["messages_sent"], sub["messages_received"]) == (0, 9)


def test_telemetry_exports_the_python_nodes_metrics_as_json(tmp_path):
    import json

    path = tmp_path / "telemetry.json"
    node = Node(name="beacon", tick=lambda n: n.send("beat", {"n": 1}), rate=100, order=3)
    sched = Scheduler(tick_rate=100, telemetry=f"file://{path}", name="exporter").add(node)
    assert sched.run(duration=0.2) == 0
    snapshot = json.loads(path.read_text())
    assert snapshot["scheduler"] == "exporter"
    (beacon,) = [n for n in snapshot["nodes"] if n["name"] == "beacon"]
    stats = sched.get_node_stats("beacon")
    assert beacon["order"] == 3 and beacon["total_ticks"] == stats["total_ticks"] > 0
    assert beacon["messages_sent"] == stats["messages_sent"] == stats["total_ticks"]


def test_a_bad_telemetry_endpoint_is_refused_with_the_reason():
    with pytest.raises(horus.HorusError, match="expected udp://HOST:PORT or file:///PATH"):
        Scheduler(telemetry="http://localhost:1")
    with pytest.raises(horus.HorusError, match="must be absolute"):
        Scheduler(telemetry="file://relative.json")
