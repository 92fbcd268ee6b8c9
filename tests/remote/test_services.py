"""A robot's service called from a laptop's namespace across `horus remote`: the laptop's
mirror serves it there while the link lasts (POD request frames, serialized response frames),
the server's failure comes back as it is, a service outside the policy is not served, and the
robot's server gone or the link lost ends a call with an error (a TransportError during an
outage), never a wait for its timeout, and calls are answered again once the link is back."""
from __future__ import annotations

import os

from conftest import connect, free_port, serve
from peer_scripts import scale_server
from processes import wait_line

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
