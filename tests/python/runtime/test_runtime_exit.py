"""How a Python program ends: nothing of it left in shared memory (at the end of its input, on
Ctrl+C or SIGTERM, with a scheduler still held at exit; by the same rules as a C++ program), a
failure instead of an idle run once no node is left, a way to declare the type of a typed topic
named without one, and its schedulers named after it."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest

import horus
from horus import Node, Scheduler
from horus.msg import CmdVel
from pyrt_test import Scalars

from .conftest import python_child

PEER = os.environ.get("HORUS_PY_PEER", "")

# Each runs until its standard input closes, Ctrl+C or SIGTERM, on a dict topic (a 1 MiB segment)
# and a POD one, and prints "ready" once it has sent; so does the C++ peer's "node" role.
TALKER = """
import sys, threading, horus
from horus.msg import CmdVel

ended = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), ended.set()), daemon=True).start()

def talk(node):
    node.send("chatter", {"n": horus.tick()})
    node.send("cmd_vel", CmdVel(linear=1.0))
    node.recv("chatter")
    if horus.tick() == 3:
        print("ready", flush=True)
    if ended.is_set():
        node.request_stop()

talker = horus.Node(name="talker", tick=talk, rate=100, pubs={"chatter": dict, "cmd_vel": CmdVel},
                    subs=["chatter"])
