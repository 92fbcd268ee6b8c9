"""Every code example of seed 001 (the Scheduler deep-dive), as written there, topic names aside."""
from __future__ import annotations

import os
import textwrap
import threading
import time

import pytest

import horus
from horus import Node, Scheduler, ms, us

from .conftest import python_child


def test_unit_constants():
    assert us == 1e-6 and ms == 1e-3
    assert 300 * us == pytest.approx(0.0003)


def test_horus_run_one_liner_moves_data_sensor_to_motor():
    driven = []

    def read_sensor(node):
        node.send("scan", {"ranges": [1.0, 2.0, 3.0]})

    def navigate(node):
        if node.has_msg("scan"):
            scan = node.recv("scan")
            node.send("cmd", {"linear": 0.5, "angular": scan["ranges"][0]})

    def drive(node):
        if node.has_msg("cmd"):
            cmd = node.recv("cmd")
            driven.append(cmd)
            node.log_info(f"Driving: linear={cmd['linear']}")

    sensor = horus.Node(name="sensor", tick=read_sensor, rate=10, order=0, pubs=["scan"])
    ctrl = horus.Node(name="controller", tick=navigate, rate=30, order=10, subs=["scan"],
                      pubs=["cmd"])
    motor = horus.Node(name="motor", tick=drive, rate=1000, order=20, budget=300 * us,
                       subs=["cmd"])
    assert horus.run(sensor, ctrl, motor, rt=True, watchdog_ms=500, duration=0.5) == 0
    assert driven and driven[0] == {"linear": 0.5, "angular": 1.0}


def test_horus_run_takes_every_scheduler_keyword():
    ticks = []
    node = Node(name="n", tick=lambda n: ticks.append(horus.tick()), rate=100, order=0)
    horus.run(node, duration=0.05, tick_rate=100.0, rt=False, deterministic=True, blackbox_mb=0,
              watchdog_ms=0, recording=False, name="one_liner", cores=None,
              max_deadline_misses=None, verbose=False, telemetry=None)
    assert ticks == [0, 1, 2, 3, 4]


def test_recording_keywords_record_a_session(monkeypatch, tmp_path):
    # The seed's calls; the file itself is checked by test_runtime_recording.py.
    monkeypatch.setenv("HORUS_RECORDINGS", str(tmp_path))
    sched = Scheduler(tick_rate=100, recording=True, blackbox_mb=16)
    sched.add(Node(name="sensor", tick=lambda n: None, rate=100, order=0))
    sched.run(duration=0.05)
    assert sched.is_recording()
    files = sched.stop_recording()
    assert len(files) == 1 and os.path.exists(files[0])
    session = os.path.basename(files[0])[:-len(".mcap")]
    assert sched.list_recordings() == [session]
    sched.delete_recording(session)
    assert sched.list_recordings() == []
    assert horus.run(Node(name="n", tick=lambda n: None), recording=True, duration=0.01) == 0


def test_creating_a_scheduler_adding_and_chaining():
    sched = Scheduler(tick_rate=1000.0, rt=True, watchdog_ms=500, blackbox_mb=16,
                      max_deadline_misses=50)
    safety_fn = motor_fn = plan_fn = lambda node: None
    sched.add(Node(name="safety", tick=safety_fn, rate=1000, order=0))
    sched.add(Node(name="motor", tick=motor_fn, rate=1000, order=5, budget=300 * us))
    assert sched.add(Node(name="planner", tick=plan_fn, rate=50, order=50, compute=True)) is sched
    a, b, c = (Node(name=x, tick=lambda n: None) for x in ("a", "b", "c"))
    assert sched.add(a).add(b).add(c) is sched
    assert sched.get_node_names() == ["safety", "motor", "planner", "a", "b", "c"]
    classes = {i["name"]: i["execution_class"] for i in sched.get_all_nodes()}
    assert classes["safety"] == "Rt" and classes["planner"] == "Compute"
    assert classes["a"] == "BestEffort"


