"""The demo robot as separate processes, and launches of real HORUS programs.

- examples/warehouse_agv with each node in a process of its own (`warehouse_agv --nodes NAME`),
  started by hand: the nodes still exchange the scan, the plan, the commands and the robot's
  position, and the person in front of the robot still stops it; the fleet node's GoToPallet
  goal reaches the planner in another process and succeeds, as do goals `horus action send`s;
- its launch file (examples/warehouse_agv/launch/warehouse.yaml), expanded by --dry-run and run
  by `horus launch` until the emergency stop, which holds for a motor controller restarted
  after it;
- a four-process launch (programs/fourproc.yaml): a C++ service server and publisher
  (programs/fourproc_peer.cpp), `horus record` and a Python subscriber
  (programs/fourproc_listener.py), started in dependency order until steady state.

Each test runs in a namespace of its own under a shared-memory root of its own.
"""
from __future__ import annotations

import json
import os
import pathlib
import re
import signal
import subprocess

import pytest
from processes import Output, private_namespace

HORUS = os.environ.get("HORUS_CLI", "")
WAREHOUSE_AGV = os.environ.get("WAREHOUSE_AGV", "")
FOURPROC_PEER = os.environ.get("FOURPROC_PEER", "")
ROOT = pathlib.Path(__file__).resolve().parents[2]
DEMO_LAUNCH = ROOT / "examples" / "warehouse_agv" / "launch" / "warehouse.yaml"
FOURPROC_LAUNCH = pathlib.Path(__file__).resolve().parent / "programs" / "fourproc.yaml"
NODES = ("motor", "lidar", "safety", "planner", "tracker", "battery", "fleet")
WHEELS_HALTED = "emergency stop: wheels halted"
GOAL_ACCEPTED = re.compile(r"fleet: GoToPallet pallet 7 at x=1\.20 m: goal [0-9a-f]{32} accepted$")
GOAL_SUCCEEDED = "fleet: GoToPallet succeeded: pallet 7 reached, robot at x=0."


@pytest.fixture(autouse=True)
def namespace(monkeypatch, tmp_path):
    """A namespace under a shared-memory root of its own; control sockets and logs in tmp_path."""
    assert HORUS and WAREHOUSE_AGV and FOURPROC_PEER, "run this suite through ctest"
    # pytest's folder is deep: the control socket is reached through the folder's descriptor, so
    # its path never meets a Unix socket address's 108 bytes.
    runtime = tmp_path / "runtime-folder-deep-enough-that-a-socket-path-in-it-passes-108-bytes"
    runtime.mkdir(mode=0o700)
    assert len(str(runtime / "horus-launch" / "warehouse.4194304.sock")) > 108
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(runtime))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setenv("HORUS_RECORDINGS", str(tmp_path / "recordings"))
    yield from private_namespace(monkeypatch, tmp_path, "launch_demo")


def topics_left() -> list[str]:
    """The topic segments left in the test's namespace."""
    folder = pathlib.Path(os.environ["HORUS_SHM_DIR"]) / os.environ["HORUS_NAMESPACE"]
    return sorted(path.name for path in folder.glob("*")) if folder.is_dir() else []


def stop(process: subprocess.Popen, limit: float = 15.0) -> int:
    process.send_signal(signal.SIGINT)
    return process.wait(limit)


def started_order(launcher_errors: Output) -> list[str]:
    """The processes in the order the launcher said it started them."""
    return [match.group(1) for line in launcher_errors.lines
            if (match := re.fullmatch(r"horus launch: (\S+) started \(pid \d+\)", line))]


# ---- the demo's nodes, each a process of its own, without the launcher ------------------------

