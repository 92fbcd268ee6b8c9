"""A running Python scheduler changed as seed 001's "Runtime Mutation" has it: nodes added from
another thread and from a tick, add_critical_node while running; and the seed's units and
timestamps: `100 * us` stays 100 microseconds, horus.timestamp_now() is now() in nanoseconds."""
from __future__ import annotations

import json
import threading
import time

import horus
from horus import Node, Scheduler, ms, us


def wait_for(condition, what: str, timeout: float = 20.0) -> None:
    give_up = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < give_up, f"timed out waiting for {what}"
        time.sleep(0.002)


def announced(node: str) -> bool:
    for entry in horus._core.list_presence():
        if entry["alive"] and entry["snapshot_json"]:
            snapshot = json.loads(entry["snapshot_json"])
            if any(n["name"] == node for n in snapshot.get("nodes", [])):
                return True
    return False


def test_a_node_added_from_another_thread_starts_ticks_and_shuts_down_in_order():
    journal = []
    late_ticks = []
    sched = Scheduler(tick_rate=500)
    sched.add(Node(name="base", tick=lambda n: None, order=0,
                   shutdown=lambda n: journal.append("shutdown:base")))
    sched.add(Node(name="motor", tick=lambda n: None, rate=200, order=20,
                   shutdown=lambda n: journal.append("shutdown:motor")))
    runner = threading.Thread(target=sched.run)
    runner.start()
    try:
        wait_for(lambda: sched.get_node_stats("motor")["total_ticks"] > 2, "the first ticks")
        assert sched.add(Node(name="lidar", rate=100, order=10,
                              init=lambda n: journal.append("init:lidar"),
                              tick=lambda n: late_ticks.append(horus.tick()),
                              shutdown=lambda n: journal.append("shutdown:lidar"))) is sched
        assert sched.get_node_names() == ["base", "lidar", "motor"]
        wait_for(lambda: len(late_ticks) >= 3, "the added node's ticks")
        info = {i["name"]: i for i in sched.get_all_nodes()}["lidar"]
        assert (info["state"], info["execution_class"], info["rate"]) == ("Running", "Rt", 100.0)
        wait_for(lambda: announced("lidar"), "the added node in the presence announcement")
    finally:
        sched.stop()
        runner.join(timeout=30)
    assert not runner.is_alive()
    assert late_ticks[:3] == [0, 1, 2]
    assert journal == ["init:lidar", "shutdown:motor", "shutdown:lidar", "shutdown:base"]


def test_a_node_added_from_a_tick_does_not_deadlock():
    child_ticks = []
    sched = Scheduler(tick_rate=500)

    def spawn(node):
        if horus.tick() == 2:
            sched.add(Node(name="child", tick=lambda n: child_ticks.append(horus.tick()),
                           rate=200, order=1))

    sched.add(Node(name="parent", tick=spawn, rate=200, order=0))
    runner = threading.Thread(target=sched.run)
    runner.start()
    try:
        wait_for(lambda: len(child_ticks) >= 3, "the node added by a tick to tick")
    finally:
        sched.stop()
        runner.join(timeout=30)
    assert not runner.is_alive()
    assert sched.stop_reason() == "stop() called"


def test_a_node_added_from_a_tick_in_deterministic_mode_ticks_at_its_rate():
    stamps = []
    sched = Scheduler(tick_rate=100, deterministic=True)

    def spawn(node):
        if horus.tick() == 2:
            sched.add(Node(name="late", tick=lambda n: stamps.append(horus.timestamp_now()),
                           rate=25, order=5))

    sched.add(Node(name="spawner", tick=spawn, order=0))
    for _ in range(20):
        sched.tick_once()
    # Added in the third cycle (20 ms), started in the next one: every 40 ms from 30 ms.
    assert stamps == [30_000_000, 70_000_000, 110_000_000, 150_000_000, 190_000_000]


def test_add_critical_node_while_running():
    sched = Scheduler(tick_rate=500)
    sched.add(Node(name="motor", tick=lambda n: None, rate=100, order=0))
    runner = threading.Thread(target=sched.run)
    runner.start()
    try:
        wait_for(lambda: sched.get_node_stats("motor")["total_ticks"] > 2, "the first ticks")
        assert sched.add_critical_node("motor", timeout_ms=200) is sched
        info = sched.get_all_nodes()[0]
        assert info["critical"] and round(info["watchdog"] * 1e9) == 200_000_000
    finally:
        sched.stop()
        runner.join(timeout=30)
    assert not runner.is_alive()


def test_integer_multiples_of_us_and_ms_stay_exact():
    sched = Scheduler(tick_rate=1000)
    for n in range(1, 1000):
        sched.add(Node(name=f"n{n}", tick=lambda node: None, rate=100,
                       budget=n * us, deadline=n * us + 5 * ms, watchdog=n * ms))
    for info in sched.get_all_nodes():
        n = int(info["name"][1:])
        assert round(info["budget"] * 1e9) == n * 1_000, info
        assert round(info["deadline"] * 1e9) == n * 1_000 + 5_000_000, info
        assert round(info["watchdog"] * 1e9) == n * 1_000_000, info
    assert sched.set_tick_budget("n1", 100)  # microseconds, as the seed has it
    assert round(sched.get_all_nodes()[0]["budget"] * 1e9) == 100_000


def test_timestamp_now_is_now_in_integer_nanoseconds():
    wall = []

    def read():  # on a fresh thread: no tick has run there, so this is the wall clock
        wall.extend((time.time_ns(), horus.timestamp_now(), time.time_ns()))

    reader = threading.Thread(target=read)
    reader.start()
    reader.join()
    before, stamp, after = wall
    assert isinstance(stamp, int) and before <= stamp <= after

    seen = []
    sched = Scheduler(tick_rate=1000, deterministic=True)
    sched.add(Node(name="clock", tick=lambda n: seen.append((horus.timestamp_now(), horus.now()))))
    for _ in range(3):
        sched.tick_once()
    assert [t for t, _ in seen] == [0, 1_000_000, 2_000_000]
    assert all(round(now * 1e9) == t for t, now in seen)
    assert horus.timestamp_now() == 2_000_000  # after a tick, the clock that tick saw
