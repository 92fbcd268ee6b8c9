"""Seed 001's production patterns: the warehouse AGV and the drone flight controller.

`test_*_runs_its_course` run each example exactly as the seed writes it, in a process of its own
(with the seed's real-time settings: rt=True, its deadlines and on_miss policies), for
RUN_SECONDS, then end it as the seed does, with Ctrl+C; the example must still be running then,
with nothing stopped. The only changes are what cannot exist here: core=2 is core=1 on a 2-CPU
machine, and the hardware functions the seed leaves undefined are defined (PLACEHOLDERS). They
are marked `quiet_machine`: the seed's 100-200 us deadlines, counted from each tick's release,
with on_miss="stop" are the thing under test, and a machine whose thread wake-ups come that late
(a shared 2-core VM such as CI's, where C++ nodes miss them too) stops them as the seed says it
must. Their own ctest, `pytest_runtime_seed001_as_written` (label `quiet-machine`, RUN_SERIAL),
runs them; `scripts/test` leaves that label out. The other tests check the data flow in
deterministic mode, in `pytest_runtime`.
"""
from __future__ import annotations

import json
import select
import signal
import subprocess
import sys
import time

import pytest

import horus
from horus import Node, Scheduler, us

RUN_SECONDS = 3.0

# The functions the examples call but the seed leaves undefined: each returns a plausible value
# and counts its calls; the first call (from the first tick) says the example is running.
PLACEHOLDERS = '''
import atexit, collections, json, sys
_calls = collections.Counter()
atexit.register(lambda: print(json.dumps(_calls), flush=True))

def _called(name):
    if not _calls:
        print("running", flush=True)
    _calls[name] += 1

def compute_path(scan):
    _called("compute_path")
    return [[0.0, 0.0], [1.0, min(scan["ranges"])]]

def pure_pursuit(path, lookahead):
    _called("pure_pursuit")
    return {"left": path[1][0] - lookahead * path[1][1], "right": path[1][0]}

def apply_wheel_velocities(left, right):
    _called("apply_wheel_velocities")

def read_battery_voltage():
    _called("read_battery_voltage")
    return 24.0

def read_imu_hardware():
    _called("read_imu_hardware")
    return {"gyro": [0.0, 0.0, 0.1]}

def complementary_filter(raw):
    return {"roll": 0.0, "pitch": 0.0, "yaw": raw["gyro"][2]}

def pid_control(imu, sp, delta):
    return [sp["thrust"] + imu["yaw"] * delta] * 4

def position_pid(gps, waypoint, delta):
    return {"thrust": 0.5 + (waypoint[2] - gps["alt"]) * 0.1}

def current_waypoint():
    return [0.0, 0.0, 10.0]

def write_esc(cmd):
    _called("write_esc")
'''

