"""`horus topic echo / pub` and `horus service call` against live C++ and Python processes, for
standard types and for user types generated in the test (the command was never built with
them; one package is even written by the test), POD and serialized, and their bad input."""
from __future__ import annotations

import json
import os
import subprocess
import time
import uuid

from conftest import HORUS, run_horus, wait_ready
from processes import wait_until

USER_PROCESS = """
import sys, time
sys.path.insert(0, {python!r})
import horus
from horus.msg import Accel
from cli_user import Gear, Pose, Route, Shift
poses, routes = horus.Topic(Pose, "pose"), horus.Topic(Route, "route")
poses.send(Pose(gear=Gear.Drive, x=1.5, label="dock", corners=[[1, 2], [3, 4]]))
routes.send(Route(name="to dock", poses=[Pose(x=-2.0)], speed=0.25, accel=Accel(linear=[0.5, 0, 0])))
inbox = {{"pose": horus.Topic(Pose, "pose_in"), "route": horus.Topic(Route, "route_in")}}
for topic in inbox.values():
    topic.try_recv()

def shift(request):
    if request.dx > 50:
        time.sleep(5)  # a server too slow for the caller's timeout
    moved = Pose(gear=request.pose.gear, x=request.pose.x + request.dx, label=request.pose.label)
    return Shift.Response(pose=moved, note=f"moved {{request.pose.label}} by {{request.dx}}")

server = horus.ServiceServer(Shift, shift)
print("ready", flush=True)
while True:
    for name, topic in inbox.items():
        m = topic.recv(0.01)
        if m is not None and name == "pose":
            print("pose", m.gear.name, m.x, m.label, flush=True)
        elif m is not None:
            print("route", m.name, [p.x for p in m.poses], m.speed, flush=True)
"""

SHIFT_CLIENT = """
import sys, time
sys.path.insert(0, {python!r})
import horus
from cli_user import Shift
client = horus.ServiceClient(Shift)
print("ready", flush=True)
time.sleep(60)
"""


def _echo_json(*args: str) -> dict:
    result = run_horus("topic", "echo", *args, "--once", "--json", "--timeout", "10")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_echo_and_pub_of_a_standard_type_with_cpp_peers(children):
    publisher = children.program(os.environ["HORUS_PY_PEER"], "pub", "cmdvel", "cmd_vel", "3")
    assert publisher.wait(timeout=30) == 0
    # The publisher is gone; its newest message is still the topic's.
    assert _echo_json("cmd_vel") == {"stamp_nanos": 0, "linear": 3.0, "angular": -3.0}
    text = run_horus("topic", "echo", "cmd_vel", "--once")
    assert text.stdout == "stamp_nanos: 0\nlinear: 3.0\nangular: -3.0\n---\n"
    field = run_horus("topic", "echo", "cmd_vel", "--once", "--field", "angular")
    assert field.stdout == "-3.0\n"

    subscriber = children.program(os.environ["HORUS_PY_PEER"], "sub", "cmdvel", "cmd_vel", "2")
    wait_ready(subscriber)
    result = run_horus("topic", "pub", "cmd_vel", "{linear: 0.5, angular: 2}", "--count", "2",
                       "--rate", "50")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "published 2 messages on 'cmd_vel'"
    assert subscriber.stdout.read().split() == ["0.5", "0.5"]

    image = children.program(os.environ["HORUS_PY_PEER"], "pub", "image", "camera", "2")
    assert image.wait(timeout=30) == 0
    shown = _echo_json("camera")
    assert shown["format"] == "png" and shown["width"] == 2 and shown["data"] == [0xab, 0xab]


def test_echo_and_pub_of_user_types_unknown_to_the_command(children, user_types):
    process = children.python(USER_PROCESS.format(python=user_types))
    wait_ready(process)
    assert _echo_json("pose") == {"gear": "Drive", "x": 1.5, "label": "dock",
                                  "corners": [[1.0, 2.0], [3.0, 4.0]]}
    route = _echo_json("route")
    assert route["name"] == "to dock" and route["speed"] == 0.25
    assert route["poses"] == [{"gear": "Park", "x": -2.0, "label": "",
                               "corners": [[0.0, 0.0], [0.0, 0.0]]}]
    assert route["accel"]["linear"] == [0.5, 0.0, 0.0]
    assert run_horus("topic", "echo", "route", "--once", "--field", "poses.0.x").stdout == "-2.0\n"

    # Publishing on topics whose users know the types: pose_in (POD), route_in (serialized).
    wait_until(lambda: "pose_in" in run_horus("topic", "list").stdout, "the inbox topics")
    result = run_horus("topic", "pub", "pose_in", "{gear: Drive, x: 7.25, label: shelf}", "--once")
    assert result.returncode == 0, result.stderr
    result = run_horus("topic", "pub", "route_in",
                       '{"name": "back", "poses": [{"x": 1}, {"x": 2}], "speed": null}', "--once")
    assert result.returncode == 0, result.stderr
    received = [process.stdout.readline().strip() for _ in range(2)]
    assert received == ["pose Drive 7.25 shelf", "route back [1.0, 2.0] None"]


