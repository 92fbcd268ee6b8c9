"""A robot's parameters on a laptop across `horus remote`, under the policy's `param` verb: the
laptop's `connect --params` makes local mirrors of what its rules let it see (nothing else of the
node shows), `horus param` there lists, reads and follows the robot's values, and a set there is
the robot's owner's to judge (its callback sees it once, from "remote:laptop"); refusals (out of
range, vetoed, the policy's) come back with their reason. A peer without a `param` rule, a
third-party client of remote.capnp (pycapnp), sees no parameter and its writes are refused
naming the policy. The mirrors end with the link, shown as not running. Every kind of parameter
(the generated ParamNode's: enums, arrays, read-only ones) is mirrored with its declaration, and
a mirror follows its robot node as it stops and starts again."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import pytest
from conftest import GENERATOR, HORUS, SCHEMA, connect, free_port, serve
from peer_scripts import param_motor
from processes import wait_line, wait_until

# The robot's node (peer_scripts.param_motor), with a parameter no policy line here allows.
MOTOR = param_motor('self.declare_param("secret", 42)')

# A peer of remote.capnp alone: what `params` shows it, then a write of motor.max_speed.
PEER = """
import asyncio, os, ssl, sys
import capnp
schema, port, certs = sys.argv[1], int(sys.argv[2]), sys.argv[3]
remote = capnp.load(schema, imports=[os.path.dirname(os.path.dirname(capnp.__file__))])

async def main():
    tls = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=f"{certs}/ca.crt")
    tls.load_cert_chain(f"{certs}/attacker.crt", f"{certs}/attacker.key")
    stream = await capnp.AsyncIoStream.create_connection(host="127.0.0.1", port=port, ssl=tls,
                                                         server_hostname="robot")
    session = capnp.TwoPartyClient(stream).bootstrap().cast_as(remote.Session)
    shown = await session.params(since=0, waitMs=0)
    print("nodes", len(shown.nodes), flush=True)
    # (A request builder: pycapnp's call takes a `name` of its own.)
    write = session.setParam_request()
    write.node, write.name, write.value, write.timeoutMs = "motor", "max_speed", b"\\xcb" + bytes(8), 2000
    answer = await write.send()
    print("accepted", answer.accepted, answer.reason, flush=True)

asyncio.run(capnp.run(main()))
"""


def horus(world, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([HORUS, "--namespace", world.namespace, *args], env=world.env(),
                          capture_output=True, text=True, timeout=30)


def listed(world) -> dict:
    result = horus(world, "param", "list", "--json")
    if result.returncode != 0:
        return {}
    return {f"{row['node']}.{row['name']}": row for row in json.loads(result.stdout)}


def test_parameters_across_the_link(children, worlds, certs):
    robot, laptop = worlds
    motor = children.python(MOTOR, robot.env())
    wait_line(motor, "ready")
    server, port = serve(children, robot, certs, "laptop param motor.max_speed",
                         "laptop param motor.profile", "laptop param motor.gains",
                         "attacker read nothing", port=free_port())
    link = connect(children, laptop, certs, port, "--params", "motor.*")
    link.errors.wait_for("mirroring the parameters of motor")

    # Only what the rules name; the robot's values, its owner running here.
    wait_until(lambda: set(listed(laptop)) == {"motor.max_speed", "motor.profile",
                                               "motor.gains"}, "the laptop's mirror")
    rows = listed(laptop)
    assert rows["motor.max_speed"]["value"] == 1.0
    assert rows["motor.max_speed"]["unit"] == "m/s"
    assert rows["motor.gains"]["value"] == [1.0, 0.5, 0.0]
    assert rows["motor.profile"]["owner_alive"]
    assert horus(laptop, "param", "get", "motor", "secret").returncode != 0

    # A change on the robot reaches the mirror.
    assert horus(robot, "param", "set", "motor", "max_speed", "1.5").returncode == 0
    wait_line(motor, "change max_speed 1.5 horus param")
    wait_until(lambda: listed(laptop)["motor.max_speed"]["value"] == 1.5, "the robot's change")

    # A set on the laptop is the robot's: its callback sees it once, from the laptop.
    result = horus(laptop, "param", "set", "motor", "profile", "sport")
    assert result.returncode == 0, result.stderr
    wait_line(motor, "change profile 'sport' remote:laptop")
    assert horus(robot, "param", "get", "motor", "profile").stdout.strip() == "sport"
    assert listed(laptop)["motor.profile"]["value"] == "sport"

    # Refused with the reason, changing nothing on either side.
    result = horus(laptop, "param", "set", "motor", "max_speed", "5")
    assert result.returncode == 1 and "max" in result.stderr, result.stderr
    result = horus(laptop, "param", "set", "motor", "profile", "track")
    assert result.returncode == 1, result.stderr
    assert "track mode needs the cage closed" in result.stderr, result.stderr
    assert horus(robot, "param", "get", "motor", "profile").stdout.strip() == "sport"
    assert listed(laptop)["motor.profile"]["value"] == "sport"
    # The callback saw the laptop's write once and the refused ones never: the next change it
    # prints is the robot's own next one.
    assert horus(robot, "param", "set", "motor", "max_speed", "0.5").returncode == 0
    assert motor.stdout.readline().rstrip() == "change max_speed 0.5 horus param"
    wait_until(lambda: listed(laptop)["motor.max_speed"]["value"] == 0.5, "the robot's change")

    # A peer without a param rule sees none, and its write is refused naming the policy.
    peer = children.start([sys.executable, "-c", PEER, str(SCHEMA), str(port), str(certs)])
    out, errors = peer.communicate(timeout=30)
    lines = out.splitlines()
    assert len(lines) == 2, errors
    assert lines[0] == "nodes 0", out
    assert lines[1].startswith("accepted False") and "policy" in lines[1], out
    assert horus(robot, "param", "get", "motor", "max_speed").stdout.strip() == "0.5"

    # The link gone, the mirror shows as not running.
    link.terminate()
    link.wait(timeout=10)
    wait_until(lambda: not listed(laptop)["motor.profile"]["owner_alive"], "the mirror's end")


# The node of tests/schemas/test_nodes/param_node.hnode (every kind of parameter), generated.
PARAM_NODE = """
import horus
from test_nodes import ParamNodeBase

