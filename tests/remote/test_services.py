"""A robot's service called from a laptop's namespace across `horus remote`: the laptop's
mirror serves it there while the link lasts (POD request frames, serialized response frames),
the server's failure comes back as it is, a service outside the policy is not served, and the
robot's server gone or the link lost ends a call with an error (a TransportError during an
outage), never a wait for its timeout, and calls are answered again once the link is back.
A call the robot's server does not answer reaches the laptop's caller with the kind and text a
caller on the robot would get: NoServerError, ServiceTimeout, TransportError. The first caller of
a fresh laptop namespace is answered too, `horus service call` (which makes no reply topic of
its own when it does not know the response type) included, and its unanswered call fails with
its kind when its schemas tell the type; `horus remote status` counts as sent only the requests
the robot got."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

from conftest import HORUS, SCHEMAS, connect, free_port, serve
from peer_scripts import scale_server
from processes import World, wait_line, wait_until

SERVER = scale_server("remote_test")

# calls: five calls and a failing one, printing what each gave.
# none: whether a server shows up within 3 s.
# once: one call, printing the error's class or the answer; answer: the same once a server is
# there (up to 20 s).
CLIENT = """
import sys, horus
from remote_test import Scale, ScaleRequest
client = horus.ServiceClient(Scale)
mode = sys.argv[1]
if mode == "calls":
    print("server", client.wait_for_server(30), flush=True)
    for i in range(5):
        answer = client.call(ScaleRequest(value=float(i), factor=2.5), timeout=20)
        print("answer", answer.product, answer.note, flush=True)
    try:
        client.call(ScaleRequest(value=1.0, factor=0.0), timeout=20)
    except horus.ServiceError as error:
        print("error", type(error).__name__, error, flush=True)
elif mode == "none":
    print("server", client.wait_for_server(3), flush=True)
else:
    if mode == "answer":
        client.wait_for_server(20)
    try:
        answer = client.call(ScaleRequest(value=1.0, factor=2.0), timeout=20)
        print("answer", answer.product, flush=True)
    except horus.ServiceError as error:
        print("error", type(error).__name__, flush=True)
"""


# A Scale server that sleeps -factor seconds before answering a negative factor (printing
# "handling" as it starts), and stops (withdraws) at a line on stdin.
STOPPABLE_SERVER = """
import sys, time, horus
from remote_test import Scale, ScaleResponse
def handle(request):
    print("handling", flush=True)
    if request.factor == 0:
        raise ValueError("a factor of 0")
    if request.factor < 0:
        time.sleep(-request.factor)
    return ScaleResponse(product=request.value * request.factor, note="")
server = horus.ServiceServer(Scale, handle)
print("ready", flush=True)
sys.stdin.readline()
server.stop()
print("stopped", flush=True)
sys.stdin.readline()
"""

# Calls Scale once per line "VALUE FACTOR TIMEOUT" on stdin, printing the answer or the error's
# class and text; a line "answered" calls until a call is answered (the laptop serves the
# service again), printing "answered".
CALLER = """
import sys, time, horus
from remote_test import Scale, ScaleRequest
client = horus.ServiceClient(Scale)
print("server", client.wait_for_server(30), flush=True)
for line in sys.stdin:
    if line.strip() == "answered":
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            try:
                client.call(ScaleRequest(value=1.0, factor=1.0), timeout=5)
                break
            except (horus.NoServerError, horus.TransportError):
                time.sleep(0.05)
        print("answered", flush=True)
        continue
    value, factor, timeout = map(float, line.split())
    try:
        answer = client.call(ScaleRequest(value=value, factor=factor), timeout=timeout)
        print("answer", answer.product, flush=True)
    except horus.ServiceError as error:
        print("error", type(error).__name__, error, flush=True)
