"""The `horus` command against live C++ and Python processes (bin/horus, as a user runs it)."""
from __future__ import annotations

import calendar
import contextlib
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import time

from conftest import HORUS, run_horus, wait_ready
from processes import stderr_after_kill, wait_until

PUBLISH_CMDVEL = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, {name!r})
topic.send(CmdVel(linear=1.0, angular=0.5))
print("ready", flush=True)
while True:
    time.sleep(0.01)
    topic.send(CmdVel(linear=1.0, angular=0.5))
"""

SUBSCRIBE_DICT = """
import time, horus
topic = horus.Topic(dict, {name!r})
topic.try_recv()
print("ready", flush=True)
while True:
    time.sleep(0.01)
    topic.try_recv()
"""

LOGGING_NODE = """
import horus
count = [0]
def tick(node):
    count[0] += 1
    if count[0] % 5 == 1:
        node.log_info(f"tick number {{count[0]}}")
    if count[0] == 1:
        print("ready", flush=True)
horus.run(horus.Node(name={name!r}, tick=tick, rate=50), tick_rate=50)
"""

SCHEDULER = """
import horus
ticks = [0]
def sense(node):
    node.send("scan", {{"range": 1.0}})
    ticks[0] += 1
    if ticks[0] == 3:
        print("ready", flush=True)
def plan(node):
    if node.has_msg("scan"):
        node.recv("scan")
horus.run(horus.Node(name={sensor!r}, tick=sense, rate=100, order=0, pubs=["scan"]),
          horus.Node(name="planner", tick=plan, rate=20, order=10, subs=["scan"]),
          tick_rate=100)