def test_demo_nodes_in_processes_of_their_own_stop_the_robot(tmp_path):
    processes = {}
    outputs = {}
    try:
        for node in NODES:  # the motor controller first: the others simulate from its pose
            argv = [WAREHOUSE_AGV, "--nodes", node]
            if node == "lidar":
                argv += ["--person-at", "2"]
            processes[node] = subprocess.Popen(argv, text=True, stdout=subprocess.PIPE,
                                               stderr=subprocess.STDOUT)
            outputs[node] = Output(processes[node].stdout)
        # The scan reaches the safety monitor, its stop the motor controller: three processes.
        outputs["motor"].wait_for(WHEELS_HALTED, limit=20)
        outputs["safety"].wait_for("EMERGENCY STOP")
        # The robot had moved: the tracker's commands and the planner's path crossed processes.
        halted_at = float(re.search(WHEELS_HALTED + r" at x=([0-9.]+) m",
                                    outputs["motor"].text()).group(1))
        assert halted_at > 0.1, outputs["motor"].text()
    finally:
        statuses = {node: stop(processes[node]) for node in reversed(list(processes))}
    for output in outputs.values():
        output.wait_closed()
    assert statuses == {node: 0 for node in NODES}, {n: o.text() for n, o in outputs.items()}
    assert "robot stopped at x=" in outputs["motor"].text()
    for node in NODES:  # each process's own timing report, of its node alone
        report = re.findall(r"^(\w+) +(?:Rt|Compute|AsyncIo) ", outputs[node].text(), re.M)
        assert report == [node], outputs[node].text()


def test_demo_goal_to_the_pallet_across_processes_and_from_horus_action():
    # The nodes that move the robot, the planner (the action's server) and the fleet node (its
    # client) each in a process of its own; nobody steps in front of the robot.
    argvs = {"motor": [], "lidar": ["--person-at", "60"], "planner": [], "tracker": [],
             "fleet": []}
    processes = {}
    outputs = {}
    try:
        for node, extra in argvs.items():
            processes[node] = subprocess.Popen([WAREHOUSE_AGV, "--nodes", node, *extra],
                                               text=True, stdout=subprocess.PIPE,
                                               stderr=subprocess.STDOUT)
            outputs[node] = Output(processes[node].stdout)
        outputs["fleet"].wait_for(GOAL_SUCCEEDED, limit=20)
        assert any(GOAL_ACCEPTED.search(line) for line in outputs["fleet"].lines)
        assert "fleet: GoToPallet feedback: " in outputs["fleet"].text()
        assert "planner: pallet 7 reached at x=0." in outputs["planner"].text()
        # `horus action` finds the demo's action and sends it goals: one the robot, standing at
        # the pallet, has already reached, and one the planner refuses.
        listed = subprocess.run([HORUS, "action", "list"], capture_output=True, text=True,
                                timeout=30)
        assert re.search(r"^GoToPallet +warehouse_agv\.GoToPallet +\d+ +succeeded ",
                         listed.stdout, re.M), listed.stdout + listed.stderr
        sent = subprocess.run([HORUS, "action", "send", "GoToPallet", "{pallet_id: 7, x: 1.2}"],
                              capture_output=True, text=True, timeout=30)
        assert sent.returncode == 0, sent.stdout + sent.stderr
        assert "succeeded: {reached: true, pallet_id: 7, " in sent.stdout, sent.stdout
        refused = subprocess.run(
            [HORUS, "action", "send", "GoToPallet", "{pallet_id: 3, x: 1.0, y: 2.5}"],
            capture_output=True, text=True, timeout=30)
        assert refused.returncode == 1, refused.stdout + refused.stderr
        assert "rejected: pallet 3 is off the corridor (y=2.50 m" in refused.stderr
        # One 10 cm on, to 1 mm, which cannot end within 0.3 s: the command cancels it, the
        # planner ends it Canceled.
        canceled = subprocess.run(
            [HORUS, "action", "send", "GoToPallet", "{pallet_id: 7, x: 1.3, tolerance_m: 0.001}",
             "--result-timeout", "0.3"], capture_output=True, text=True, timeout=30)
        assert canceled.returncode == 1, canceled.stdout + canceled.stderr
        assert "did not end within 0.3 s: canceled" in canceled.stderr, canceled.stderr
        outputs["planner"].wait_for("planner: pallet 7: canceled by a client")
    finally:
        statuses = {node: stop(processes[node]) for node in reversed(list(processes))}
    for output in outputs.values():
        output.wait_closed()
    assert statuses == {node: 0 for node in argvs}, {n: o.text() for n, o in outputs.items()}