# Seed 001, "Warehouse AGV", as written (core=2 -> core=1).
WAREHOUSE_AGV = '''
import horus
from horus import Node, Scheduler, us, ms

# --- Node callbacks ---

def safety_check(node):
    """Order 0: runs before everything else, every cycle."""
    if node.has_msg("scan"):
        scan = node.recv("scan")
        min_range = min(scan["ranges"])
        if min_range < 0.3:  # 30 cm emergency threshold
            node.send("emergency.stop", {"reason": "obstacle", "distance": min_range})
            node.log_warning(f"Emergency stop: obstacle at {min_range:.2f}m")

def read_lidar(node):
    """Order 10: read LiDAR at 40 Hz."""
    # Hardware read
    node.send("scan", {"ranges": [1.2, 0.8, 2.5, 1.1], "angle_min": -1.57})

def plan_path(node):
    """Order 50: heavy computation on thread pool."""
    if node.has_msg("scan"):
        scan = node.recv("scan")
        # A* or RRT on occupancy grid (40+ ms of computation)
        path = compute_path(scan)
        node.send("path", path)

def track_path(node):
    """Order 60: pure pursuit controller at 100 Hz."""
    if node.has_msg("path"):
        path = node.recv("path")
        cmd = pure_pursuit(path, lookahead=0.5)
        node.send("cmd_vel", cmd)

def motor_drive(node):
    """Order 70: motor controller at 1 kHz with tight budget."""
    if node.has_msg("cmd_vel"):
        cmd = node.recv("cmd_vel")
        # Write to motor hardware
        apply_wheel_velocities(cmd["left"], cmd["right"])

def battery_check(node):
    """Order 100: slow background monitoring."""
    voltage = read_battery_voltage()
    if voltage < 22.0:
        node.log_warning(f"Low battery: {voltage:.1f}V")
    node.send("battery", {"voltage": voltage})

def fleet_report(node):
    """Order 200: async HTTP upload to fleet management."""
    if node.has_msg("battery"):
        data = node.recv("battery")
        # aiohttp call to fleet server
        node.send("fleet.telemetry", data)

# --- Build and run ---

safety   = Node(name="safety",  tick=safety_check, rate=1000, order=0,
                budget=100*us, deadline=200*us, on_miss="stop",
                subs=["scan"], pubs=["emergency.stop"])

lidar    = Node(name="lidar",   tick=read_lidar, rate=40, order=10,
                pubs=["scan"])

planner  = Node(name="planner", tick=plan_path, rate=10, order=50,
                compute=True, subs=["scan"], pubs=["path"])

tracker  = Node(name="tracker", tick=track_path, rate=100, order=60,
                subs=["path"], pubs=["cmd_vel"])

motor    = Node(name="motor",   tick=motor_drive, rate=1000, order=70,
                budget=300*us, deadline=900*us, on_miss="safe_mode",
                core=1, subs=["cmd_vel"])

battery  = Node(name="battery", tick=battery_check, rate=1, order=100)

fleet    = Node(name="fleet",   tick=fleet_report, rate=1, order=200,
                failure_policy="skip", subs=["battery"], pubs=["fleet.telemetry"])

with Scheduler(tick_rate=1000, rt=True, watchdog_ms=500,
               blackbox_mb=16, max_deadline_misses=50) as sched:
    sched.add(safety).add(lidar).add(planner).add(tracker)
    sched.add(motor).add(battery).add(fleet)
    sched.add_critical_node("motor", timeout_ms=200)
    sched.add_critical_node("safety", timeout_ms=100)
    sched.run()
'''

# Seed 001, "Drone Flight Controller", as written.
DRONE = '''
import horus
from horus import Node, us, ms

def imu_read(node):
    """Read IMU at 400 Hz."""
    raw = read_imu_hardware()
    fused = complementary_filter(raw)
    node.send("imu", fused)

def attitude_control(node):
    """Inner loop: attitude PID at 400 Hz."""
    if node.has_msg("imu") and node.has_msg("setpoint"):
        imu = node.recv("imu")
        sp = node.recv("setpoint")
        delta = horus.dt()
        motors = pid_control(imu, sp, delta)
        node.send("motor_cmd", motors)

def position_control(node):
    """Outer loop: position PID at 50 Hz."""
    if node.has_msg("gps"):
        gps = node.recv("gps")
        waypoint = node.recv("waypoint") if node.has_msg("waypoint") else current_waypoint()
        setpoint = position_pid(gps, waypoint, horus.dt())
        node.send("setpoint", setpoint)

def motor_output(node):
    """ESC output at 400 Hz with hard deadline."""
    if node.has_msg("motor_cmd"):
        cmd = node.recv("motor_cmd")
        write_esc(cmd)

def telemetry_log(node):
    """Log to SD card at 10 Hz."""
    if node.has_msg("imu"):
        node.send("log", {
            "t": horus.now(),
            "tick": horus.tick(),
            "imu": node.recv("imu"),
        })

imu    = Node(name="imu",      tick=imu_read,         rate=400, order=0, core=0)
att    = Node(name="attitude",  tick=attitude_control,  rate=400, order=10,
              budget=200*us, deadline=500*us, on_miss="safe_mode", core=1,
              subs=["imu", "setpoint"], pubs=["motor_cmd"])
pos    = Node(name="position",  tick=position_control,  rate=50,  order=20,
              subs=["gps", "waypoint"], pubs=["setpoint"])
esc    = Node(name="esc",       tick=motor_output,      rate=400, order=30,
              budget=100*us, deadline=200*us, on_miss="stop", core=1,
              subs=["motor_cmd"])
logger = Node(name="logger",    tick=telemetry_log,     rate=10,  order=100,
              subs=["imu"], pubs=["log"])

horus.run(imu, att, pos, esc, logger,
          tick_rate=400, rt=True, watchdog_ms=100,
          blackbox_mb=8, max_deadline_misses=10, cores=[0, 1])
'''