"""


def test_help_at_every_level_exits_zero():
    for args in ([], ["topic"], ["topic", "list"], ["topic", "info"], ["topic", "echo"],
                 ["topic", "pub"], ["service", "call"], ["process"], ["process", "list"],
                 ["service"], ["service", "list"], ["service", "info"], ["node"],
                 ["node", "list"], ["node", "info"], ["topic", "hz"], ["topic", "bw"],
                 ["monitor"], ["msg"], ["msg", "list"], ["msg", "show"], ["msg", "hash"], ["log"],
                 ["shm"], ["shm", "list"], ["shm", "clean"], ["completion"], ["blackbox"],
                 ["bridge"], ["record"], *(["record", action] for action in
                                            ("list", "info", "delete", "repair", "replay", "diff",
                                             "export"))):
        result = run_horus(*args, "--help")
        assert result.returncode == 0, (args, result.stderr)
        # `blackbox` hands --help to horus-blackbox, whose usage line names it.
        usage = "usage: horus-blackbox" if args == ["blackbox"] else \
            f"usage: horus {' '.join(args)}".rstrip()
        assert result.stdout.startswith(usage), (args, result.stdout)


def test_usage_errors_exit_two_with_one_line():
    for args in (["frobnicate"], ["topic", "info"], ["log", "--level", "loud"],
                 ["topic", "list", "--window", "soon"]):
        result = run_horus(*args)
        assert result.returncode == 2, (args, result)
        assert len(result.stderr.strip().splitlines()) == 1, (args, result.stderr)
        assert "Traceback" not in result.stderr


def test_windows_rates_timeouts_and_counts_must_be_above_zero():
    # Each would otherwise sleep a negative time, busy-loop, divide by zero or never end.
    for args in (["topic", "list", "-v", "--window", "-1"],
                 ["topic", "hz", "scan", "--window", "0"],
                 ["topic", "bw", "scan", "--window", "nan"],
                 ["topic", "echo", "scan", "--count", "0"],
                 ["topic", "echo", "scan", "--timeout", "-2"],
                 ["topic", "pub", "scan", "{}", "--count", "-1"],
                 ["topic", "pub", "scan", "{}", "--rate", "inf"],
                 ["service", "call", "Add", "{}", "--timeout", "0"],
                 ["log", "--since", "-5"],
                 ["monitor", "--interval", "0"],
                 ["bridge", "--export", "*", "--depth", "0"],
                 ["record", "-a", "--duration", "0"],
                 ["record", "replay", "x.mcap", "--rate", "-1"],
                 ["record", "replay", "x.mcap", "--capacity", "0"]):
        result = run_horus(*args)
        assert result.returncode == 2, (args, result)
        option = next(arg for arg in args if arg.startswith("--") and arg != "--export")
        assert result.stderr.count("\n") == 1 and f"argument {option}" in result.stderr \
            and "above 0" in result.stderr, (args, result.stderr)


def test_offsets_and_refresh_intervals_are_bounded():
    # A negative offset into a recording, an end before the start, or a refresh with no pause.
    for args, error in ((["record", "replay", "x.mcap", "--start", "-1"], "argument --start: needs a number of 0 or more"),
                        (["record", "replay", "x.mcap", "--end", "inf"], "argument --end: needs a number of 0 or more"),
                        (["record", "replay", "x.mcap", "--start", "2", "--end", "1"],
                         "--end 1 is before --start 2: nothing to replay"),
                        (["monitor", "--interval", "0.001"], "argument --interval: needs at least 0.1 seconds")):
        result = run_horus(*args)
        assert result.returncode == 2, (args, result)
        assert result.stderr.count("\n") == 1 and error in result.stderr, (args, result.stderr)


def test_an_unexpected_failure_is_one_internal_error_line(tmp_path):
    # A schema compiler whose package describes schemas as something other than a description
    # (a string): nothing the command expects.
    generator = tmp_path / "horus-gen"
    generator.write_text("#!/bin/sh\nexit 1\n")
    generator.chmod(0o755)
    (tmp_path / "horus_gen").mkdir()
    (tmp_path / "horus_gen" / "__init__.py").write_text(
        "class SchemaCompileError(Exception):\n    pass\n\n\n"
        "def describe_schema_text(name, text):\n    return 'not a description'\n\n\n"
        "def describe_files(paths, include_dirs=()):\n    return 'not a description'\n")
    environment = dict(os.environ, HORUS_GEN_PROGRAM=str(generator))
    result = subprocess.run([HORUS, "msg", "list"], capture_output=True, text=True, timeout=30,
                            env=environment)
    assert result.returncode == 1, result
    assert result.stderr.startswith("horus: internal error: TypeError: "), result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    debug = subprocess.run([HORUS, "msg", "list"], capture_output=True, text=True, timeout=30,
                           env=dict(environment, HORUS_DEBUG="1"))
    assert debug.returncode == 1 and "Traceback" in debug.stderr, debug


def test_no_subcommand_prints_help():
    result = run_horus()
    assert result.returncode == 0
    assert "topic" in result.stdout and "service" in result.stdout


def test_topic_list_shows_live_python_and_cpp_publishers(children, namespace):
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="py_cmd")))
    wait_ready(children.python(SUBSCRIBE_DICT.format(name="py_dict")))
    cpp = children.program(os.environ["HORUS_PY_PEER"], "pub", "cmdvel", "cpp_cmd", "1")
    assert cpp.wait(timeout=30) == 0

    plain = run_horus("topic", "list")
    assert plain.returncode == 0, plain.stderr
    assert plain.stdout.split() == ["cpp_cmd", "py_cmd", "py_dict"]

    listing = json.loads(run_horus("topic", "list", "--json").stdout)
    by_name = {t["name"]: t for t in listing}
    assert by_name["py_cmd"]["type_name"] == "horus.msg.CmdVel"
    assert by_name["py_cmd"]["publishers"] == 1
    assert by_name["py_dict"]["subscribers"] == 1
    # The C++ publisher exited: its message stays, its handle no longer counts.
    assert by_name["cpp_cmd"]["message_count"] == 1
    assert by_name["cpp_cmd"]["publishers"] == 0

    verbose = run_horus("topic", "list", "-v", "--namespace", namespace)
    lines = verbose.stdout.splitlines()
    assert lines[0].split() == ["TOPIC", "TYPE", "PUBS", "SUBS", "RATE_HZ", "MESSAGES"]
    py_row = next(line.split() for line in lines if line.startswith("py_cmd"))
    assert py_row[1:4] == ["horus.msg.CmdVel", "1", "0"]
    assert float(py_row[4]) > 0  # it publishes about every 10 ms


def test_namespace_option_overrides_the_environment(children, namespace):
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="here")))
    assert run_horus("topic", "list", "--namespace", "cli_nobody_uses_this").stdout == ""
    assert run_horus("--namespace", namespace, "topic", "list").stdout.split() == ["here"]


def test_topic_info_shows_type_schema_and_users(children):
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="cmd_vel")))
    result = run_horus("topic", "info", "cmd_vel")
    assert result.returncode == 0, result.stderr
    assert "type: horus.msg.CmdVel" in result.stdout
    assert "encoding: POD" in result.stdout
    assert "publishers: 1" in result.stdout
    assert "linear" in result.stdout  # the schema text
    info = json.loads(run_horus("topic", "info", "cmd_vel", "--json").stdout)
    assert info["is_pod"] and "angular" in info["schema"] and info["message_count"] >= 1


def test_unknown_topic_and_service_are_one_line_and_exit_one():
    for args, name in ((["topic", "info", "nope"], "'nope'"),
                       (["service", "info", "missing"], "'missing'")):
        result = run_horus(*args)
        assert result.returncode == 1, result
        assert result.stderr.count("\n") == 1 and name in result.stderr
        assert "Traceback" not in result.stderr


def test_every_command_gives_the_same_error_for_a_missing_topic(children, namespace):
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="cmd_vel")))
    expected = f"horus: no topic 'cmd_vle' in namespace '{namespace}'; did you mean 'cmd_vel'?"
    for args in (["topic", "info", "cmd_vle"], ["topic", "echo", "cmd_vle", "--once"],
                 ["topic", "hz", "cmd_vle", "--once"], ["topic", "bw", "cmd_vle", "--once"]):
        result = run_horus(*args)
        assert (result.returncode, result.stderr) == (1, expected + "\n"), args
    result = run_horus("topic", "pub", "cmd_vle", "{}", "--once")
    assert (result.returncode, result.stderr) == (
        1, expected + " (give --type TYPE to create it)\n")


def test_unknown_nodes_services_and_types_get_the_closest_names(children, namespace):
    wait_ready(children.python(SCHEDULER.format(sensor="lidar")))
    wait_ready(children.program(os.environ["HORUS_PY_SERVICE_PEER"], "serve"), "serving")
    for args, expected in (
            (["node", "info", "lidr"],
             f"no running node 'lidr' in namespace '{namespace}'; did you mean 'lidar'?"),
            (["service", "info", "Ad"],
             f"no service 'Ad' in namespace '{namespace}'; did you mean 'Add'?"),
            (["service", "call", "Ecco", "{}"],
             f"no service 'Ecco' in namespace '{namespace}'; did you mean 'Echo'?"),
            (["msg", "show", "CmdVle"], "no message type 'CmdVle' in the installed schemas; "
                                        "did you mean 'CmdVel'?"),
            (["msg", "hash", "horus.msg.Imuu"], "no message type 'horus.msg.Imuu' in the "
                                                "installed schemas; did you mean 'horus.msg.Imu'?")):
        result = run_horus(*args)
        assert result.returncode == 1 and result.stderr.count("\n") == 1, (args, result)
        assert result.stderr.startswith(f"horus: {expected}"), (args, result.stderr)
    # Nothing close: no guess.
    assert "did you mean" not in run_horus("node", "info", "zzzzzz").stderr


def test_topic_list_hides_the_topics_services_run_on_unless_asked(children):
    wait_ready(children.program(os.environ["HORUS_PY_SERVICE_PEER"], "serve"), "serving")
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="cmd_vel")))
    called = run_horus("service", "call", "Add", "{a: 1, b: 2}")  # its request and reply topics
    assert called.returncode == 0, called.stderr
    assert run_horus("topic", "list").stdout.split() == ["cmd_vel"]
    assert [t["name"] for t in json.loads(run_horus("topic", "list", "--json").stdout)] == \
        ["cmd_vel"]
    assert [line.split()[0] for line in run_horus("topic", "list", "-v").stdout.splitlines()] \
        == ["TOPIC", "cmd_vel"]
    everything = run_horus("topic", "list", "--include-hidden").stdout.split()
    assert {"cmd_vel", "Add.service", "Add.request", "Add.response.0", "Echo.service"} <= \
        set(everything), everything
    # They are still there for whoever names them.
    assert run_horus("topic", "info", "Add.service").returncode == 0
    assert run_horus("service", "list").stdout.split() == ["Add", "Echo"]


def test_service_list_and_info_against_a_live_cpp_server(children):
    server = children.program(os.environ["HORUS_PY_SERVICE_PEER"], "serve")
    wait_ready(server, "serving")
    listing = json.loads(run_horus("service", "list", "--json").stdout)
    names = [s["name"] for s in listing]
    assert names, "the server registered nothing"
    served = next(s for s in listing if s["servers"] == 1)
    assert served["server_pid"] == server.pid
    info = run_horus("service", "info", served["name"])
    assert info.returncode == 0, info.stderr
    assert f"server: pid {server.pid}" in info.stdout
    assert f"request: {served['request_type']}" in info.stdout
    described = json.loads(run_horus("service", "info", served["name"], "--json").stdout)
    assert described["name"] == served["name"] and described["server_pid"] == server.pid
    assert described["request_type"] == served["request_type"]
    assert described["response_type"] == served["response_type"]
    assert described["client_processes"] == []
    verbose = run_horus("service", "list", "-v")
    assert verbose.stdout.splitlines()[0].split()[:3] == ["SERVICE", "REQUEST", "RESPONSE"]


def test_log_filters_and_follows_a_nodes_log_info(children):
    node = children.python(LOGGING_NODE.format(name="chatty"))
    wait_ready(node)
    wait_until(lambda: "tick number" in run_horus("log", "--node", "chatty").stdout,
               "chatty's log line")
    lines = run_horus("log", "--node", "chatty", "--level", "info").stdout.splitlines()
    assert all(" INFO chatty: tick number " in line for line in lines), lines
    assert run_horus("log", "--node", "chatty", "--level", "warn").stdout == ""
    assert run_horus("log", "--node", "other").stdout == ""
    assert run_horus("log", "--node", "chatty", "--since", "3600").stdout.count("tick number") \
        >= len(lines)
    records = json.loads(run_horus("log", "--node", "chatty", "--json").stdout)
    assert records and all(r["source"] == "chatty" and r["pid"] == node.pid for r in records)

    follow = subprocess.Popen([HORUS, "log", "--follow", "--node", "chatty"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        newest = max(int(r["message"].split()[-1]) for r in records)
        # Lines logged after the command started reach it without running it again.
        for _ in range(200):
            line = follow.stdout.readline()
            assert line, follow.stderr.read()
            if int(line.split()[-1]) > newest:
                break
        else:
            raise AssertionError("--follow never showed a new line")
    finally:
        follow.kill()
        follow.communicate()


MISSING_DEADLINES = """
import time, horus
ticks = [0]
def slow(node):
    time.sleep(0.02)  # ten times its deadline
    ticks[0] += 1
    if ticks[0] == 1:
        print("ready", flush=True)