"""


def env_with(world, generated) -> dict:
    env = world.env()
    env["PYTHONPATH"] = os.pathsep.join([str(generated), env.get("PYTHONPATH", "")])
    return env


def client_lines(children, world, generated, mode: str) -> list[str]:
    client = children.python(CLIENT, env_with(world, generated), mode)
    out, _ = client.communicate(timeout=90)
    assert client.returncode == 0, client.errors.text()
    return out.splitlines()


def test_service_called_across_the_link(children, worlds, certs, generated):
    robot, laptop = worlds
    robot_server = children.python(SERVER, env_with(robot, generated))
    wait_line(robot_server, "ready")
    server, port = serve(children, robot, certs, "laptop call Scale", port=free_port())
    link = connect(children, laptop, certs, port)
    lines = client_lines(children, laptop, generated, "calls")
    assert lines[0] == "server True"
    assert lines[1:6] == [f"answer {i * 2.5} {i:g} times 2.5" for i in range(5)]
    assert lines[6].startswith("error ServiceFailed") and "a factor of 0" in lines[6]
    link.errors.wait_for("serving Scale of the robot here")

    # The robot's server gone: a call from the laptop ends with an error, not its timeout.
    robot_server.kill()
    robot_server.wait()
    error = client_lines(children, laptop, generated, "once")[0]
    assert error in ("error TransportError", "error NoServerError"), error
    robot_server = children.python(SERVER, env_with(robot, generated))
    wait_line(robot_server, "ready")
    assert client_lines(children, laptop, generated, "answer")[0] == "answer 2.0"

    # The link lost: a call ends with a transport error at once, not at its timeout; once the
    # robot is back, calls are answered again.
    server.kill()
    link.errors.wait_for("trying again")
    assert client_lines(children, laptop, generated, "once") == ["error TransportError"]
    serve(children, robot, certs, "laptop call Scale", port=port)
    wait_line(link, "connected to")  # the first connection's line
    wait_line(link, "connected to")  # the new one's
    assert client_lines(children, laptop, generated, "answer")[0] == "answer 2.0"


def test_service_outside_the_policy_is_not_served(children, worlds, certs, generated):
    robot, laptop = worlds
    wait_line(children.python(SERVER, env_with(robot, generated)), "ready")
    _, port = serve(children, robot, certs, "laptop read *")
    connect(children, laptop, certs, port)
    assert client_lines(children, laptop, generated, "none") == ["server False"]



def talking(children, code: str, env: dict):
    """A Python child running `code` whose stdin the test writes lines to."""
    return children.start([sys.executable, "-c", code], env, keep_stdin=True)


def ask(caller, line: str) -> str:
    caller.stdin.write(line + "\n")
    caller.stdin.flush()
    return wait_line(caller, "")


def test_unanswered_calls_reach_the_caller_with_their_kind(children, worlds, certs, generated):
    robot, laptop = worlds
    robot_server = talking(children, STOPPABLE_SERVER, env_with(robot, generated))
    wait_line(robot_server, "ready")
    server, port = serve(children, robot, certs, "laptop call Scale", port=free_port())
    link = connect(children, laptop, certs, port)
    caller = talking(children, CALLER, env_with(laptop, generated))
    assert wait_line(caller, "server") == "server True"

    assert ask(caller, "1 0 20") == "error ServiceFailed the handler raised: ValueError: a factor of 0"

    # The robot's relay waits 10 s for its server: the caller's 20 s are not spent.
    assert ask(caller, "1 -12 20") == (
        "error ServiceTimeout no answer from Scale on the robot within 10000 ms")

    # The robot's server dies in the middle of a call.
    caller.stdin.write("1 -30 20\n")
    caller.stdin.flush()
    for _ in range(3):  # the failed call's, the one that timed out, this one
        wait_line(robot_server, "handling")
    robot_server.send_signal(signal.SIGKILL)
    died = wait_line(caller, "")
    # The laptop may have withdrawn its stand-in (the robot has no live server) before the
    # robot's reason came: the kind is the same, the text the laptop's own.
    assert died.startswith("error TransportError the server of Scale "), died
    assert died.endswith("died before answering") or died.endswith("stopped before answering")

    # The robot's server stopped while the laptop still serves the service: the robot's
    # NoServer reaches the caller. Asked the moment it stopped, before the laptop's next look at
    # the robot's services (every second), which withdraws the stand-in; a call after that finds
    # no server on the laptop itself, also a NoServerError, with the laptop's text.
    texts = []
    for _ in range(3):
        robot_server = talking(children, STOPPABLE_SERVER, env_with(robot, generated))
        wait_line(robot_server, "ready")
        assert ask(caller, "answered") == "answered"
        assert ask(caller, "2 3 20") == "answer 6.0"
        robot_server.stdin.write("stop\n")
        robot_server.stdin.flush()
        wait_line(robot_server, "stopped")
        answer = ask(caller, "2 3 20")
        assert answer.startswith("error NoServerError no server for Scale "), answer
        texts.append(answer)
        if answer == "error NoServerError no server for Scale on the robot":
            break
    assert texts[-1] == "error NoServerError no server for Scale on the robot", texts

    # The link lost: the caller's TransportError names it.
    robot_server = talking(children, STOPPABLE_SERVER, env_with(robot, generated))
    wait_line(robot_server, "ready")
    assert ask(caller, "answered") == "answered"
    server.kill()
    link.errors.wait_for("trying again")
    assert ask(caller, "2 3 20") == "error TransportError the link to the robot is down"


def test_the_robots_wait_for_an_answer_is_the_call_timeout_of_connect(children, worlds, certs,
                                                                       generated):
    robot, laptop = worlds
    wait_line(talking(children, STOPPABLE_SERVER, env_with(robot, generated)), "ready")
    _, port = serve(children, robot, certs, "laptop call Scale")
    connect(children, laptop, certs, port, "--call-timeout", "1.5")
    caller = talking(children, CALLER, env_with(laptop, generated))
    assert wait_line(caller, "server") == "server True"
    assert ask(caller, "1 -4 20") == (
        "error ServiceTimeout no answer from Scale on the robot within 1500 ms")


def test_a_call_timeout_out_of_range_is_a_usage_error():
    for text in ("0", "-1", "61", "soon", "nan"):
        result = subprocess.run([HORUS, "remote", "connect", "127.0.0.1:1", "--insecure",
                                 "--call-timeout", text], capture_output=True, text=True)
        assert result.returncode == 2, (text, result)
        assert f"--call-timeout needs a number of seconds from 0.001 to 60, not '{text}'" \
            in result.stderr, (text, result.stderr)


HALVE_SERVER = """
import time, horus
from remote_test import Halve, HalveResponse
server = horus.ServiceServer(Halve, lambda request: HalveResponse(half=request.value / 2))
print("ready", flush=True)
while True:
    time.sleep(1)
