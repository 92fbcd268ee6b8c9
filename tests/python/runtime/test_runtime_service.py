"""Services from Python: clients and servers, interoperating with C++ both ways (real processes)."""
from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import textwrap

import pytest

import horus
from pyrt_test import Add, AddRequest, AddResponse, Echo, EchoRequest, EchoResponse

from .conftest import python_child

SERVICE_PEER = os.environ.get("HORUS_PY_SERVICE_PEER", "")


def add_handler(req):
    if req.a < 0:
        raise ValueError(f"negative a: {req.a}")
    return AddResponse(sum=req.a + req.b)


def echo_handler(req):
    return EchoResponse(text=req.text * req.repeat)


@pytest.fixture
def cpp_server():
    assert SERVICE_PEER, "HORUS_PY_SERVICE_PEER names the C++ service peer (run through ctest)"
    proc = subprocess.Popen([SERVICE_PEER, "serve"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "serving"
    yield proc
    proc.stdin.close()
    assert proc.wait(timeout=30) == 0


def test_python_client_and_python_server_in_one_process():
    with horus.ServiceServer(Add, add_handler) as server:
        client = horus.ServiceClient(Add)
        assert client.call(AddRequest(a=2, b=40), timeout=5.0) == AddResponse(sum=42)
        with pytest.raises(horus.ServiceFailed, match="ValueError: negative a: -1"):
            client.call(AddRequest(a=-1, b=0), timeout=5.0)
        assert server.requests == 2 and server.failures == 1


@pytest.mark.parametrize("error", [horus.NoServerError, horus.ServiceTimeout,
                                   horus.TransportError, horus.ServiceFailed])
def test_a_forwarding_server_hands_its_callers_the_kind_its_own_call_got(error):
    def forward(req):
        raise error(f"elsewhere: {req.a}")

    with horus.ServiceServer(Add, forward, forward_errors=True):
        with pytest.raises(error, match="^elsewhere: 7$"):
            horus.ServiceClient(Add).call(AddRequest(a=7, b=0), timeout=5.0)
    # Without forward_errors, whatever a handler raises is the caller's ServiceFailed.
    with horus.ServiceServer(Add, forward):
        with pytest.raises(horus.ServiceFailed, match=f"the handler raised: {error.__name__}"):
            horus.ServiceClient(Add).call(AddRequest(a=7, b=0), timeout=5.0)


def test_no_server_is_reported_at_once():
    client = horus.ServiceClient(Add)
    with pytest.raises(horus.NoServerError, match="no server for Add"):
        client.call(AddRequest(a=1, b=1), timeout=5.0)
    assert client.wait_for_server(0.05) is False


def test_a_stopped_server_withdraws():
    server = horus.ServiceServer(Add, add_handler)
    client = horus.ServiceClient(Add)
    assert client.wait_for_server(1.0)
    server.stop()
    with pytest.raises(horus.NoServerError):
        client.call(AddRequest(a=1, b=1), timeout=1.0)


def test_a_second_live_server_is_refused():
    with horus.ServiceServer(Add, add_handler):
        with pytest.raises(horus.HorusError, match="already has a server"):
            horus.ServiceServer(Add, add_handler)


def test_timeout_when_the_handler_is_slow():
    import threading
    release = threading.Event()

    def slow(req):
        release.wait(10.0)
        return AddResponse(sum=0)

    with horus.ServiceServer(Add, slow):
        with pytest.raises(horus.ServiceTimeout, match="no answer from Add in time"):
            horus.ServiceClient(Add).call(AddRequest(a=1, b=2), timeout=0.1)
        release.set()


def test_wrong_request_type_is_a_type_error():
    with pytest.raises(TypeError, match="takes a AddRequest"):
        horus.ServiceClient(Add).call(EchoRequest(text="x", repeat=1))


def test_async_calls_return_futures_usable_from_asyncio():
    with horus.ServiceServer(Echo, echo_handler):
        client = horus.ServiceClient(Echo)
        futures = [client.call_async(EchoRequest(text=str(i), repeat=2), timeout=5.0)
                   for i in range(5)]
        assert [f.result(timeout=10).text for f in futures] == ["00", "11", "22", "33", "44"]

        async def main():
            return await asyncio.wrap_future(
                client.call_async(EchoRequest(text="ab", repeat=3), timeout=5.0))

        assert asyncio.run(main()).text == "ababab"
        client.close()


def test_python_client_against_cpp_server(cpp_server):
    adder = horus.ServiceClient(Add)
    echo = horus.ServiceClient(Echo)
    assert adder.call(AddRequest(a=20, b=22), timeout=5.0).sum == 42
    with pytest.raises(horus.ServiceFailed, match="negative a: -3"):
        adder.call(AddRequest(a=-3, b=0), timeout=5.0)
    assert echo.call(EchoRequest(text="py", repeat=3), timeout=5.0).text == "pypypy"
    with pytest.raises(horus.ServiceFailed, match="empty text"):
        echo.call(EchoRequest(text="", repeat=3), timeout=5.0)


def test_cpp_client_against_python_server():
    with horus.ServiceServer(Add, add_handler), horus.ServiceServer(Echo, echo_handler):
        ok = subprocess.run([SERVICE_PEER, "call", "4", "5", "hi"], capture_output=True,
                            text=True, timeout=60)
        assert ok.returncode == 0, ok.stderr
        assert ok.stdout == "9 hihi\n"
        failed = subprocess.run([SERVICE_PEER, "call", "-4", "5", "yo"], capture_output=True,
                                text=True, timeout=60)
        assert failed.stdout == "error:the handler raised: ValueError: negative a: -4 yoyo\n"


def test_a_killed_python_server_is_a_transport_error_not_a_hang():
    child = python_child(textwrap.dedent("""
        import threading, horus
        from pyrt_test import Add, AddResponse
        gate = threading.Event()
        server = horus.ServiceServer(Add, lambda req: (gate.wait(), AddResponse())[1])
        print("serving", flush=True)
        gate.wait()
    """))
    assert child.stdout.readline().strip() == "serving"
    client = horus.ServiceClient(Add)
    future = client.call_async(AddRequest(a=1, b=2), timeout=30.0)
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    with pytest.raises(horus.TransportError, match="died"):
        future.result(timeout=30)
    client.close()