def run_as_written(tmp_path, name: str, example: str) -> dict:
    """Runs `example` (after PLACEHOLDERS) as the program `name`.py until RUN_SECONDS after its
    first tick, then presses Ctrl+C; returns the placeholders' call counts. Fails if the example
    ended (a stop) before that, or said it stopped."""
    script = tmp_path / f"{name}.py"
    script.write_text(PLACEHOLDERS + example)
    child = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([child.stdout], [], [], 60.0)
        assert ready and child.stdout.readline() == "running\n", child.communicate()
        time.sleep(RUN_SECONDS)
        still_running = child.poll() is None
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert still_running, f"{name} stopped before {RUN_SECONDS} s:\n{err}"
    assert child.returncode == 0, err
    assert "stopping:" not in err, err
    return json.loads(out.splitlines()[-1])


@pytest.mark.quiet_machine
def test_warehouse_agv_runs_its_course(tmp_path):
    calls = run_as_written(tmp_path, "agv", WAREHOUSE_AGV)
    # lidar -> planner -> tracker -> motor: the wheels were driven.
    assert calls["apply_wheel_velocities"] > 0 and calls["read_battery_voltage"] > 0, calls


@pytest.mark.quiet_machine
def test_drone_flight_controller_runs_its_course(tmp_path):
    calls = run_as_written(tmp_path, "drone", DRONE)
    # Nothing in the example publishes gps: no setpoint, so no motor command reaches the ESC.
    assert calls["read_imu_hardware"] > 0 and "write_esc" not in calls, calls


def warehouse_agv(wheels: list):
    def compute_path(scan):
        return [[0.0, 0.0], [1.0, min(scan["ranges"])]]

    def pure_pursuit(path, lookahead):
        return {"left": path[1][0] - lookahead * path[1][1], "right": path[1][0]}

    def apply_wheel_velocities(left, right):
        wheels.append((left, right))

    def read_battery_voltage():
        return 21.5

    def safety_check(node):
        """Order 0: runs before everything else, every cycle."""
        if node.has_msg("scan"):
            scan = node.recv("scan")
            min_range = min(scan["ranges"])
            if min_range < 0.3:  # 30 cm emergency threshold
                node.send("emergency.stop", {"reason": "obstacle", "distance": min_range})
                node.log_warning(f"Emergency stop: obstacle at {min_range:.2f}m")

    def read_lidar(node):
        """Order 10: read LiDAR at 40 Hz."""
        node.send("scan", {"ranges": [1.2, 0.8, 2.5, 1.1], "angle_min": -1.57})

    def plan_path(node):
        """Order 50: heavy computation on thread pool."""
        if node.has_msg("scan"):
            scan = node.recv("scan")
            path = compute_path(scan)
            node.send("path", path)

    def track_path(node):
        """Order 60: pure pursuit controller at 100 Hz."""
        if node.has_msg("path"):
            path = node.recv("path")
            cmd = pure_pursuit(path, lookahead=0.5)
            node.send("cmd_vel", cmd)

    def motor_drive(node):
        """Order 70: motor controller at 1 kHz with tight budget."""
        if node.has_msg("cmd_vel"):
            cmd = node.recv("cmd_vel")
            apply_wheel_velocities(cmd["left"], cmd["right"])

    def battery_check(node):
        """Order 100: slow background monitoring."""
        voltage = read_battery_voltage()
        if voltage < 22.0:
            node.log_warning(f"Low battery: {voltage:.1f}V")
        node.send("battery", {"voltage": voltage})

    def fleet_report(node):
        """Order 200: async HTTP upload to fleet management."""
        if node.has_msg("battery"):
            data = node.recv("battery")
            node.send("fleet.telemetry", data)

    return [
        Node(name="safety", tick=safety_check, rate=1000, order=0,
             budget=100 * us, deadline=200 * us, on_miss="stop",
             subs=["scan"], pubs=["emergency.stop"]),
        Node(name="lidar", tick=read_lidar, rate=40, order=10, pubs=["scan"]),
        Node(name="planner", tick=plan_path, rate=10, order=50,
             compute=True, subs=["scan"], pubs=["path"]),
        Node(name="tracker", tick=track_path, rate=100, order=60,
             subs=["path"], pubs=["cmd_vel"]),
        Node(name="motor", tick=motor_drive, rate=1000, order=70,
             budget=300 * us, deadline=900 * us, on_miss="safe_mode",
             core=1, subs=["cmd_vel"]),
        Node(name="battery", tick=battery_check, rate=1, order=100),
        Node(name="fleet", tick=fleet_report, rate=1, order=200,
             failure_policy="skip", subs=["battery"], pubs=["fleet.telemetry"]),
    ]