sched = horus.Scheduler(tick_rate=20, name="agv")
sched.add(horus.Node(name="slow", tick=slow, rate=20, deadline=0.002, on_miss="warn"))
sched.run()
"""


def test_log_shows_the_schedulers_own_deadline_warning(children):
    process = children.python(MISSING_DEADLINES)
    wait_ready(process)
    lines = wait_until(lambda: run_horus("log", "--level", "warn").stdout.splitlines(),
                       "the scheduler's deadline warning")
    # The scheduler logs as "@<its name>"; the first miss is logged, later ones at most every 10 s.
    assert len(lines) == 1, lines
    assert re.search(r" WARN @agv: node 'slow' missed its deadline \(2000 us\) by \d+ us "
                     r"\(Miss::Warn\); misses: 1 by this node, 1 in total$", lines[0]), lines
    assert run_horus("log", "--node", "@agv").stdout.splitlines() == lines
    assert run_horus("log", "--node", "slow", "--level", "warn").stdout == ""
    records = json.loads(run_horus("log", "--level", "warn", "--json").stdout)
    assert [(r["source"], r["level"], r["pid"]) for r in records] == \
        [("@agv", "WARN", process.pid)]


def test_node_info_shows_the_misses_against_the_schedulers_limit(children):
    process = children.python(MISSING_DEADLINES.replace('name="agv"',
                                                        'name="agv", max_deadline_misses=100000'))
    wait_ready(process)
    info = wait_until(lambda: [line for line in run_horus("node", "info", "slow").stdout.splitlines()
                               if line.startswith("scheduler misses: ")
                               and not line.startswith("scheduler misses: 0 ")],
                      "a miss in the announcement")
    assert re.fullmatch(r"scheduler misses: \d+ of max_deadline_misses 100000, where it stops",
                        info[0]), info
    node = json.loads(run_horus("node", "info", "slow", "--json").stdout)[0]
    assert node["deadline_ns"] == 2_000_000 and node["max_deadline_misses"] == 100000
    assert node["scheduler_deadline_misses"] >= node["deadline_misses"] >= 1


def test_shm_clean_removes_only_the_dead(children, namespace):
    alive = children.python(PUBLISH_CMDVEL.format(name="alive"))
    wait_ready(alive)
    dead = children.program(os.environ["HORUS_PY_PEER"], "pub", "cmdvel", "dead", "1")
    assert dead.wait(timeout=30) == 0
    listing = {s["name"]: s for s in json.loads(run_horus("shm", "list", "--json").stdout)}
    assert listing["alive"]["users"] == [{"pid": alive.pid, "program": "python3"}]
    assert listing["alive"]["in_use"]
    assert listing["dead"]["users"] == [] and not listing["dead"]["in_use"]
    assert listing["dead"]["size"] > 0
    table = {line.split()[0]: line.split() for line in run_horus("shm", "list").stdout.splitlines()}
    assert table["SEGMENT"][:3] == ["SEGMENT", "BYTES", "USERS"]
    assert table["alive"][2] == f"{alive.pid}(python3)" and table["dead"][2] == "-"

    result = run_horus("shm", "clean")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == \
        "removed 1 segment, 0 announcements and 0 tensor pools left by dead processes"
    assert run_horus("topic", "list").stdout.split() == ["alive"]
    assert json.loads(run_horus("shm", "clean", "--json").stdout) == \
        {"removed": 0, "announcements": 0, "pools": 0}


MAP_POOL = """
import time, horus
pool = horus.TensorPool.open({name!r}, block_size=1 << 20, block_count=2)
print("ready", flush=True)
while True:
    time.sleep(0.1)