"""

# As CALLER, for Halve (POD request and response frames): "VALUE TIMEOUT" per line.
HALVE_CALLER = """
import sys, horus
from remote_test import Halve, HalveRequest
client = horus.ServiceClient(Halve)
print("server", client.wait_for_server(30), flush=True)
for line in sys.stdin:
    value, timeout = map(float, line.split())
    try:
        print("answer", client.call(HalveRequest(value=value), timeout=timeout).half, flush=True)
    except horus.ServiceError as error:
        print("error", type(error).__name__, error, flush=True)
"""


def test_unanswered_pod_call_reaches_the_caller_with_its_kind(children, worlds, certs, generated):
    robot, laptop = worlds
    wait_line(children.python(HALVE_SERVER, env_with(robot, generated)), "ready")
    server, port = serve(children, robot, certs, "laptop call Halve")
    link = connect(children, laptop, certs, port)
    caller = talking(children, HALVE_CALLER, env_with(laptop, generated))
    assert wait_line(caller, "server") == "server True"
    assert ask(caller, "5 20") == "answer 2.5"
    server.kill()
    link.errors.wait_for("trying again")
    # The laptop's answer is a POD response frame: its error text at the frame's own offset.
    assert ask(caller, "5 20") == "error TransportError the link to the robot is down"


def service_call(world, value: str, *args: str) -> subprocess.CompletedProcess:
    """`horus service call Scale VALUE` in `world`."""
    return subprocess.run([HORUS, "service", "call", "Scale", value, *args], env=world.env(),
                          capture_output=True, text=True, timeout=90)


def request_counts(world) -> tuple[int, int] | None:
    """(sent, dropped) of the laptop's stream of Scale requests in `horus remote status`."""
    listed = subprocess.run([HORUS, "remote", "status", "--json"], env=world.env(),
                            capture_output=True, text=True, check=True)
    for row in json.loads(listed.stdout):
        if row["stream"] == "requests of Scale to the robot":
            return row["sent"], row["dropped"]
    return None