def test_deadline_miss_escalation_stops_the_scheduler_at_the_threshold():
    # Seed 001: "After 50 total deadline misses across all nodes, the scheduler stops" (3 here).
    sched = Scheduler(tick_rate=1000, max_deadline_misses=3)
    sched.add(Node(name="slow", tick=lambda n: time.sleep(0.002), rate=1000, order=0,
                   deadline=50 * us))
    sched.tick_once()
    sched.tick_once()
    assert sched.stop_reason() == ""
    sched.tick_once()
    assert sched.stop_reason().startswith(
        "max_deadline_misses (3) reached: deadline misses by node 'slow' 3;"), sched.stop_reason()
    assert sched.get_node_stats("slow")["deadline_misses"] == 3


def test_without_max_deadline_misses_misses_never_stop_the_scheduler():
    # Seed 001: max_deadline_misses defaults to None in Python (100 is Rust's, and C++'s).
    sched = Scheduler(tick_rate=1000)
    sched.add(Node(name="slow", tick=lambda n: time.sleep(0.002), rate=1000, order=0,
                   deadline=50 * us))
    for _ in range(101):
        sched.tick_once()
    assert sched.get_node_stats("slow")["deadline_misses"] == 101
    assert sched.stop_reason() == ""


def test_context_manager_stops_and_shuts_down():
    log = []
    with Scheduler(tick_rate=100, watchdog_ms=500) as sched:
        sched.add(Node(name="sensor", tick=lambda n: log.append("s"), rate=100, order=0,
                       shutdown=lambda n: log.append("sensor down")))
        sched.add(Node(name="logger", tick=lambda n: log.append("l"), rate=10, order=100,
                       shutdown=lambda n: log.append("logger down")))
        sched.run(duration=0.2)
    assert sched.status() == "stopped"
    assert log[-2:] == ["logger down", "sensor down"]
    assert "s" in log and "l" in log


def test_budget_and_deadline_auto_derivation_and_override():
    fn = lambda node: None  # noqa: E731
    sched = Scheduler(tick_rate=1000)
    sched.add(Node(name="auto", tick=fn, rate=1000, order=0))
    sched.add(Node(name="explicit", tick=fn, rate=1000, order=0, budget=300 * us,
                   deadline=900 * us))
    sched.tick_once()
    info = {i["name"]: i for i in sched.get_all_nodes()}
    assert info["auto"]["budget"] == pytest.approx(800e-6)
    assert info["auto"]["deadline"] == pytest.approx(950e-6)
    assert info["explicit"]["budget"] == pytest.approx(300e-6)
    assert info["explicit"]["deadline"] == pytest.approx(900e-6)


def test_on_miss_and_failure_policies_are_applied():
    motor = Node(name="motor", tick=lambda n: None, rate=1000, order=5, budget=300 * us,
                 deadline=900 * us, on_miss="safe_mode")
    safety = Node(name="safety_monitor", tick=lambda n: None, rate=1000, order=0,
                  budget=100 * us, deadline=200 * us, on_miss="stop")
    cloud = Node(name="cloud_upload", tick=lambda n: None, rate=1, order=200,
                 failure_policy="skip")
    sched = Scheduler().add(motor).add(safety).add(cloud)
    info = {i["name"]: i for i in sched.get_all_nodes()}
    assert info["motor"]["on_miss"] == "safe_mode"
    assert info["safety_monitor"]["on_miss"] == "stop"
    assert info["cloud_upload"]["failure_policy"] == "skip"
    with pytest.raises(ValueError, match="on_miss"):
        Node(name="x", tick=lambda n: None, on_miss="panic")
    with pytest.raises(ValueError, match="failure_policy"):
        Node(name="x", tick=lambda n: None, failure_policy="retry")


