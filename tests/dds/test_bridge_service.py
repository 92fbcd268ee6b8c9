"""Services across `horus bridge`: a client in namespace B (Python, and C++: service_peer.cpp)
calls a server in namespace A over DDS (rq/ScaleRequest, rr/ScaleReply) and gets each failure as
the kind it would get calling locally: NoServer with no server anywhere, or when the server on
A's side leaves; Timeout when A's server does not answer in time there; ServiceFailed naming
the handler's failure."""
from __future__ import annotations

import os
import signal

import pytest

from peer_scripts import scale_server
from processes import wait_line
from test_bridge import bridge, python_env

SERVER = scale_server("dds_test")

# Scale with two more cases: a factor of 99 takes 1.5 s (longer than the exporting bridge's
# --service-timeout), a factor of -1 is answered and the server stops (withdraws) 0.25 s later,
# once the answer is surely in.
SERVER_WITH_KINDS = """
import threading, time, horus
from dds_test import Scale, ScaleResponse
def handle(request):
    if request.factor == 99:
        time.sleep(1.5)
    elif request.factor == -1:
        threading.Timer(0.25, server.stop).start()
    return ScaleResponse(product=request.value * request.factor, note="")
server = horus.ServiceServer(Scale, handle)
print("ready", flush=True)
while True:
    time.sleep(1)
"""

# call: waits for a server, makes five calls and a failing one, printing what each gave.
# once: one call, printing the error's class and kind (or the answer).
# until-no-server: calls every 0.1 s until one gives NoServerError, printing it.
# kinds: waits for a server, then calls with the factors 99, -1 and 2 (20 s timeouts), printing
# each answer or error as service_peer.cpp's kinds does; the second 3 s after the first, so that
# the server is done with it, the third 0.5 s after the second, when the server has stopped.
CLIENT = """
import sys, time, horus
from dds_test import Scale, ScaleRequest
client = horus.ServiceClient(Scale)
mode = sys.argv[1]
if mode == "call":
    print("server", client.wait_for_server(30), flush=True)
    for i in range(5):
        answer = client.call(ScaleRequest(value=float(i), factor=2.5), timeout=20)
        print("answer", answer.product, answer.note, flush=True)
    try:
        client.call(ScaleRequest(value=1.0, factor=0.0), timeout=20)
    except horus.ServiceError as error:
        print("error", type(error).__name__, error, flush=True)
elif mode == "kinds":
    client.wait_for_server(30)
    for factor in (99.0, -1.0, 2.0):
        try:
            answer = client.call(ScaleRequest(value=1.0, factor=factor), timeout=20)
            print("answer", f"{answer.product:g}", flush=True)
        except horus.ServiceError as error:
            print("error", error.kind, error, flush=True)
        time.sleep({99.0: 3, -1.0: 0.5}.get(factor, 0))
elif mode == "once":
    try:
        answer = client.call(ScaleRequest(value=1.0, factor=2.0), timeout=2)
        print("answer", answer.product, flush=True)
    except horus.ServiceError as error:
        print("error", type(error).__name__, error.kind, flush=True)
else:
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            client.call(ScaleRequest(value=1.0, factor=2.0), timeout=5)
        except horus.NoServerError as error:
            print("error", type(error).__name__, error.kind, flush=True)
            break
        except horus.ServiceError:
            pass
        time.sleep(0.1)
"""


CPP_CLIENT = os.environ.get("HORUS_DDS_SERVICE_PEER", "")  # service_peer.cpp


def run_client(children, world, generated, mode: str, language: str = "python") -> list[str]:
    if language == "python":
        client = children.python(CLIENT, python_env(world, generated), mode)
    else:
        client = children.start([CPP_CLIENT, mode], world.env())
    out, errors = client.communicate(timeout=90)
    assert client.returncode == 0, errors
    return out.splitlines()


def test_a_client_in_b_calls_a_server_in_a_through_the_bridges(
        dds_domain, worlds, children, generated):
    source, target = worlds
    server = children.python(SERVER, python_env(source, generated))
    wait_line(server, "ready")
    exporter = bridge(children, source, generated, dds_domain, "--export-service", "Sc*")
    importer = bridge(children, target, generated, dds_domain, "--import-service", "*")

    lines = run_client(children, target, generated, "call")
    assert lines == ["server True"] + [f"answer {2.5 * i} {i} times 2.5" for i in range(5)] + [
        "error ServiceFailed on the server's host: the handler raised: ValueError: a factor of 0"
    ], lines
    assert run_client(children, target, generated, "call", "c++") == ["answer 7.5 3 times 2.5"]

    # The server goes: the exporting bridge withdraws the service from DDS, the importing one
    # its local stand-in, and B's callers get NoServer as they would with no bridge.
    server.send_signal(signal.SIGTERM)
    server.communicate(timeout=30)
    assert run_client(children, target, generated, "until-no-server") == [
        "error NoServerError no_server"]
    wait_line(importer, "no longer importing service 'Scale' (no server on DDS)")
    said = {}
    for side, process in (("exporter", exporter), ("importer", importer)):
        process.send_signal(signal.SIGTERM)
        said[side], errors = process.communicate(timeout=30)
        assert process.returncode == 0 and errors == "", errors
    assert ("exporting service 'Scale' as rq/ScaleRequest (dds_test::dds_::Scale_Request_) and "
            "rr/ScaleReply (dds_test::dds_::Scale_Response_)") in said["exporter"], said


@pytest.mark.parametrize("language", ["python", "c++"])
def test_with_no_server_anywhere_a_client_across_the_bridge_gets_no_server(
        language, dds_domain, worlds, children, generated):
    source, target = worlds
    bridge(children, source, generated, dds_domain, "--export-service", "*")
    bridge(children, target, generated, dds_domain, "--import-service", "*")
    lines = run_client(children, target, generated, "once", language)
    if language == "python":
        assert lines == ["error NoServerError no_server"]
    else:
        assert len(lines) == 1 and lines[0].startswith("error NoServer "), lines


@pytest.mark.parametrize("language", ["python", "c++"])
def test_a_remote_timeout_and_a_remote_no_server_reach_the_caller_as_those_kinds(
        language, dds_domain, worlds, children, generated):
    """The exporting bridge gives A's server 0.5 s: a call A's server takes 1.5 s over is the
    caller's Timeout (well before its own 20 s); a call that finds A's server gone (it withdrew
    after answering the call before) is the caller's NoServer, whichever side notices first: the
    exporting bridge's call (most often: it looks for servers every 0.5 s), the importing one's
    request writer losing its reader, or the importing bridge withdrawing its stand-in."""
    source, target = worlds
    server = children.python(SERVER_WITH_KINDS, python_env(source, generated))
    wait_line(server, "ready")
    bridge(children, source, generated, dds_domain, "--export-service", "Scale",
           "--service-timeout", "0.5")
    bridge(children, target, generated, dds_domain, "--import-service", "Scale")
    lines = run_client(children, target, generated, "kinds", language)
    timeout, answer, no_server = lines
    if language == "python":
        assert timeout == ("error timeout on the server's host: no answer from Scale in time"), lines
        assert no_server.startswith("error no_server "), lines
    else:
        assert timeout == "error Timeout on the server's host: no answer from Scale in time", lines
        assert no_server.startswith("error NoServer "), lines
    assert answer.rstrip() == "answer -1", lines  # C++ prints the (empty) note too