class Driver(ParamNodeBase):
    def tick(self):
        if not getattr(self, "said", False):
            self.said = True
            print("ready", flush=True)

    def on_param_change(self, change):
        print(f"change {change.name} {change.value!r} {change.source}", flush=True)

horus.Scheduler(tick_rate=100).add(Driver()).run()
"""

DECLARED = ("type", "min", "max", "choices", "unit", "doc", "read_only", "value", "owner_alive")


@pytest.fixture(scope="module")
def param_node(tmp_path_factory) -> pathlib.Path:
    """test_nodes (ParamNode) and the test_msgs it uses, generated for Python; the folder."""
    schemas = pathlib.Path(__file__).resolve().parents[1] / "schemas"
    out = tmp_path_factory.mktemp("param_node")
    files = [*sorted((schemas / "test_msgs").glob("*.h*")), schemas / "other_pkg" / "stamp.hmsg",
             schemas / "test_nodes" / "param_node.hnode"]
    subprocess.run([GENERATOR, "generate", "--lang", "python", "--out", str(out), "-I",
                    str(schemas), *map(str, files)], check=True, capture_output=True)
    return out / "python"


def test_every_kind_of_parameter_follows_the_robot_node(children, worlds, certs, param_node):
    robot, laptop = worlds
    env = robot.env(PYTHONPATH=os.pathsep.join([str(param_node), os.environ["PYTHONPATH"]]))
    node = children.python(PARAM_NODE, env)
    wait_line(node, "ready")
    server, port = serve(children, robot, certs, "laptop param param_node.*", port=free_port())
    link = connect(children, laptop, certs, port, "--params", "*")
    link.errors.wait_for("mirroring the parameters of param_node")

    # The same declarations and values as on the robot, enums, arrays and read-only ones too.
    here = listed(robot)
    wait_until(lambda: set(listed(laptop)) == set(here), "the laptop's mirror")
    mirrored = listed(laptop)
    for name, row in here.items():
        assert {key: mirrored[name].get(key) for key in DECLARED} == \
            {key: row.get(key) for key in DECLARED}, name

    # An enum set from the laptop, by its enumerator's name; a read-only one refused here.
    result = horus(laptop, "param", "set", "param_node", "mode", "Idle")
    assert result.returncode == 0, result.stderr
    wait_line(node, "change mode")
    assert horus(robot, "param", "get", "param_node", "mode").stdout.strip() == "Idle"
    result = horus(laptop, "param", "set", "param_node", "wheel_count", "6")
    assert result.returncode == 1 and "read-only" in result.stderr, result.stderr

    # The robot's node gone, its mirror goes; started again, it is mirrored again.
    node.terminate()
    node.wait(timeout=10)
    wait_until(lambda: not listed(laptop)["param_node.mode"]["owner_alive"], "the mirror's end")
    node = children.python(PARAM_NODE, env)
    wait_line(node, "ready")
    wait_until(lambda: listed(laptop)["param_node.mode"]["owner_alive"], "the mirror again")
    assert listed(laptop)["param_node.mode"]["value"] == "Run"