def test_stop_on_miss_stops_the_scheduler():
    def slow(node):
        time.sleep(0.01)

    sched = Scheduler(tick_rate=100)
    sched.add(Node(name="safety_monitor", tick=slow, rate=100, order=0, budget=100 * us,
                   deadline=200 * us, on_miss="stop"))
    sched.run(duration=5.0)
    assert sched.get_node_stats("safety_monitor")["total_ticks"] < 50
    assert sched.stop_reason() != ""


def test_first_tick_of_a_run_is_a_warm_up():
    # A node's first tick pays its one-time costs: run() times it but judges only later ticks
    # (runtime/python/README.md, "Deadlines and the first tick").
    def slow_first(node):
        if horus.tick() == 0:
            time.sleep(0.2)

    sched = Scheduler(tick_rate=100)
    sched.add(Node(name="safety", tick=slow_first, rate=10, order=0, deadline=50 * ms,
                   on_miss="stop"))
    assert sched.run(duration=0.5) == 0, sched.stop_reason()
    stats = sched.get_node_stats("safety")
    assert stats["total_ticks"] >= 2 and stats["max_tick_duration"] >= 0.2, stats
    assert stats["deadline_misses"] == 0 and stats["budget_overruns"] == 0, stats

    def slow_second(node):
        if horus.tick() == 1:
            time.sleep(0.2)

    judged = Scheduler(tick_rate=100)
    judged.add(Node(name="safety", tick=slow_second, rate=10, order=0, deadline=50 * ms,
                    on_miss="stop"))
    assert judged.run(duration=5.0) == 1
    assert judged.stop_reason() == "node 'safety' missed its deadline (Miss::Stop)"
    assert judged.get_node_stats("safety")["total_ticks"] == 2


def test_failure_policy_skip_keeps_ticking_and_fatal_stops():
    calls = []

    def flaky(node):
        calls.append(1)
        raise ConnectionError("network glitch")

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="cloud", tick=flaky, rate=100, order=200, failure_policy="ignore"))
    for _ in range(5):
        sched.tick_once()
    assert len(calls) == 5
    assert sched.get_node_stats("cloud")["failed_ticks"] == 5

    fatal = Scheduler(tick_rate=100)
    fatal.add(Node(name="fatal", tick=flaky, rate=100, failure_policy="fatal"))
    assert fatal.run(duration=5.0) == 1


def test_async_node_runs_its_coroutine_on_an_asyncio_loop():
    import asyncio

    uploaded = []

    async def upload_telemetry(node):
        if node.has_msg("telemetry"):
            data = node.recv("telemetry")
            await asyncio.sleep(0)
            uploaded.append(data)

    uploader = Node(name="cloud", tick=upload_telemetry, rate=1, order=200, pubs=[],
                    subs=["telemetry"], failure_policy="skip")
    assert uploader.is_async
    sched = Scheduler(tick_rate=100, deterministic=True).add(uploader)
    sched.tick_once()
    horus.Topic(dict, "telemetry").send({"battery": 24.1})
    sched.tick_for(1.0)  # rate=1: due again one simulated second later
    assert uploaded == [{"battery": 24.1}]
    assert sched.get_all_nodes()[0]["execution_class"] == "AsyncIo"


def test_event_node_wakes_on_its_topic_and_request_stop_stops_run():
    seen = []

    def handle_estop(node):
        msg = node.recv("emergency.stop")
        seen.append(msg)
        node.log_warning(f"E-STOP triggered: {msg}")
        node.request_stop()

    estop = Node(name="estop", tick=handle_estop, on="emergency.stop", order=0,
                 subs=["emergency.stop"])
    child = python_child(textwrap.dedent("""
        import horus, time
        time.sleep(0.3)
        horus.Topic(dict, "emergency.stop").send({"reason": "obstacle"})
    """))
    sched = Scheduler(tick_rate=100).add(estop)
    assert sched.get_all_nodes()[0]["execution_class"] == "Event"
    sched.run(duration=20.0)
    assert child.wait(timeout=30) == 0, child.stderr.read()
    assert seen == [{"reason": "obstacle"}]
    assert sched.status() == "stopped"