FRESH_SCHEMA = """package {package};

enum Blade: u8 {{
    Off = 0,
    Spinning = 1,
}}

/// POD.
Battery {{
    volts: f32,
    cells: [u16; 3],
    blade: Blade,
}}

/// Serialized, holding the POD type.
Report {{
    zone: String,
    cut_m2: Vec<f32>,
    battery: Battery,
}}
"""

FRESH_PROCESS = """
import sys, time
sys.path.insert(0, {python!r})
import horus
from {package} import Battery, Blade, Report
batteries, reports = horus.Topic(Battery, "battery"), horus.Topic(Report, "report")
batteries.send(Battery(volts=24.5, cells=[4100, 4090, 4080], blade=Blade.Spinning))
reports.send(Report(zone="north", cut_m2=[1.5, 2.5], battery=Battery(volts=23.0)))
inbox = {{"battery": horus.Topic(Battery, "battery_in"), "report": horus.Topic(Report, "report_in")}}
for topic in inbox.values():
    topic.try_recv()
print("ready", flush=True)
while True:
    for name, topic in inbox.items():
        m = topic.recv(0.01)
        if m is not None and name == "battery":
            print("battery", m.volts, list(m.cells), m.blade.name, flush=True)
        elif m is not None:
            print("report", m.zone, list(m.cut_m2), m.battery.volts, flush=True)
"""


def test_echo_and_pub_of_a_type_written_and_generated_in_this_test(children, tmp_path):
    # A package name no schema folder, cache or build ever held: the command can only decode it
    # from the schema text the topics' segments store.
    package = f"mower_{uuid.uuid4().hex[:8]}"
    folder = tmp_path / "fresh" / package
    folder.mkdir(parents=True)
    (folder / "mower.hmsg").write_text(FRESH_SCHEMA.format(package=package))
    output = tmp_path / "fresh_generated"
    subprocess.run([os.environ["HORUS_GEN_PROGRAM"], "generate", "--lang", "python", "--out",
                    str(output), "-I", str(folder.parent), str(folder / "mower.hmsg")], check=True)
    process = children.python(FRESH_PROCESS.format(python=str(output / "python"),
                                                   package=package))
    wait_ready(process)

    info = json.loads(run_horus("topic", "info", "battery", "--json").stdout)
    assert (info["type_name"], info["is_pod"]) == (f"{package}.Battery", True)
    assert _echo_json("battery") == {"volts": 24.5, "cells": [4100, 4090, 4080],
                                     "blade": "Spinning"}
    assert _echo_json("report") == {"zone": "north", "cut_m2": [1.5, 2.5],
                                    "battery": {"volts": 23.0, "cells": [0, 0, 0],
                                                "blade": "Off"}}
    assert run_horus("topic", "echo", "report", "--once", "--field", "battery.volts").stdout \
        == "23.0\n"

    for topic, value in (("battery_in", "{volts: 12.5, cells: [1, 2, 3], blade: Spinning}"),
                         ("report_in", "{zone: south, cut_m2: [0.5], battery: {volts: 11}}")):
        result = run_horus("topic", "pub", topic, value, "--once")
        assert result.returncode == 0, result.stderr
    received = [process.stdout.readline().strip() for _ in range(2)]
    assert received == ["battery 12.5 [1, 2, 3] Spinning", "report south [0.5] 11.0"]
    bad = run_horus("topic", "pub", "battery_in", "{blade: Flying}", "--once")
    assert bad.returncode == 1 and "Flying" in bad.stderr and bad.stderr.count("\n") == 1, bad


def test_service_call_against_a_live_cpp_server(children):
    server = children.program(os.environ["HORUS_PY_SERVICE_PEER"], "serve")
    wait_ready(server, "serving")
    for _ in range(2):  # the first call learns the response type from the server's answer
        result = run_horus("service", "call", "Add", "{a: 2, b: 40}", "--json")
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout) == {"sum": 42}
    result = run_horus("service", "call", "Echo", "text: hi\nrepeat: 3")
    assert result.returncode == 0, result.stderr
    assert result.stdout == "text: hihihi\n---\n"

    failed = run_horus("service", "call", "Add", "{a: -1, b: 1}")
    assert failed.returncode == 1 and failed.stderr.count("\n") == 1
    assert "service 'Add' failed" in failed.stderr and "negative" in failed.stderr
    bad = run_horus("service", "call", "Add", "{a: fast}")
    assert bad.returncode == 1 and "field 'a'" in bad.stderr and bad.stderr.count("\n") == 1

    server.kill()
    server.wait()
    dead = run_horus("service", "call", "Add", "{a: 1, b: 1}", "--timeout", "2")
    assert dead.returncode == 1 and dead.stderr.count("\n") == 1, dead
    assert "no live server" in dead.stderr
    missing = run_horus("service", "call", "Nope", "{}")
    assert missing.returncode == 1 and "'Nope'" in missing.stderr