"""


def test_shm_clean_removes_the_tensor_pools_no_live_process_maps(children, namespace):
    live = children.python(MAP_POOL.format(name="live"))
    wait_ready(live)
    killed = children.python(MAP_POOL.format(name="killed"))
    wait_ready(killed)
    killed.kill()
    killed.wait(timeout=30)
    cleaned = json.loads(run_horus("shm", "clean", "--json").stdout)
    assert cleaned["pools"] == 1, cleaned
    pools = pathlib.Path(os.environ["HORUS_SHM_DIR"]) / "@pool" / namespace
    assert sorted(path.name for path in pools.iterdir()) == ["live"]
    live.kill()
    live.wait(timeout=30)
    assert json.loads(run_horus("shm", "clean", "--json").stdout)["pools"] == 1
    assert not pools.exists()


FLIGHT_RECORDER = """
import horus
def fail(node):
    raise RuntimeError("encoder lost")
sched = horus.Scheduler(tick_rate=100, blackbox_mb=1, deterministic=True, name="agv")
sched.add(horus.Node(name="motor", tick=fail, failure_policy="ignore"))
sched.add(horus.Node(name="lidar", tick=lambda node: None))
for _ in range(3):
    sched.tick_once()
sched.dump_blackbox({path!r})
"""


def test_blackbox_is_folded_in(tmp_path):
    box = tmp_path / "agv.blackbox"
    subprocess.run([sys.executable, "-c", FLIGHT_RECORDER.format(path=str(box))], check=True,
                   timeout=60)
    result = run_horus("blackbox", str(box))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.split("\n\n")[0].splitlines()  # the events; the ticks follow
    assert lines[0] == f"{box}: 6 events (6 shown)", result.stdout
    assert lines[1].split()[:5] == ["time", "(UTC)", "tick", "event", "node"]
    # (tick, event, node) of each event: the scheduler's start, each node's init, the motor's
    # three failures.
    events = [tuple(line.split()[1:4]) for line in lines[2:] if line[:4].isdigit()]
    assert events == [("0", "SchedulerStart", "agv"), ("0", "NodeInit", "motor"),
                      ("0", "NodeInit", "lidar"), ("1", "NodeError", "motor"),
                      ("2", "NodeError", "motor"), ("3", "NodeError", "motor")], result.stdout
    lidar = run_horus("blackbox", str(box), "--node", "lidar")
    assert lidar.returncode == 0, lidar.stderr
    assert lidar.stdout.splitlines()[0] == f"{box}: 6 events (1 shown)"
    assert [line.split()[1:4] for line in lidar.stdout.split("\n\n")[0].splitlines()[2:]] == \
        [["0", "NodeInit", "lidar"]]
    missing = run_horus("blackbox", "no_such_file.blackbox")
    assert missing.returncode == 1 and "no_such_file.blackbox" in missing.stderr


def _complete(script: str, *words: str) -> list[str]:
    """What bash offers after `horus WORDS...` (the last word being the one typed so far), with
    bin/horus on the PATH as an installed command is."""
    line = " ".join(f"'{word}'" for word in ("horus", *words))
    program = f'{script}\nCOMP_WORDS=({line}); COMP_CWORD={len(words)}; _horus; ' \
              'printf "%s\\n" "${COMPREPLY[@]}"'
    environment = dict(os.environ, PATH=f"{os.path.dirname(HORUS)}:{os.environ['PATH']}")
    result = subprocess.run(["bash", "-c", program], capture_output=True, text=True,
                            env=environment, timeout=30)
    assert result.returncode == 0, result.stderr
    return sorted(result.stdout.split())


def test_completion_script_names_the_subcommands(children):
    result = run_horus("completion")
    assert result.returncode == 0
    assert "complete -F _horus horus" in result.stdout
    assert 'topic) words="list info hz bw echo pub"' in result.stdout
    assert 'node) words="list info"' in result.stdout
    checked = subprocess.run(["bash", "-n"], input=result.stdout, text=True, capture_output=True)
    assert checked.returncode == 0, checked.stderr
    assert _complete(result.stdout, "to") == ["topic"]
    assert _complete(result.stdout, "topic", "e") == ["echo"]
    # `record` takes an action or the topics to record: both are offered.
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="rear_lidar")))
    assert _complete(result.stdout, "record", "re") == ["rear_lidar", "repair", "replay"]
    assert _complete(result.stdout, "record", "d") == ["delete", "diff"]


def test_completion_offers_launch_actions_and_launch_files(tmp_path, monkeypatch):
    script = run_horus("completion").stdout
    folder = tmp_path / "launch_files"
    (folder / "config").mkdir(parents=True)
    (folder / "robot.yaml").write_text("processes: {}\n")
    (folder / "notes.txt").write_text("")
    monkeypatch.chdir(folder)
    assert _complete(script, "launch", "") == ["config", "restart", "robot.yaml", "status", "stop"]
    assert _complete(script, "launch", "r") == ["restart", "robot.yaml"]


def test_completion_offers_each_commands_options():
    script = run_horus("completion").stdout
    assert _complete(script, "bridge", "--fr") == ["--frames"]
    assert _complete(script, "bridge", "--frames", "--import-f") == ["--import-frames"]
    assert _complete(script, "topic", "echo", "scan", "--ti") == ["--timeout"]
    assert _complete(script, "frame", "tree", "--d") == ["--dot"]
    # horus-remote parses its own options: they are written out.
    assert _complete(script, "remote", "connect", "robot:7447", "--import-f") == ["--import-frames"]
    assert _complete(script, "remote", "serve", "--p") == ["--policy"]


def started_between(started_wall_ns: int, before: float, after: float) -> bool:
    """Whether a start time the command shows lies between two wall-clock readings taken around
    the process's start, give or take the kernel's clock tick (it is counted in ticks)."""
    return before - 0.05 <= started_wall_ns / 1e9 <= after + 0.05


def test_node_list_shows_a_schedulers_nodes_with_their_topics(children):
    before = time.time()
    process = children.python(SCHEDULER.format(sensor="lidar"))
    after = time.time()
    wait_ready(process)
    nodes = wait_until(lambda: json.loads(run_horus("node", "list", "--json").stdout),
                       "the scheduler's announcement")
    assert [n["name"] for n in nodes] == ["lidar", "planner"]
    lidar, planner = nodes
    assert lidar["pid"] == planner["pid"] == process.pid
    assert lidar["rate_hz"] == 100.0 and planner["rate_hz"] == 20.0
    assert lidar["publishers"] == [{"topic": "scan", "type": "horus.msg.GenericMessage"}]
    assert planner["subscribers"] == [{"topic": "scan", "type": "horus.msg.GenericMessage"}]
    assert lidar["state"] == "Running" and lidar["health"] == "Healthy"
    assert started_between(lidar["started_wall_ns"], before, after), (lidar, before, after)

    assert run_horus("node", "list").stdout.split() == ["lidar", "planner"]
    verbose = run_horus("node", "list", "-v").stdout.splitlines()
    assert verbose[0].split()[:4] == ["NODE", "PID", "SCHEDULER", "RATE_HZ"]
    info = run_horus("node", "info", "planner")
    assert info.returncode == 0, info.stderr
    shown = re.search(rf"^process: pid {process.pid} \(started (\S+)\.(\d\d)Z\), scheduler ",
                      info.stdout, re.MULTILINE)
    assert shown, info.stdout
    seconds = calendar.timegm(time.strptime(shown[1], "%Y-%m-%dT%H:%M:%S")) + int(shown[2]) / 100
    assert abs(seconds - planner["started_wall_ns"] / 1e9) < 0.01
    described = json.loads(run_horus("node", "info", "planner", "--json").stdout)
    assert [(n["name"], n["pid"], n["rate_hz"]) for n in described] == \
        [("planner", process.pid, 20.0)]
    assert described[0]["subscribers"] == planner["subscribers"]
    # The same start, worked out again from the boot time (two clocks read a moment apart).
    assert abs(described[0]["started_wall_ns"] - planner["started_wall_ns"]) < 1_000_000
    assert "subscribers: scan (horus.msg.GenericMessage)" in info.stdout
    assert "rate: 20.0 Hz requested" in info.stdout

    missing = run_horus("node", "info", "ghost")
    assert missing.returncode == 1 and "'ghost'" in missing.stderr
    assert missing.stderr.count("\n") == 1


def test_a_killed_schedulers_nodes_are_never_shown_and_shm_clean_removes_them(children):
    survivor = children.python(SCHEDULER.format(sensor="survivor"))
    victim = children.python(SCHEDULER.format(sensor="victim"))
    wait_ready(survivor)
    wait_ready(victim)
    wait_until(lambda: "victim" in run_horus("node", "list").stdout.split(), "the victim's nodes")
    victim.kill()  # no destructor runs: its announcement stays behind
    victim.wait()

    names = [n["name"] for n in json.loads(run_horus("node", "list", "--json").stdout)]
    assert names == ["planner", "survivor"]
    result = run_horus("shm", "clean", "--json")
    # The victim's scheduler announcement and its process announcement (its open topics).
    assert json.loads(result.stdout)["announcements"] == 2
    assert json.loads(run_horus("shm", "clean", "--json").stdout)["announcements"] == 0
    assert run_horus("node", "list").stdout.split() == ["planner", "survivor"]


def test_hz_and_bw_measure_a_100_hz_publisher_from_slot_headers(children):
    wait_ready(children.python(SCHEDULER.format(sensor="lidar")))
    # The acceptance bar: within 10 % of the publisher's 100 Hz.
    hz = json.loads(run_horus("topic", "hz", "scan", "--once", "--window", "2", "--json").stdout)
    assert 90 <= hz["rate_hz"] <= 110, hz
    bw = json.loads(run_horus("topic", "bw", "scan", "--once", "--window", "1", "--json").stdout)
    # {"range": 1.0} as the Python runtime encodes a dict: the same size every time.
    assert bw["messages"] > 0 and bw["mean_message_bytes"] == bw["bytes"] / bw["messages"]
    text = run_horus("topic", "hz", "scan", "--once", "--window", "0.5").stdout
    assert text.startswith("average rate: ") and text.rstrip().endswith(" s)")


def test_hz_of_an_unknown_topic_is_one_line_and_exits_one():
    result = run_horus("topic", "hz", "nowhere", "--once")
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1 and "'nowhere'" in result.stderr


def test_hz_goes_on_when_its_topic_is_removed_and_created_again(children):
    def talker():
        # A scheduler: when it stops, it removes the topic segments nobody else has open.
        process = children.program(os.environ["HORUS_PY_PEER"], "node", "cmdvel", "talk", "50")
        wait_ready(process)
        return process

    first = talker()
    hz = children.start([HORUS, "topic", "hz", "talk", "--window", "0.3", "--json"])

    def window_with(condition):
        while True:
            line = hz.stdout.readline()
            assert line, f"topic hz ended: {stderr_after_kill(hz)}"
            if condition(json.loads(line)["messages"]):
                return

    window_with(lambda messages: messages > 0)
    first.communicate(timeout=30)  # the end of its input stops it
    assert first.returncode == 0
    wait_until(lambda: "talk" not in run_horus("topic", "list").stdout.split(),
               "the stopped scheduler to remove its topic")
    window_with(lambda messages: messages == 0)
    talker()
    window_with(lambda messages: messages > 0)
    assert hz.poll() is None
    assert stderr_after_kill(hz) == "horus: topic 'talk' was removed (its last user ended); " \
                                    "counting again once it is back"


@contextlib.contextmanager
def _monitor(namespace: str):
    """`horus monitor` in a real terminal (tmux), refreshing every 0.3 s; yields a function that
    returns its screen's rows by their first word."""
    assert shutil.which("tmux"), "tmux runs the monitor in a real terminal (scripts/install-deps)"
    session = f"horus_{namespace}"
    environment = [f"{key}={os.environ[key]}" for key in
                   ("PYTHONPATH", "HORUS_SHM_DIR", "HORUS_NAMESPACE")]
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "120", "-y", "30", "env",
                    *environment, HORUS, "monitor", "--interval", "0.3"], check=True)

    def rows() -> dict[str, list[str]]:
        pane = subprocess.run(["tmux", "capture-pane", "-p", "-t", session],
                              capture_output=True, text=True).stdout
        return {line.split()[0]: line.split() for line in pane.splitlines() if line.split()}
    try:
        yield session, rows
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)