def test_compute_node_and_cpu_pinning_settings():
    def plan_path(node):
        if node.has_msg("map"):
            node.send("path", [(0, 0), (10, 10)])

    planner = Node(name="planner", tick=plan_path, rate=10, order=50, compute=True,
                   subs=["map"], pubs=["path"])
    motor = Node(name="motor", tick=lambda n: None, rate=1000, order=0, budget=300 * us,
                 core=0, priority=80)
    sched = Scheduler(tick_rate=1000).add(planner).add(motor)
    sched.run(duration=0.1)
    stats = sched.get_node_stats("planner")
    assert stats["total_ticks"] >= 1 and stats["failed_ticks"] == 0


def test_framework_clock_inside_a_tick():
    seen = {}

    def control_loop(node):
        seen["now"] = horus.now()
        seen["dt"] = horus.dt()
        seen["elapsed"] = horus.elapsed()
        seen["tick"] = horus.tick()
        seen["remaining"] = horus.budget_remaining()

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="ctl", tick=control_loop, rate=100, order=0, budget=5 * ms))
    for _ in range(3):
        sched.tick_once()
    assert seen["dt"] == 0.01 and seen["tick"] == 2
    assert seen["elapsed"] == pytest.approx(0.02)
    assert seen["remaining"] == pytest.approx(0.005)
    plain = Scheduler(tick_rate=100, deterministic=True)
    plain.add(Node(name="free", tick=control_loop, order=0))
    plain.tick_once()
    assert seen["remaining"] == float("inf")


def test_tick_once_counts_and_selective_ticking():
    counts = {"a": 0, "b": 0}

    def make(name):
        def tick(node):
            counts[name] += 1
        return tick

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="a", tick=make("a"), rate=100, order=0))
    sched.add(Node(name="b", tick=make("b"), rate=100, order=1))
    for _ in range(3):
        sched.tick_once()
    sched.tick_once(["a"])
    assert counts == {"a": 4, "b": 3}
    assert sched.current_tick() == 4
    sched.tick_for(0.05, ["b"])
    assert counts["a"] == 4 and counts["b"] > 3


def test_deterministic_mode_fixed_dt_and_repeatable_rng():
    def sim_tick(node):
        pass

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="sim_sensor", tick=sim_tick, rate=100, order=0))
    for _ in range(1000):
        sched.tick_once()
        assert horus.dt() == 0.01

    def sequence():
        values = []
        s = Scheduler(tick_rate=100, deterministic=True)
        s.add(Node(name="rng", tick=lambda n: values.append(horus.rng_float()), rate=100))
        for _ in range(20):
            s.tick_once()
        return values

    first, second = sequence(), sequence()
    assert first == second and len(set(first)) == 20
    assert all(0.0 <= v < 1.0 for v in first)


def test_introspection():
    sched = Scheduler(tick_rate=100, name="agv")
    for name, order in (("sensor", 0), ("motor", 5), ("planner", 50)):
        sched.add(Node(name=name, tick=lambda n: None, rate=100, order=order))
    assert sched.status() == "idle"
    assert sched.current_tick() == 0
    assert sched.is_running() is False
    assert sched.scheduler_name() == "agv"
    assert sched.get_node_count() == 3
    assert sched.get_node_names() == ["sensor", "motor", "planner"]
    assert sched.has_node("motor") and not sched.has_node("lidar")
    infos = sched.get_all_nodes()
    assert [(i["name"], i["order"], i["state"]) for i in infos] == [
        ("sensor", 0, "Uninitialized"), ("motor", 5, "Uninitialized"),
        ("planner", 50, "Uninitialized")]
    assert sched.get_node_info("motor") == 5
    assert sched.get_node_info("nope") is None
    assert isinstance(sched.has_full_rt(), bool)
    assert isinstance(sched.degradations(), list)
    assert set(sched.capabilities()) == {"rt_scheduling", "memory_locking", "cpu_isolation"}
    assert sched.set_node_rate("motor", 50.0) and not sched.set_node_rate("nope", 1.0)
    assert sched.set_tick_budget("motor", 500)  # Allow 500 us per tick
    assert sched.get_all_nodes()[1]["budget"] == pytest.approx(500e-6)
    assert not sched.set_tick_budget("nope", 500)
    assert sched.remove_node("planner") and sched.get_node_count() == 2