def test_service_call_against_a_python_server_of_a_user_service(children, user_types):
    wait_ready(children.python(USER_PROCESS.format(python=user_types)))
    for _ in range(2):
        result = run_horus("service", "call", "Shift", "{pose: {x: 1.0, label: cart}, dx: 0.5}",
                           "--json")
        assert result.returncode == 0, result.stderr
        answer = json.loads(result.stdout)
        assert answer["pose"]["x"] == 1.5 and answer["pose"]["label"] == "cart"
        assert answer["note"] == "moved cart by 0.5"
    client = children.python(SHIFT_CLIENT.format(python=user_types))
    wait_ready(client)
    wait_until(lambda: f"clients: 1 in pid {client.pid} (python3)" in
               run_horus("service", "info", "Shift").stdout, "the client in service info")
    slow = run_horus("service", "call", "Shift", "{dx: 99}", "--timeout", "0.5")
    assert slow.returncode == 1 and slow.stderr.count("\n") == 1, slow
    assert "no response from service 'Shift' within 0.5 s" in slow.stderr


def test_bad_values_and_topics_are_one_line(children):
    publisher = children.program(os.environ["HORUS_PY_PEER"], "pub", "cmdvel", "cmd_vel", "1")
    assert publisher.wait(timeout=30) == 0
    for args, status, expected in (
            (["topic", "pub", "cmd_vel", 'linear: "fast"'], 1, "field 'linear'"),
            (["topic", "pub", "cmd_vel", "{speed: 1}"], 1, "no field 'speed'"),
            (["topic", "pub", "cmd_vel", "[1, 2]"], 1, "expected a mapping"),
            (["topic", "pub", "cmd_vel", "{linear: 1"], 2, "cannot parse"),
            (["topic", "pub", "nowhere", "{}"], 1, "no topic 'nowhere'"),
            (["topic", "echo", "nowhere"], 1, "no topic 'nowhere'"),
            (["topic", "echo", "cmd_vel", "--field", "linear.x"], 1, "no field 'linear.x'"),
            (["topic", "pub", "cmd_vel", "{}", "--rate", "0"], 2, "--rate")):
        result = run_horus(*args, "--once")
        assert result.returncode == status, (args, result)
        assert result.stderr.count("\n") == 1 and expected in result.stderr, (args, result.stderr)
        assert "Traceback" not in result.stderr


SILENT = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "silent")
print("ready", flush=True)
time.sleep(60)
"""


def test_echo_with_a_timeout_exits_one_on_a_silent_topic(children):
    wait_ready(children.python(SILENT))
    result = run_horus("topic", "echo", "silent", "--timeout", "0.3")
    assert result.returncode == 1, result
    assert result.stdout == ""
    assert result.stderr == "horus: no message on topic 'silent' within 0.3 s\n"


def test_echo_with_a_timeout_waits_for_a_topic_that_does_not_exist_yet(children, namespace):
    echo = children.start([HORUS, "topic", "echo", "later", "--once", "--json", "--timeout", "20"])
    time.sleep(1)  # long enough for a command that does not wait to have given up
    assert echo.poll() is None, echo.communicate()
    publisher = children.program(os.environ["HORUS_PY_PEER"], "pub", "cmdvel", "later", "1")
    assert publisher.wait(timeout=30) == 0
    out, err = echo.communicate(timeout=30)
    assert echo.returncode == 0, err
    assert json.loads(out) == {"stamp_nanos": 0, "linear": 1.0, "angular": -1.0}
    never = run_horus("topic", "echo", "never", "--timeout", "0.3")
    assert (never.returncode, never.stderr) == (
        1, f"horus: no topic 'never' in namespace '{namespace}' within 0.3 s\n")


COUNTER = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "counter")
value = 0
while True:
    value += 1
    topic.send(CmdVel(linear=float(value)))
    if value == 100:
        print("ready", flush=True)
    time.sleep(0.001)
"""