def test_monitor_in_a_real_terminal_shows_nodes_and_rates_and_quits_on_q(children, namespace):
    wait_ready(children.python(SCHEDULER.format(sensor="lidar")))
    with _monitor(namespace) as (session, screen):
        def screen_with_rates():
            rows = screen()
            # A rate shows once measured (from send stamps, or counted between two refreshes).
            if "lidar" in rows and "scan" in rows and rows["scan"][4] != "-":
                return rows
            return None
        rows = wait_until(screen_with_rates, "the monitor's nodes and topic rates")
        assert rows["lidar"][2] == "100.0" and rows["planner"][2] == "20.0"
        assert float(rows["scan"][4]) > 0 and rows["scan"][-1].endswith("/s")
        subprocess.run(["tmux", "send-keys", "-t", session, "q"], check=True)
        wait_until(lambda: subprocess.run(["tmux", "has-session", "-t", session],
                                          capture_output=True).returncode != 0,
                   "the monitor to quit on q")


ONE_HZ = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "slow")
start, sent = time.monotonic(), 0
while True:
    sent += 1
    topic.send(CmdVel(linear=float(sent)))
    if sent == 6:
        print("ready", flush=True)
    time.sleep(max(0.0, start + sent - time.monotonic()))
"""


def test_list_and_monitor_show_the_rate_of_a_1_hz_topic(children, namespace):
    # A short window counts 0 or 1 message of a 1 Hz topic (a rate of 0 or twice the truth);
    # its send stamps span seconds.
    publisher = children.python(ONE_HZ)
    wait_ready(publisher)

    def listed_rate() -> float:
        return json.loads(run_horus("topic", "list", "-v", "--json").stdout)[0]["rate_hz"]
    for _ in range(3):
        assert 0.6 <= listed_rate() <= 1.5
        time.sleep(0.4)
    with _monitor(namespace) as (_, screen):
        def rate_shown():
            row = screen().get("slow")
            return row if row and row[4] != "-" else None
        row = wait_until(rate_shown, "the monitor's rate of the 1 Hz topic")
        assert 0.6 <= float(row[4]) <= 1.5, row
    # Its stamps stay in the ring; once it missed two periods the rate is 0.
    publisher.kill()
    wait_until(lambda: listed_rate() == 0.0, "a rate of 0 after the publisher ended")


def test_monitor_without_a_terminal_is_a_usage_error():
    result = run_horus("monitor")
    assert result.returncode == 2 and "needs a terminal" in result.stderr


def test_msg_list_show_and_hash_of_installed_types_match_the_live_segment(children):
    names = run_horus("msg", "list").stdout.split()
    assert "horus.msg.CmdVel" in names
    listed = json.loads(run_horus("msg", "list", "--json").stdout)
    assert [t["name"] for t in listed] == names
    cmd_vel = next(t for t in listed if t["name"] == "horus.msg.CmdVel")
    assert cmd_vel["kind"] == "message" and cmd_vel["tier"] == "pod" and cmd_vel["size"] == 16
    shown = json.loads(run_horus("msg", "show", "CmdVel", "--json").stdout)
    assert shown["name"] == "horus.msg.CmdVel" and shown["size"] == 16
    assert [f["name"] for f in shown["fields"]] == ["stamp_nanos", "linear", "angular"]
    fingerprint = run_horus("msg", "hash", "horus.msg.CmdVel").stdout.strip()
    wait_ready(children.python(PUBLISH_CMDVEL.format(name="cmd_vel")))
    segment = json.loads(run_horus("topic", "info", "cmd_vel", "--json").stdout)
    assert int(fingerprint, 16) == segment["fingerprint"]
    # The type description the segment carries, as hex digits (JSON has no bytes).
    from horus.msg import CmdVel
    assert "description" not in segment
    assert bytes.fromhex(segment["description_hex"]) == CmdVel.__horus__.description
    listed = json.loads(run_horus("topic", "list", "--json").stdout)
    assert [t["description_hex"] for t in listed] == [segment["description_hex"]]


def test_msg_show_of_a_user_type_given_with_I_with_its_padding(tmp_path):
    schemas = tmp_path / "schemas" / "my_robot"
    schemas.mkdir(parents=True)
    (schemas / "arm.hmsg").write_text("package my_robot;\n\nJointGoal {\n    joint: u16,\n"
                                      "    angle: f64,\n    done: bool,\n}\n")
    result = run_horus("msg", "show", "my_robot.JointGoal", "-I", str(tmp_path / "schemas"))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "type: my_robot.JointGoal (message)"
    assert lines[2] == "tier: pod, size 24, alignment 8"
    # The holes between fields and at the end are rows of their own.
    assert [line.split() for line in lines[3:9]] == [
        ["FIELD", "TYPE", "OFFSET", "SIZE"], ["joint", "u16", "0", "2"],
        ["(padding)", "-", "2", "6"], ["angle", "f64", "8", "8"], ["done", "bool", "16", "1"],
        ["(padding)", "-", "17", "7"]]
    assert lines[9:] == ["schema:", "  message my_robot.JointGoal {", "    joint: u16,",
                         "    angle: f64,", "    done: bool,", "  }"]
    missing = run_horus("msg", "hash", "Nope", "-I", str(tmp_path / "schemas"))
    assert missing.returncode == 1 and "'Nope'" in missing.stderr
    # Without -I only the installed types are known: the error says how to show one's own.
    installed_only = run_horus("msg", "show", "my_robot.JointGoal")
    assert installed_only.returncode == 1 and installed_only.stderr.count("\n") == 1
    assert "no message type 'my_robot.JointGoal' in the installed schemas" in \
        installed_only.stderr and "-I DIR" in installed_only.stderr, installed_only.stderr


TOPIC_WITHOUT_SCHEDULER = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "alone")
print("ready", flush=True)
while True:
    time.sleep(1)
"""