def test_lifecycle_callbacks_and_logging_only_inside_them(capfd):
    def setup_hardware(node):
        node.log_info("Connecting to motor controller...")
        node.send("status", {"state": "ready"})

    def control(node):
        if node.has_msg("cmd"):
            node.log_debug(f"Command: {node.recv('cmd')}")

    def cleanup(node):
        node.log_info("Stopping motor controller...")
        node.send("cmd", {"linear": 0.0, "angular": 0.0})

    status = horus.Topic(dict, "status")
    cmd = horus.Topic(dict, "cmd")
    motor = Node(name="motor", init=setup_hardware, tick=control, shutdown=cleanup, rate=1000,
                 order=5, budget=300 * us)
    motor.log_info("outside any callback: dropped")
    horus.run(motor, duration=0.05)
    horus._core.flush_log()
    err = capfd.readouterr().err
    assert "INFO motor: Connecting to motor controller..." in err
    assert "INFO motor: Stopping motor controller..." in err
    assert "dropped" not in err
    assert status.try_recv() == {"state": "ready"}
    assert cmd.try_recv() == {"linear": 0.0, "angular": 0.0}


def test_unit_testing_a_single_node():
    results = []

    def counter_tick(node):
        count = (node.recv("count") or 0) + 1
        node.send("count", count)
        results.append(count)

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="counter", tick=counter_tick, rate=100, order=0,
                   pubs=["count"], subs=["count"]))
    sched.tick_once()
    sched.tick_once()
    sched.tick_once()
    assert results == [1, 2, 3]


def test_sensor_to_motor_pipeline():
    motor_cmds = []

    def fake_sensor(node):
        node.send("scan", {"ranges": [0.5, 1.0, 1.5]})

    def controller(node):
        if node.has_msg("scan"):
            scan = node.recv("scan")
            node.send("cmd", {"speed": min(scan["ranges"])})

    def mock_motor(node):
        if node.has_msg("cmd"):
            motor_cmds.append(node.recv("cmd"))

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="sensor", tick=fake_sensor, rate=100, order=0, pubs=["scan"]))
    sched.add(Node(name="ctrl", tick=controller, rate=100, order=10, subs=["scan"],
                   pubs=["cmd"]))
    sched.add(Node(name="motor", tick=mock_motor, rate=100, order=20, subs=["cmd"]))
    sched.tick_for(0.1)
    assert len(motor_cmds) > 0
    assert motor_cmds[0]["speed"] == 0.5


def test_watchdog_detects_frozen_node():
    def frozen_tick(node):
        time.sleep(2.0)

    sched = Scheduler(tick_rate=10, watchdog_ms=100)
    sched.add(Node(name="frozen", tick=frozen_tick, rate=10, order=0))
    sched.tick_once()
    stats = sched.safety_stats()
    assert stats is not None
    assert stats["watchdog_expirations"] > 0


def test_reverse_order_shutdown():
    order = []
    sched = Scheduler(tick_rate=100)
    for name in ("sensor", "controller", "motor"):
        sched.add(Node(name=name, tick=lambda n: None, init=lambda n: order.append(f"init {n.name}"),
                       shutdown=lambda n: order.append(f"down {n.name}"), rate=100))
    sched.run(duration=0.05)
    assert order == ["init sensor", "init controller", "init motor",
                     "down motor", "down controller", "down sensor"]