"""
PROGRAMS = {
    "horus.run": TALKER + "sys.exit(horus.run(talker, tick_rate=100))\n",
    "with horus.Scheduler()": TALKER + textwrap.dedent("""
        with horus.Scheduler(tick_rate=100) as sched:
            sched.add(talker)
            code = sched.run()
        sys.exit(code)
    """),
}


def _start(program: str) -> subprocess.Popen:
    command = ([PEER, "node", "dict", "chatter", "100"] if program == "C++"
               else [sys.executable, "-c", PROGRAMS[program]])
    return subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _assert_nothing_left(namespace: str, pid: int, program: str) -> None:
    folder = horus._core.namespace_directory(namespace)
    segments = sorted(os.listdir(folder)) if os.path.isdir(folder) else []
    assert segments == [], f"{program} left its topics: {segments}"
    entries = [p["entry"] for p in horus._core.list_presence(namespace) if p["pid"] == pid]
    assert entries == [], f"{program} left its presence entries: {entries}"
    # The log ring stays, for `horus log` to read the ended run's lines; nobody uses it.
    left = [(o["kind"], o["in_use"]) for o in horus._core.list_namespace_objects(namespace)]
    assert left == [("@logs", False)], left


@pytest.mark.parametrize("ending", ["end of input", "SIGINT", "SIGTERM"])
@pytest.mark.parametrize("program", ["horus.run", "with horus.Scheduler()", "C++"])
def test_a_program_that_ends_leaves_nothing_of_its_own_in_shared_memory(namespace, program,
                                                                         ending):
    assert PEER, "HORUS_PY_PEER names the C++ peer; run this suite through ctest (pytest_runtime)"
    child = _start(program)
    try:
        assert child.stdout.readline().strip() == "ready", child.stderr.read()
        if ending != "end of input":
            child.send_signal(getattr(signal, ending))
        out, err = child.communicate(timeout=60)  # closes its standard input
    finally:
        child.kill()
        child.wait()
    assert child.returncode == 0, err
    _assert_nothing_left(namespace, child.pid, program)


def test_a_scheduler_held_until_exit_shuts_its_nodes_down_and_leaves_nothing(namespace):
    # Not run, not dropped: the interpreter's exit ends it, before finalizing (when CPython ends
    # any thread that takes the GIL, so the node's shutdown() could not run).
    child = python_child(textwrap.dedent("""
        import horus

        def down(node):
            node.send("farewell", {"bye": True})
            print("down", node.name, flush=True)

        sched = horus.Scheduler(tick_rate=100)
        sched.add(horus.Node(name="talker", tick=lambda n: n.send("chatter", {"n": 1}),
                             shutdown=down, pubs=["chatter"]))
        sched.tick_once()
    """))
    out, err = child.communicate(timeout=60)
    assert child.returncode == 0, err
    assert out.split() == ["down", "talker"], err
    _assert_nothing_left(namespace, child.pid, "a scheduler held until exit")


def _run_script(tmp_path, name: str, code: str) -> subprocess.CompletedProcess:
    script = tmp_path / name
    script.write_text(textwrap.dedent(code))
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=60)


def test_a_run_whose_every_node_failed_init_stops_with_a_failure_naming_them(tmp_path):
    # Seed 001's default keeps the others running when a node's init() fails; with none left,
    # the run idled until Ctrl+C and then reported success.
    child = _run_script(tmp_path, "arm_driver.py", """
        import horus

        def connect(node):
            raise OSError("no arm on /dev/ttyUSB0")

        def calibrate(node):
            raise ValueError("no calibration file")

        nodes = [horus.Node(name="arm", init=connect, tick=lambda n: None, rate=100),
                 horus.Node(name="wrist", init=calibrate, tick=lambda n: None, rate=100)]
        raise SystemExit(horus.run(*nodes))
    """)
    assert child.returncode == 1, child.stderr
    stopping = [line for line in child.stderr.splitlines() if "stopping:" in line]
    assert len(stopping) == 1 and stopping[0].endswith(
        " ERROR @arm_driver: stopping: no node left to run: "
        "node 'arm' failed in init(): OSError: no arm on /dev/ttyUSB0; "
        "node 'wrist' failed in init(): ValueError: no calibration file"), child.stderr


@pytest.mark.parametrize("msg_type, module", [(CmdVel, "horus.msg"), (Scalars, "pyrt_test")])
@pytest.mark.parametrize("declared", ["subs", "pubs"])
def test_a_topic_named_without_its_type_says_how_to_declare_it(msg_type, module, declared):
    typed = horus.Topic(msg_type, "arm.state")  # a live user of the typed topic
    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="arm", tick=lambda n: None, **{declared: ["arm.state"]}))
    sched.tick_once()
    (arm,) = sched.get_all_nodes()
    assert arm["state"] == "Error"
    cls = msg_type.__name__
    assert arm["last_error"].startswith(
        f"init(): horus._core.HorusError: node 'arm': topic 'arm.state' carries {module}.{cls}, "
        f"not dict values: declare {declared}={{'arm.state': {cls}}} (from {module} import "
        f"{cls}) (topic 'arm.state'"), arm["last_error"]
    assert typed.send(msg_type())  # unharmed


@pytest.mark.parametrize("use, declared", [("recv", "subs"), ("has_msg", "subs"),
                                           ("send", "pubs")])
def test_a_topic_used_without_a_declaration_says_how_to_declare_its_type(use, declared):
    typed = horus.Topic(CmdVel, "cmd_vel")
    args = ("cmd_vel", {"linear": 1.0}) if use == "send" else ("cmd_vel",)
    sched = Scheduler(tick_rate=100, deterministic=True)
    sched.add(Node(name="drive", tick=lambda n: getattr(n, use)(*args), failure_policy="ignore"))
    sched.tick_once()
    (drive,) = sched.get_all_nodes()
    assert (f"declare {declared}={{'cmd_vel': CmdVel}} (from horus.msg import CmdVel)"
            in drive["last_error"]), drive["last_error"]
    assert typed.send(CmdVel())


def test_a_scheduler_is_named_after_its_program(tmp_path):
    package = tmp_path / "fleet"
    package.mkdir()
    code = """
        import horus
        print(horus.Scheduler().scheduler_name(), horus.Scheduler(name="mine").scheduler_name())
    """
    (package / "__init__.py").write_text("")
    (package / "__main__.py").write_text(textwrap.dedent(code))
    script = _run_script(tmp_path, "agv.py", code)
    assert script.returncode == 0, script.stderr
    assert script.stdout.split() == ["agv", "mine"]
    module = subprocess.run([sys.executable, "-m", "fleet"], capture_output=True, text=True,
                            cwd=tmp_path, timeout=60)
    assert module.returncode == 0, module.stderr
    assert module.stdout.split() == ["fleet", "mine"]
