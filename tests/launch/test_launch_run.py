"""`horus launch` running real processes (tools/horus/horus_cli/launch/runner.py): the start in
dependency order, restarts with backoff, `required`, the stop in reverse order with SIGKILL after
stop_timeout, the prefixed and logged output, control from another terminal, and no process or
segment left when the launcher itself is killed.

Every launch runs programs/run_worker.py, which says "ready NAME PID" and journals its start and
stop; each test has its own shared-memory root, namespace, control folder and log folder.
"""
from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest
from processes import Output, private_namespace, wait_until

HORUS = os.environ.get("HORUS_CLI", "")
WORKER = pathlib.Path(__file__).resolve().parent / "programs" / "run_worker.py"


@pytest.fixture(autouse=True)
def world(monkeypatch, tmp_path):
    """A namespace under a root of its own; the control sockets and default logs in tmp_path;
    the workers find horus.msg."""
    runtime = tmp_path / "runtime"
    runtime.mkdir(mode=0o700)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(runtime))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        filter(None, [os.environ.get("PYTHONPATH"), os.environ.get("HORUS_MSGS_PYTHON")])))
    monkeypatch.delenv("NO_COLOR", raising=False)
    yield from private_namespace(monkeypatch, tmp_path, "launch")


def worker(name: str, *options: str) -> dict:
    return {"command": sys.executable, "args": [str(WORKER), name, *options]}


def write_launch(tmp_path: pathlib.Path, processes: dict, name: str = "robot") -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text(json.dumps({"processes": processes}, indent=2))  # JSON is YAML
    return str(path)