def test_processes_without_a_scheduler_announce_their_topics_and_services(children):
    before = time.time()
    python = children.python(TOPIC_WITHOUT_SCHEDULER)
    after = time.time()
    wait_ready(python)
    server = children.program(os.environ["HORUS_PY_SERVICE_PEER"], "serve")
    wait_ready(server, "serving")

    def both_announced():
        found = {p["pid"]: p for p in json.loads(run_horus("process", "list", "--json").stdout)}
        # Changes after a process's first are written a moment later (coalesced).
        return found if len(found.get(server.pid, {}).get("services", [])) == 2 else None
    processes = wait_until(both_announced, "the server's services in its announcement")
    assert set(processes) == {python.pid, server.pid}
    assert processes[python.pid]["topics"] == [
        {"topic": "alone", "type": "horus.msg.CmdVel", "handles": 1}]
    assert processes[python.pid]["nodes"] == [] and processes[python.pid]["services"] == []
    assert started_between(processes[python.pid]["started_wall_ns"], before, after)
    table = run_horus("process", "list").stdout.splitlines()
    assert table[0].split()[:3] == ["PID", "STARTED", "PROGRAM"]
    row = next(line.split() for line in table if line.startswith(f"{python.pid} "))
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d\dZ", row[1]), row
    assert row[2] == "python3"
    served = {s["service"]: s for s in processes[server.pid]["services"]}
    assert served["Add"] == {"service": "Add", "role": "server",
                             "request_type": "pyrt_test.AddRequest",
                             "response_type": "pyrt_test.AddResponse"}
    info = run_horus("topic", "info", "alone")
    assert f"open in: pid {python.pid} (python3)" in info.stdout

    # A client that ran and exited took its announcement with it; a killed process is not shown.
    client = children.program(os.environ["HORUS_PY_SERVICE_PEER"], "call", "1", "2", "hi")
    assert client.wait(timeout=30) == 0
    python.kill()
    python.wait()
    assert [p["pid"] for p in json.loads(run_horus("process", "list", "--json").stdout)] == \
        [server.pid]
    assert json.loads(run_horus("shm", "clean", "--json").stdout)["announcements"] == 1


FORKING = """
import os, time, horus
from horus.msg import CmdVel
parent_topics = [horus.Topic(CmdVel, f"parent_{i}") for i in range(20)]  # the writer is busy
child = os.fork()
if child == 0:
    mine = horus.Topic(CmdVel, "child_only")
    print("child", os.getpid(), flush=True)
    time.sleep(60)
    os._exit(0)
print("parent", os.getpid(), flush=True)
time.sleep(60)
"""


def test_a_forked_child_announces_itself_and_leaves_its_parents_announcement_alone(children):
    process = children.python(FORKING)
    pids = dict(process.stdout.readline().split() for _ in range(2))
    parent, child = int(pids["parent"]), int(pids["child"])
    try:
        def both():
            found = {p["pid"]: p for p in json.loads(run_horus("process", "list", "--json").stdout)}
            if child in found and len(found.get(parent, {}).get("topics", [])) == 20:
                return found
            return None
        found = wait_until(both, "the parent's and the child's announcements")
        assert [t["topic"] for t in found[child]["topics"]] == ["child_only"]
        assert "child_only" not in [t["topic"] for t in found[parent]["topics"]]
    finally:
        os.kill(child, 9)