def test_init_failure_excludes_only_that_node():
    # Seed 001's default: no failure_policy, yet the run goes on without the broken node.
    ticked = []

    def broken(node):
        raise OSError("no such device")

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="broken", init=broken, tick=lambda n: ticked.append("broken"), rate=100))
    sched.add(Node(name="ok", tick=lambda n: ticked.append("ok"), rate=100))
    sched.tick_once()
    sched.tick_once()
    assert ticked == ["ok", "ok"]
    info = {i["name"]: i for i in sched.get_all_nodes()}
    assert info["broken"]["state"] == "Error"
    assert info["broken"]["last_error"].startswith("init(): OSError: no such device")
    assert sched.stop_reason() == ""

    ticked.clear()
    running = Scheduler(tick_rate=100, deterministic=True)
    running.add(Node(name="broken", init=broken, tick=lambda n: ticked.append("broken"), rate=100))
    running.add(Node(name="ok", tick=lambda n: ticked.append("ok"), rate=100))
    assert running.run(duration=0.05) == 0
    assert ticked == ["ok"] * 5


def test_failure_policy_fatal_given_explicitly_still_stops_on_a_failed_init():
    ticked = []
    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="broken", init=lambda n: 1 / 0, tick=lambda n: None, rate=100,
                   failure_policy="fatal"))
    sched.add(Node(name="ok", tick=lambda n: ticked.append("ok"), rate=100))
    assert sched.run(duration=1.0) == 1
    assert ticked == []
    assert "node 'broken' failed in init()" in sched.stop_reason()


def test_a_failing_tick_without_a_policy_stops_the_scheduler():
    def flaky(node):
        raise ConnectionError("encoder lost")

    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="motor", tick=flaky, rate=100))
    assert sched.run(duration=1.0) == 1
    assert sched.get_node_stats("motor")["failed_ticks"] == 1
    assert sched.get_all_nodes()[0]["state"] == "Crashed"


def test_get_node_stats_as_written(capsys):
    sched = Scheduler(tick_rate=1000)
    sched.add(Node(name="motor", tick=lambda n: None, rate=1000, order=0, priority=80))
    sched.add(Node(name="logger", tick=lambda n: None, rate=10, order=100))
    sched.tick_once()
    sched.tick_once()

    stats = sched.get_node_stats("motor")
    print(f"Node: {stats['name']}")
    print(f"Priority: {stats['priority']}")
    print(f"Total ticks: {stats['total_ticks']}")
    print(f"Errors: {stats['errors_count']}")

    assert capsys.readouterr().out == "Node: motor\nPriority: 80\nTotal ticks: 2\nErrors: 0\n"
    assert sched.get_node_stats("logger")["priority"] is None
    assert sched.get_node_stats("nope") is None


def test_safety_stats_as_written(capsys):
    sched = Scheduler(tick_rate=1000, watchdog_ms=100)
    sched.add(Node(name="slow", tick=lambda n: time.sleep(0.12), rate=1000, order=0,
                   budget=100 * us))
    sched.add(Node(name="quick", tick=lambda n: None, order=10))  # no budget to overrun
    sched.tick_once()

    stats = sched.safety_stats()
    if stats:
        print(f"Budget overruns: {stats['budget_overruns']}")
        print(f"Watchdog expirations: {stats['watchdog_expirations']}")
        print(f"Node health states: {stats['health_states']}")

    out = capsys.readouterr().out
    assert "Budget overruns: 1\nWatchdog expirations: 1\nNode health states: {" in out
    assert stats["budget_overruns"] == 1 and stats["watchdog_expirations"] == 1
    assert set(stats["health_states"]) == {"slow", "quick"}
    # Past 1x its watchdog (2x on a loaded machine); never Isolated, which is for critical nodes.
    assert stats["health_states"]["slow"] in ("Warning", "Unhealthy")
    assert stats["health_states"]["quick"] == "Healthy"