class Launch:
    """`horus launch FILE` running, its stdout and stderr read as they come."""

    def __init__(self, path: str, *options: str) -> None:
        assert HORUS, "HORUS_CLI names bin/horus; run this suite through ctest"
        self.process = subprocess.Popen([HORUS, "launch", path, *options], text=True,
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.out, self.err = Output(self.process.stdout), Output(self.process.stderr)

    def ready(self, name: str, limit: float = 10.0) -> int:
        """The pid of process `name` once it said it is ready."""
        line = self.out.wait_for(f"| ready {name} ", limit)
        return int(line.split()[-1])

    def wait(self, limit: float = 15.0) -> int:
        try:
            status = self.process.wait(limit)
        except subprocess.TimeoutExpired:
            self.process.kill()
            raise AssertionError(f"the launch did not end; it said {self.err.text()}")
        self.out.wait_closed()
        self.err.wait_closed()
        return status

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()


@pytest.fixture
def launches():
    started: list[Launch] = []

    def start(path: str, *options: str) -> Launch:
        started.append(Launch(path, *options))
        return started[-1]
    yield start
    for launch in started:
        launch.kill()


def horus(*args: str, timeout: float = 20) -> subprocess.CompletedProcess:
    return subprocess.run([HORUS, *args], capture_output=True, text=True, timeout=timeout)


def running(pid: int) -> bool:
    """Whether a process runs (a zombie waiting for its reaper does not)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rpartition(b")")[2].split()[0] not in (b"Z", b"X")
    except OSError:
        return False


def journal_of(path: pathlib.Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def test_processes_start_in_dependency_order_and_stop_in_reverse_on_ctrl_c(tmp_path, launches):
    journal = tmp_path / "journal"
    log_dir = tmp_path / "logs"
    path = write_launch(tmp_path, {
        # File order is not start order: the topic's publisher first, then what waits for it.
        "planner": {**worker("planner", "--journal", str(journal)),
                    "depends_on": [{"topic": "cmd", "timeout": 10}, {"process": "driver"}]},
        "driver": {**worker("driver", "--journal", str(journal)),
                   "depends_on": [{"process": "publisher"}]},
        "publisher": worker("publisher", "--journal", str(journal), "--topic", "cmd"),
    })
    launch = launches(path, "--log-dir", str(log_dir))
    pids = {name: launch.ready(name) for name in ("publisher", "driver", "planner")}
    assert journal_of(journal) == ["start publisher", "start driver", "start planner"]
    launch.process.send_signal(signal.SIGINT)
    assert launch.wait() == 130
    assert journal_of(journal)[3:] == ["stop planner", "stop driver", "stop publisher"]
    assert not any(running(pid) for pid in pids.values())
    # Each line prefixed with its process (no colour into a pipe); stderr kept apart.
    assert "driver    | ready driver " + str(pids["driver"]) in launch.out.lines
    assert "planner   | planner says hello on stderr" in launch.err.lines
    assert not any("says hello" in line for line in launch.out.lines)
    assert "\x1b[" not in launch.out.text()
    assert (log_dir / "driver.stdout.log").read_text() == f"ready driver {pids['driver']}\n"
    assert (log_dir / "driver.stderr.log").read_text() == "driver says hello on stderr\n"
    events = (log_dir / "launch.log").read_text()
    assert "planner stopped (exit 0)" in events and "SIGINT received" in events


def test_a_dependency_that_never_comes_fails_the_launch_and_stops_what_started(tmp_path,
                                                                                 launches):
    path = write_launch(tmp_path, {
        "sensor": worker("sensor"),
        "planner": {**worker("planner"),
                    "depends_on": [{"process": "sensor"}, {"topic": "map", "timeout": 0.5}]},
    })
    launch = launches(path)
    sensor = launch.ready("sensor")
    assert launch.wait() == 1
    reason = launch.err.wait_for("stopping:")
    assert "planner (robot.yaml:" in reason and "depends_on topic 'map' not in namespace" in reason
    assert "after 0.5 s" in reason
    assert not running(sensor) and not any("ready planner" in l for l in launch.out.lines)
    # No --log-dir and none in the file: a folder of its own under $XDG_STATE_HOME.
    [log_dir] = (tmp_path / "state" / "horus" / "launch" / "robot").iterdir()
    assert (log_dir / "sensor.stdout.log").read_text() == f"ready sensor {sensor}\n"
    assert "ended (planner (robot.yaml:" in (log_dir / "launch.log").read_text()


def test_a_crashing_process_is_restarted_with_backoff_then_given_up_on(tmp_path, launches):
    journal = tmp_path / "journal"
    path = write_launch(tmp_path, {
        "steady": worker("steady"),
        "crasher": {**worker("crasher", "--journal", str(journal), "--exit", "3"),
                    "restart": "on-failure",
                    "backoff": {"initial": 0.1, "max": 0.25, "limit": 3}},
    })
    launch = launches(path)
    steady = launch.ready("steady")
    launch.err.wait_for("crasher ended (exit 3); given up after 3 restarts")
    assert journal_of(journal) == ["start crasher", "end crasher"] * 4
    delays = [line.rsplit(" in ", 1)[1] for line in launch.err.lines if "restart " in line
              and " of 3 in " in line]
    assert delays == ["0.1 s", "0.2 s", "0.25 s"]
    # Not required: the launch goes on.
    assert running(steady) and launch.process.poll() is None
    status = json.loads(horus("launch", "status", "--json").stdout)[0]
    crasher = next(p for p in status["processes"] if p["name"] == "crasher")
    assert (crasher["state"], crasher["restarts"], crasher["last_end"]) == ("failed", 3, "exit 3")
    assert horus("launch", "stop").returncode == 0
    assert launch.wait() == 0


def test_a_required_process_ending_stops_the_rest(tmp_path, launches):
    journal = tmp_path / "journal"
    path = write_launch(tmp_path, {
        "base": worker("base", "--journal", str(journal)),
        "arm": {**worker("arm", "--journal", str(journal)), "depends_on": ["base"]},
        "mission": {**worker("mission", "--journal", str(journal), "--exit", "2", "--after",
                             "0.3"), "required": True, "depends_on": ["arm"]},
    })
    launch = launches(path)
    assert launch.wait() == 1
    assert "required process mission ended (exit 2)" in launch.err.text()
    assert journal_of(journal) == ["start base", "start arm", "start mission", "end mission",
                                   "stop arm", "stop base"]


def test_a_python_program_imports_the_horus_package_the_launcher_runs(tmp_path, monkeypatch,
                                                                     launches):
    # As from an installed prefix of the user's own: nothing on PYTHONPATH names the package,
    # which the `horus` command finds from where it is installed.
    monkeypatch.delenv("PYTHONPATH")
    program = tmp_path / "node.py"
    program.write_text("import horus\nprint('imported', horus.FrameTree.__name__, flush=True)\n")
    launch = launches(write_launch(tmp_path, {"node": {"command": str(program)}}))
    assert launch.wait() == 0, launch.err.text()
    assert "node | imported FrameTree" in launch.out.text()


def test_a_process_ignoring_sigint_is_killed_after_its_stop_timeout(tmp_path, launches):
    path = write_launch(tmp_path, {
        "stubborn": {**worker("stubborn", "--ignore-sigint", "--topic", "odom"),
                     "stop_timeout": 0.5},
    })
    launch = launches(path)
    pid = launch.ready("stubborn")
    wait_until(lambda: (tmp_path / "shm" / os.environ["HORUS_NAMESPACE"] / "odom").exists(),
               "the odom segment")
    started = time.monotonic()
    launch.process.send_signal(signal.SIGTERM)
    assert launch.wait() == 143
    assert 0.5 <= time.monotonic() - started < 5
    assert "stubborn still running 0.5 s after SIGINT: SIGKILL" in launch.err.text()
    assert not running(pid)
    # Killed, it cleaned nothing up: the launcher did, as `horus shm clean` does.
    assert not (tmp_path / "shm" / os.environ["HORUS_NAMESPACE"] / "odom").exists()


def test_status_stop_and_restart_from_another_terminal(tmp_path, launches):
    path = write_launch(tmp_path, {"camera": worker("camera"), "lidar": worker("lidar")},
                        name="rover")
    launch = launches(path)
    camera, lidar = launch.ready("camera"), launch.ready("lidar")

    status = json.loads(horus("launch", "status", "--json").stdout)
    assert [s["name"] for s in status] == ["rover"] and status[0]["pid"] == launch.process.pid
    rows = {p["name"]: p for p in status[0]["processes"]}
    assert (rows["camera"]["pid"], rows["camera"]["state"], rows["camera"]["restarts"]) == \
        (camera, "running", 0)
    assert rows["lidar"]["uptime_s"] >= 0
    text = horus("launch", "status", "rover").stdout
    assert "PROCESS" in text and f"lidar    {lidar}" in text

    restarted = horus("launch", "restart", "lidar")
    assert restarted.returncode == 0, restarted.stderr
    new_lidar = int(restarted.stdout.split("pid ")[1].rstrip(")\n"))
    assert new_lidar != lidar and not running(lidar) and running(new_lidar)

    assert horus("launch", "stop", "camera").returncode == 0
    rows = {p["name"]: p for p in json.loads(
        horus("launch", "status", "--json").stdout)[0]["processes"]}
    assert rows["camera"]["state"] == "stopped" and not running(camera)
    assert (rows["lidar"]["state"], rows["lidar"]["restarts"]) == ("running", 1)

    wrong = horus("launch", "restart", "lidra")
    assert wrong.returncode == 1 and "did you mean 'lidar'" in wrong.stderr

    stopped = horus("launch", "stop", "rover")
    assert stopped.returncode == 0 and "stopped launch rover" in stopped.stdout
    assert launch.wait() == 0 and not running(new_lidar)
    assert horus("launch", "status").stdout.strip() == "no launch of yours runs"
    gone = horus("launch", "stop")
    assert gone.returncode == 1 and "no launch of yours runs" in gone.stderr


def test_the_control_folder_is_refused_when_other_users_could_reach_it(tmp_path, launches):
    folder = tmp_path / "runtime" / "horus-launch"
    folder.mkdir(mode=0o700)
    folder.chmod(0o755)
    refused = horus("launch", "status")
    assert refused.returncode == 1
    assert f"the launch control folder {folder} has mode 0755" in refused.stderr
    assert f"chmod 700 {folder}" in refused.stderr


def test_killing_the_launcher_leaves_no_process_and_no_segment(tmp_path, launches):
    journal = tmp_path / "journal"
    path = write_launch(tmp_path, {
        "talker": {**worker("talker", "--topic", "chatter", "--grandchild", "--journal",
                            str(journal)), "stop_timeout": 2},
        "stubborn": {**worker("stubborn", "--ignore-sigint", "--topic", "odom"),
                     "stop_timeout": 0.5, "depends_on": ["talker"]},
    })
    launch = launches(path)
    talker, stubborn = launch.ready("talker"), launch.ready("stubborn")
    grandchild = int(launch.out.wait_for("| grandchild ").split()[-1])
    segments = tmp_path / "shm" / os.environ["HORUS_NAMESPACE"]
    wait_until(lambda: {"chatter", "odom"} <= set(os.listdir(segments)), "both segments")

    launch.process.kill()
    launch.process.wait()
    wait_until(lambda: not any(running(pid) for pid in (talker, stubborn, grandchild)),
               "every process of the killed launcher to end", limit=10)
    wait_until(lambda: not os.path.isdir(segments) or not os.listdir(segments),
               f"no segment left in {segments}", limit=10)
    # The guardian stopped them as the launcher would: the talker on SIGINT, after the stubborn
    # one (started later) was killed.
    assert journal_of(journal) == ["start talker", "stop talker"]
    log = next((tmp_path / "state" / "horus" / "launch" / "robot").iterdir()) / "launch.log"
    assert "guardian: process group " + str(stubborn) + " still there after 0.5 s" in \
        log.read_text()


def test_a_daemon_that_left_its_process_group_is_stopped_with_the_launch(tmp_path, launches):
    path = write_launch(tmp_path, {"spawner": worker("spawner", "--daemon")})
    launch = launches(path)
    launch.ready("spawner")
    daemon = int(launch.out.wait_for("| daemon ").split()[-1])
    launch.process.send_signal(signal.SIGINT)
    assert launch.wait() == 130
    assert not running(daemon)
    assert "stopping 1 orphan(s) of the processes" in launch.err.text()


def test_prefixes_are_coloured_on_a_terminal_only(tmp_path):
    import pty
    path = write_launch(tmp_path, {"camera": worker("camera", "--exit", "0")})
    leader, follower = pty.openpty()
    process = subprocess.Popen([HORUS, "launch", path], stdout=follower,
                               stderr=subprocess.DEVNULL)
    os.close(follower)
    assert process.wait(15) == 0
    seen = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # EIO: every writer closed the terminal
            break
        if not chunk:
            break
        seen += chunk
    os.close(leader)
    assert b"\x1b[36mcamera |\x1b[0m ready camera " in seen


def test_a_second_ctrl_c_kills_at_once(tmp_path, launches):
    path = write_launch(tmp_path, {
        "stubborn": {**worker("stubborn", "--ignore-sigint"), "stop_timeout": 30}})
    launch = launches(path)
    pid = launch.ready("stubborn")
    launch.process.send_signal(signal.SIGINT)
    launch.err.wait_for("stopping: SIGINT received")
    started = time.monotonic()
    launch.process.send_signal(signal.SIGINT)
    assert launch.wait() == 130 and time.monotonic() - started < 5
    assert "stopping now: SIGKILL to every process" in launch.err.text()
    assert not running(pid)