def test_warehouse_agv_data_flow():
    wheels = []
    sched = Scheduler(tick_rate=1000, deterministic=True)
    for node in warehouse_agv(wheels):
        sched.add(node)
    for _ in range(300):
        sched.tick_once()
    assert wheels and wheels[0] == (1.0 - 0.5 * 0.8, 1.0)
    assert horus.Topic(dict, "fleet.telemetry").read_latest() == {"voltage": 21.5}


def drone(log: list):
    state = {"esc": []}

    def read_imu_hardware():
        return {"gyro": [0.0, 0.0, 0.1]}

    def complementary_filter(raw):
        return {"roll": 0.0, "pitch": 0.0, "yaw": raw["gyro"][2]}

    def pid_control(imu, sp, delta):
        return [sp["thrust"] + imu["yaw"] * delta] * 4

    def position_pid(gps, waypoint, delta):
        return {"thrust": 0.5 + (waypoint[2] - gps["alt"]) * 0.1}

    def current_waypoint():
        return [0.0, 0.0, 10.0]

    def write_esc(cmd):
        state["esc"].append(cmd)

    def imu_read(node):
        """Read IMU at 400 Hz."""
        raw = read_imu_hardware()
        fused = complementary_filter(raw)
        node.send("imu", fused)

    def attitude_control(node):
        """Inner loop: attitude PID at 400 Hz."""
        if node.has_msg("imu") and node.has_msg("setpoint"):
            imu = node.recv("imu")
            sp = node.recv("setpoint")
            delta = horus.dt()
            motors = pid_control(imu, sp, delta)
            node.send("motor_cmd", motors)

    def position_control(node):
        """Outer loop: position PID at 50 Hz."""
        if node.has_msg("gps"):
            gps = node.recv("gps")
            waypoint = node.recv("waypoint") if node.has_msg("waypoint") else current_waypoint()
            setpoint = position_pid(gps, waypoint, horus.dt())
            node.send("setpoint", setpoint)

    def motor_output(node):
        """ESC output at 400 Hz with hard deadline."""
        if node.has_msg("motor_cmd"):
            cmd = node.recv("motor_cmd")
            write_esc(cmd)

    def telemetry_log(node):
        """Log to SD card at 10 Hz."""
        if node.has_msg("imu"):
            entry = {"t": horus.now(), "tick": horus.tick(), "imu": node.recv("imu")}
            log.append(entry)
            node.send("log", entry)

    nodes = [
        Node(name="imu", tick=imu_read, rate=400, order=0, core=0),
        Node(name="attitude", tick=attitude_control, rate=400, order=10,
             budget=200 * us, deadline=500 * us, on_miss="safe_mode", core=1,
             subs=["imu", "setpoint"], pubs=["motor_cmd"]),
        Node(name="position", tick=position_control, rate=50, order=20,
             subs=["gps", "waypoint"], pubs=["setpoint"]),
        Node(name="esc", tick=motor_output, rate=400, order=30,
             budget=100 * us, deadline=200 * us, on_miss="stop", core=1,
             subs=["motor_cmd"]),
        Node(name="logger", tick=telemetry_log, rate=10, order=100,
             subs=["imu"], pubs=["log"]),
    ]
    return nodes, state


def test_drone_flight_controller_data_flow():
    log = []
    nodes, state = drone(log)
    gps = horus.Topic(dict, "gps")
    sched = Scheduler(tick_rate=400, deterministic=True)
    for node in nodes:
        sched.add(node)
    sched.tick_once()
    gps.send({"alt": 9.0})
    for _ in range(100):
        sched.tick_once()
    assert state["esc"] and state["esc"][0] == [0.6 + 0.1 / 400] * 4
    assert log and log[0]["tick"] == 0 and log[1]["tick"] == 1
    assert log[1]["t"] == 0.1  # SimClock: the logger's second tick at 10 Hz


def test_flight_recorder_dump(tmp_path):
    sched = Scheduler(tick_rate=1000, blackbox_mb=1)
    sched.add(Node(name="sensor", tick=lambda n: None, rate=1000))
    sched.run(duration=0.05)
    sched.dump_blackbox(tmp_path / "box")
    assert (tmp_path / "box").stat().st_size > 0
    with pytest.raises(horus.HorusError):
        Scheduler().dump_blackbox(tmp_path / "none")