def test_per_node_watchdog_overrides_the_global_one():
    motor_ctrl = lambda node: None  # noqa: E731
    motor = Node(
        name="motor",
        tick=motor_ctrl,
        rate=1000,
        order=0,
        watchdog=200 * ms,  # Stricter: 200 ms instead of global 500 ms
    )
    sched = Scheduler(tick_rate=1000, watchdog_ms=500).add(motor)
    sched.add(Node(name="lidar", tick=motor_ctrl, rate=1000, order=1))
    sched.tick_once()
    watchdogs = {i["name"]: i["watchdog"] for i in sched.get_all_nodes()}
    assert watchdogs == {"motor": pytest.approx(0.2), "lidar": pytest.approx(0.5)}


def _wait_for(condition, what: str, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, f"timed out waiting for {what}"
        time.sleep(0.005)


def test_runtime_mutation_on_a_running_scheduler():
    sensor_ticks, logger_ticks, shut_down = [], [], []
    read_lidar = lambda node: sensor_ticks.append(horus.tick())  # noqa: E731
    sched = Scheduler(tick_rate=1000)
    # Sensor normally runs at 100 Hz
    sched.add(Node(name="sensor", tick=read_lidar, rate=100, order=0))
    sched.add(Node(name="cloud_logger", tick=lambda n: logger_ticks.append(1), rate=100,
                   order=100, shutdown=lambda n: shut_down.append(n.name)))
    runner = threading.Thread(target=sched.run)  # running in a thread
    runner.start()
    try:
        _wait_for(lambda: logger_ticks and sensor_ticks, "the first ticks")

        # Slow down to conserve power
        assert sched.set_node_rate("sensor", 20)   # 100 Hz -> 20 Hz
        assert sched.get_all_nodes()[0]["rate"] == 20.0
        # Speed up for precision docking
        assert sched.set_node_rate("sensor", 500)  # 20 Hz -> 500 Hz
        assert sched.get_all_nodes()[0]["rate"] == 500.0

        removed = sched.remove_node("cloud_logger")  # Returns True if found
        assert removed is True
        _wait_for(lambda: shut_down, "the removed node's shutdown()")
        assert not sched.has_node("cloud_logger") and sched.get_node_names() == ["sensor"]
        ticks_after_removal = len(logger_ticks)
        seen = len(sensor_ticks)
        _wait_for(lambda: len(sensor_ticks) > seen + 5, "the sensor to tick on")
        assert len(logger_ticks) == ticks_after_removal
        assert sched.remove_node("cloud_logger") is False
    finally:
        sched.stop()
        runner.join(timeout=30)
    assert not runner.is_alive()
    assert shut_down == ["cloud_logger"]


def test_a_frozen_critical_node_puts_every_node_in_its_safe_state():
    entered, motor_ticks, lidar_ticks = [], [], []

    class Motor(Node):
        def tick(self):
            motor_ticks.append(horus.tick())
            if len(motor_ticks) == 1:
                time.sleep(0.35)  # frozen past 3x its 100 ms critical timeout

        def enter_safe_state(self):
            entered.append(self.name)

        def is_safe_state(self):
            return False  # stays isolated

    class Lidar(Node):
        def tick(self):
            lidar_ticks.append(horus.tick())

        def enter_safe_state(self):
            entered.append(self.name)

    sched = Scheduler(tick_rate=100)
    sched.add(Motor(name="motor_controller", rate=100, order=0))
    sched.add(Lidar(name="lidar", rate=100, order=10))
    sched.add_critical_node("motor_controller", timeout_ms=100)
    sched.tick_once()
    assert sorted(entered) == ["lidar", "motor_controller"]
    assert sched.safety_stats()["health_states"]["motor_controller"] == "Isolated"
    info = {i["name"]: i for i in sched.get_all_nodes()}
    assert info["motor_controller"]["critical"] and not info["lidar"]["critical"]
    assert info["motor_controller"]["watchdog"] == pytest.approx(0.1)

    sched.tick_once()
    assert motor_ticks == [0], "an isolated node is out of the tick loop"
    assert lidar_ticks == [0, 1]