def test_the_first_caller_of_a_fresh_laptop_namespace_is_answered(children, worlds, certs,
                                                                   generated, tmp_path):
    robot, laptop = worlds
    wait_line(children.python(SERVER, env_with(robot, generated)), "ready")
    server, port = serve(children, robot, certs, "laptop call Scale")
    link = connect(children, laptop, certs, port)
    link.errors.wait_for("serving Scale of the robot here")

    # No reply topic of the service exists on either side: the command leaves its own to the
    # server, here the laptop's stand-in, which learns the type of the frames from the robot.
    called = service_call(laptop, "{value: 2, factor: 1.5}")
    assert called.returncode == 0, called.stderr
    assert "product: 3.0" in called.stdout and "2 times 1.5" in called.stdout, called.stdout
    assert wait_until(lambda: request_counts(laptop) == (1, 0),
                      "one request sent in horus remote status")

    # A Python client, first caller in another fresh namespace.
    other = World(tmp_path / "shm_c")
    connect(children, other, certs, port).errors.wait_for("serving Scale of the robot here")
    lines = client_lines(children, other, generated, "calls")
    assert lines[1:6] == [f"answer {i * 2.5} {i:g} times 2.5" for i in range(5)], lines

    # A request the robot never gets is answered here with its kind, and not counted as sent.
    server.kill()
    link.errors.wait_for("trying again")
    called = service_call(laptop, "{value: 2, factor: 1.5}")
    assert called.returncode == 1, called
    assert "the link to the robot is down" in called.stderr, called.stderr
    assert wait_until(lambda: request_counts(laptop) == (1, 1),
                      "the request held back counted as dropped in horus remote status")


def test_a_first_callers_unanswered_call_fails_with_its_kind(children, worlds, certs, generated):
    robot, laptop = worlds
    wait_line(talking(children, STOPPABLE_SERVER, env_with(robot, generated)), "ready")
    # A caller on the robot has been answered: the robot has a reply topic with the frames' type.
    at_robot = talking(children, CALLER, env_with(robot, generated))
    assert wait_line(at_robot, "server") == "server True"
    assert ask(at_robot, "1 2 5") == "answer 2.0"
    _, port = serve(children, robot, certs, "laptop call Scale")
    link = connect(children, laptop, certs, port, "--call-timeout", "1")
    link.errors.wait_for("serving Scale of the robot here")
    started = time.monotonic()
    called = service_call(laptop, "{value: 1, factor: -3}", "--timeout", "30")
    assert called.returncode == 1, called
    assert "no answer from Scale on the robot within 1000 ms" in called.stderr, called.stderr
    assert time.monotonic() - started < 25, "the call waited for its own timeout"


def test_a_first_callers_call_no_side_ever_answered_fails_with_its_kind(children, worlds, certs,
                                                                       generated, tmp_path):
    robot, laptop = worlds
    # A fresh robot whose server never answers in time (it sleeps 30 s), nobody having called
    # it: no reply topic of the service exists on either side.
    robot_server = talking(children, STOPPABLE_SERVER, env_with(robot, generated))
    wait_line(robot_server, "ready")
    _, port = serve(children, robot, certs, "laptop call Scale")
    link = connect(children, laptop, certs, port, "--call-timeout", "1")
    link.errors.wait_for("serving Scale of the robot here")
    started = time.monotonic()
    # The command, the first and only caller, knows the response type from the service's
    # schema, opens its reply topic with it, and so can be told of the failure.
    called = service_call(laptop, "{value: 1, factor: -30}", "--timeout", "30", "-I",
                          str(SCHEMAS))
    assert called.returncode == 1, called
    assert "failed (Timeout): no answer from Scale on the robot within 1000 ms" in called.stderr, \
        called.stderr
    assert time.monotonic() - started < 20, "the call waited for its own timeout"
    assert "cannot be told" not in link.errors.text(), link.errors.text()

    # A Python client, first caller in another fresh namespace: its own reply topic tells the
    # type.
    other = World(tmp_path / "shm_c")
    connect(children, other, certs, port, "--call-timeout", "1").errors.wait_for(
        "serving Scale of the robot here")
    caller = talking(children, CALLER, env_with(other, generated))
    assert wait_line(caller, "server") == "server True"
    assert ask(caller, "1 -30 20") == (
        "error ServiceTimeout no answer from Scale on the robot within 1000 ms")