def test_echo_shows_each_message_of_a_fast_publisher_once_and_in_order(children):
    wait_ready(children.python(COUNTER))
    for _ in range(3):
        result = run_horus("topic", "echo", "counter", "--count", "30", "--field", "linear")
        assert result.returncode == 0, result.stderr
        values = [float(value) for value in result.stdout.split()]
        # The newest message when echo started, then the later ones (a slow terminal may lose
        # some to the ring, never repeat one or go back).
        assert len(values) == 30 and all(a < b for a, b in zip(values, values[1:])), values


def test_pub_with_the_type_of_another_topic_names_both_types(children):
    publisher = children.program(os.environ["HORUS_PY_PEER"], "pub", "cmdvel", "cmd_vel", "1")
    assert publisher.wait(timeout=30) == 0
    other = run_horus("topic", "pub", "cmd_vel", "{}", "--type", "Twist", "--once")
    assert (other.returncode, other.stderr) == (
        1, "horus: topic 'cmd_vel' carries horus.msg.CmdVel, not horus.msg.Twist (--type)\n")
    same = run_horus("topic", "pub", "cmd_vel", "{linear: 2}", "--type", "CmdVel", "--once")
    assert same.returncode == 0, same.stderr
    assert _echo_json("cmd_vel")["linear"] == 2.0


def test_pub_with_a_type_creates_a_topic_nobody_opened_yet(tmp_path, user_types):
    result = run_horus("topic", "pub", "fresh", "{linear: 1.5}", "--type", "CmdVel", "--once")
    assert result.returncode == 0, result.stderr
    assert _echo_json("fresh") == {"stamp_nanos": 0, "linear": 1.5, "angular": 0.0}
    # A user type, from its schema folder (which the user_types fixture wrote); what it uses of
    # horus.msg comes from the installed schemas.
    result = run_horus("topic", "pub", "fresh_route", "{name: r, poses: [{gear: Drive}]}",
                       "--type", "cli_user.Route", "-I", str(tmp_path / "user_schemas"), "--once")
    assert result.returncode == 0, result.stderr
    assert _echo_json("fresh_route")["poses"][0]["gear"] == "Drive"
    result = run_horus("topic", "pub", "fresh_pose", "{x: 2.5, gear: Drive}", "--type",
                       "cli_user.Pose", "-I", str(tmp_path / "user_schemas"), "--once")
    assert result.returncode == 0, result.stderr
    assert _echo_json("fresh_pose")["gear"] == "Drive"
    # The topics it creates carry their type's description, as a generated type's do.
    from horus import typedesc
    for topic, type_name in (("fresh", "horus.msg.CmdVel"), ("fresh_route", "cli_user.Route")):
        info = json.loads(run_horus("topic", "info", topic, "--json").stdout)
        described = typedesc.message_class(bytes.fromhex(info["description_hex"])).__horus__
        assert (described.name, described.fingerprint) == (type_name, info["fingerprint"])
    missing = run_horus("topic", "pub", "other", "{}", "--once")
    assert missing.returncode == 1 and "give --type TYPE" in missing.stderr


def test_echo_without_a_carried_description_decodes_the_schema_text_and_refuses_a_contradicting_one():
    from horus import _core
    from horus.msg import Accel, CmdVel
    info = CmdVel.__horus__

    def opened(name: str, description: bytes):
        handle = _core.Topic(name, info.name, info.fingerprint, info.schema, True, info.size,
                             info.alignment, 64, 16 * 1024, False, description)
        assert handle.send(CmdVel(linear=2.0).to_bytes())
        return handle

    textual = opened("textual", b"")
    assert _echo_json("textual") == {"stamp_nanos": 0, "linear": 2.0, "angular": 0.0}
    contradicting = opened("contradicting", Accel.__horus__.description)
    result = run_horus("topic", "echo", "contradicting", "--once", "--timeout", "5")
    assert result.returncode == 1 and result.stderr.count("\n") == 1, result
    assert "stored with horus.msg.CmdVel" in result.stderr and "describes horus.msg.Accel" in \
        result.stderr, result.stderr
    del textual, contradicting


def test_dict_topics_show_and_take_their_plain_value(children):
    publisher = children.program(os.environ["HORUS_PY_PEER"], "pub", "dict", "values", "2")
    assert publisher.wait(timeout=30) == 0
    # A C++ GenericMessage holding {"linear": 2}: shown as that value, not as MessagePack bytes.
    assert _echo_json("values") == {"linear": 2.0}
    subscriber = children.program(os.environ["HORUS_PY_PEER"], "sub", "dict", "values", "1")
    wait_ready(subscriber)
    result = run_horus("topic", "pub", "values", "{linear: 6.5}", "--once")
    assert result.returncode == 0, result.stderr
    assert subscriber.stdout.read().split() == ["6.5"]