def test_demo_refuses_an_unknown_node():
    result = subprocess.run([WAREHOUSE_AGV, "--nodes", "lidar,motr"], capture_output=True,
                            text=True, timeout=10)
    assert result.returncode == 2
    assert "no node 'motr' (the nodes: safety, lidar, planner, tracker, motor, battery, fleet)" \
        in result.stderr


# ---- the demo's launch file ------------------------------------------------------------------

def test_demo_launch_file_expands_with_dependencies_first():
    result = subprocess.run([HORUS, "launch", str(DEMO_LAUNCH), f"agv:={WAREHOUSE_AGV}",
                             "--dry-run"], capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    order = re.findall(r"^\d+\. (\S+)", result.stdout, re.M)
    assert sorted(order) == sorted(NODES), result.stdout
    assert order.index("planner") > max(order.index("motor"), order.index("lidar"))
    assert order.index("tracker") > max(order.index("planner"), order.index("safety"))
    assert order.index("lidar") > order.index("motor")
    assert f"command:    {WAREHOUSE_AGV} --nodes lidar --person-at 5" in result.stdout
    assert result.stdout.count("namespace:  warehouse_agv_demo") == len(NODES)
    assert "depends on: topic robot.pose" in result.stdout
    assert "service GoToPallet.send_goal (timeout 10 s)" in result.stdout


class DemoLaunch:
    """`horus launch` of the demo's launch file in the test's namespace, its stdout and stderr
    read as they come."""

    def __init__(self, tmp_path: pathlib.Path, person_at: str) -> None:
        self.process = subprocess.Popen(
            [HORUS, "launch", str(DEMO_LAUNCH), f"agv:={WAREHOUSE_AGV}",
             f"namespace:={os.environ['HORUS_NAMESPACE']}", f"person_at:={person_at}",
             "--log-dir", str(tmp_path / "logs")],
            text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.out, self.err = Output(self.process.stdout), Output(self.process.stderr)

    def wait_for_the_emergency_stop(self) -> None:
        # Each process's lines come prefixed with its name (log lines are on stderr).
        assert self.err.wait_for(WHEELS_HALTED, limit=30).startswith("motor   | ")
        assert self.err.wait_for("EMERGENCY STOP").startswith("safety  | ")

    def stop(self) -> int:
        """Ctrl+C; the launcher's exit status once it and its processes ended."""
        status = stop(self.process, limit=30)
        self.out.wait_closed()
        self.err.wait_closed()
        return status


def test_demo_launch_runs_the_robot_until_the_emergency_stop(tmp_path):
    launch = DemoLaunch(tmp_path, person_at="2")
    try:
        launch.wait_for_the_emergency_stop()
        # The fleet node, started once the planner serves GoToPallet, sent it its goal.
        assert launch.err.wait_for("GoToPallet pallet 7 at x=1.20 m: goal").startswith("fleet   | ")
    finally:
        status = launch.stop()
    err = launch.err
    started = started_order(err)
    assert sorted(started) == sorted(NODES), err.text()
    assert started.index("planner") > max(started.index("motor"), started.index("lidar"))
    assert started.index("tracker") > max(started.index("planner"), started.index("safety"))
    stopped = re.findall(r"^horus launch: (\S+) stopped \(exit 0\)$", err.text(), re.M)
    assert stopped == list(reversed(started)), err.text()
    assert status == 130, err.text()  # stopped by SIGINT
    assert "motor   | robot stopped at x=" in launch.out.text()
    assert (tmp_path / "logs" / "motor.stderr.log").read_text().count(WHEELS_HALTED) == 1
    # Started in dependency order and stopped in reverse, each process removes the topics it
    # created as it ends: the launch leaves none behind.
    assert topics_left() == [], topics_left()


def test_demo_emergency_stop_holds_for_a_restarted_motor_controller(tmp_path):
    launch = DemoLaunch(tmp_path, person_at="1")
    try:
        launch.wait_for_the_emergency_stop()
        restart = subprocess.run([HORUS, "launch", "restart", "motor"], capture_output=True,
                                 text=True, timeout=30)
        assert restart.returncode == 0, restart.stderr
        # The new motor controller, at x=0 (its odometry starts again), halts as it starts.
        launch.err.wait_for(f"{WHEELS_HALTED} at x=0.00 m")
    finally:
        assert launch.stop() == 130, launch.err.text()
    assert "horus launch: motor started (pid " in launch.err.text()
    # The first stop at x > 0.1, the restarted controller's where it started.
    stopped_at = [float(x) for x in re.findall(r"^motor +\| robot stopped at x=([0-9.]+) m",
                                               launch.out.text(), re.M)]
    assert len(stopped_at) == 2 and stopped_at[0] > 0.1 and stopped_at[1] < 0.01, stopped_at
    # The first controller's topics, which its successor did not make and so does not remove,
    # are cleaned by the launcher once nobody uses them.
    assert topics_left() == [], topics_left()


# ---- four processes: a C++ publisher, a Python subscriber, a service, a recorder ---------------

def test_four_process_launch_starts_in_dependency_order_and_reaches_steady_state(tmp_path):
    recording = tmp_path / "four.mcap"
    python_path = os.pathsep.join(filter(None, [os.environ.get("PYTHONPATH"),
                                                os.environ.get("HORUS_MSGS_PYTHON")]))
    launcher = subprocess.Popen(
        [HORUS, "launch", str(FOURPROC_LAUNCH), f"peer:={FOURPROC_PEER}",
         f"python_path:={python_path}", f"recording:={recording}",
         "--log-dir", str(tmp_path / "logs")],
        text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = Output(launcher.stdout), Output(launcher.stderr)
    try:
        out.wait_for("listener | fourproc listener steady: 20 in order", limit=30)
        # Steady: the service answers from another process while the rest runs.
        call = subprocess.run([HORUS, "service", "call", "Compute", "{a: 2, b: 3}"],
                              capture_output=True, text=True, timeout=30)
        assert call.returncode == 0 and "sum: 5" in call.stdout, call.stdout + call.stderr
        [status] = json.loads(subprocess.run([HORUS, "launch", "status", "fourproc", "--json"],
                                             capture_output=True, text=True, timeout=30).stdout)
        assert {p["name"]: p["state"] for p in status["processes"]} == {
            name: "running" for name in ("adder", "talker", "recorder", "listener")}, status
    finally:
        exit_status = stop(launcher, limit=30)
    out.wait_closed()
    err.wait_closed()
    # The file lists the listener first: the launcher starts what it depends on before it.
    assert started_order(err) == ["adder", "talker", "recorder", "listener"], err.text()
    stamps = {role: int(ns) for role, ns in
              re.findall(r"\| fourproc (\w+) started at (\d+)$", out.text(), re.M)}
    assert stamps["adder"] < stamps["talker"] < stamps["listener"], out.text()
    stopped = re.findall(r"^horus launch: (\S+) stopped \(exit 0\)$", err.text(), re.M)
    assert stopped == ["listener", "recorder", "talker", "adder"], err.text()
    assert exit_status == 130, err.text()
    received = int(re.search(r"fourproc listener stopped: (\d+) received", out.text()).group(1))
    assert received >= 20
    info = subprocess.run([HORUS, "record", "info", "--json", str(recording)],
                          capture_output=True, text=True, timeout=30)
    assert info.returncode == 0, info.stderr
    topics = {topic["topic"]: topic for topic in json.loads(info.stdout)["topics"]}
    assert topics["fourproc.cmd"]["messages"] >= 20, topics
    assert topics_left() == [], topics_left()
