"""horus.ServiceClient and horus.ServiceServer: generated services from Python, on the same
topics and frames as C++'s ServiceClient<S> / ServiceServer<S> (horus/detail/service_frame.hpp),
so either side may be C++ or Python."""
from __future__ import annotations

import concurrent.futures
import itertools
import os
import random
import struct
import threading
import time

from . import _core
from ._values import _fnv1a

_CHECK_INTERVAL = 0.010  # as kServerCheckInterval: how late a dead server is noticed at worst
_IDLE_WAKE = 0.2  # how often an idle server thread looks at its stop flag
# A frame's status (horus/detail/service_frame.hpp): a handler's answer is OK or FAILED; a
# forwarding server (ServiceServer(forward_errors=True)) answers with its own call's error kind.
_STATUS_OK, _STATUS_FAILED = 0, 1
_POD_ERROR_CAPACITY = 236
_MAX_REPLY_COLLISIONS = 8
_REGISTRATION = struct.Struct("<QQ256s256sQ")
_ids = itertools.count(1)
_picking = threading.Lock()


class ServiceError(RuntimeError):
    """A call that got no answer; `kind` is 'no_server', 'timeout', 'transport' or
    'service_failed' (the server's handler reported an error)."""

    kind = "transport"


class NoServerError(ServiceError):
    kind = "no_server"


class ServiceTimeout(ServiceError, TimeoutError):
    kind = "timeout"


class TransportError(ServiceError):
    kind = "transport"


class ServiceFailed(ServiceError):
    kind = "service_failed"


_STATUS_OF_KIND = {"service_failed": _STATUS_FAILED, "no_server": 2, "timeout": 3, "transport": 4}
_ERROR_OF_STATUS = {_STATUS_OF_KIND[error.kind]: error
                    for error in (ServiceFailed, NoServerError, ServiceTimeout, TransportError)}


def _align(value: int, alignment: int) -> int:
    return (value + alignment - 1) // alignment * alignment


class _Frame:
    """The identity and layout of ServiceRequestFrame<T> / ServiceResponseFrame<T>."""

    def __init__(self, payload_type, response: bool) -> None:
        meta = payload_type.__horus__
        self.payload_type = payload_type
        self.is_pod = bool(meta.is_pod)
        opener = "horus.ServiceResponse<" if response else "horus.ServiceRequest<"
        self.name = f"{opener}{meta.name}>"
        if response:
            error = "string<236>" if self.is_pod else "String"
            fields = f" {{\n  client_id: u64,\n  request_id: u64,\n  status: u32,\n  error: {error},\n  payload: "
        else:
            fields = " {\n  client_id: u64,\n  request_id: u64,\n  reply_to: u64,\n  payload: "
        self.schema = f"message {self.name}{fields}{meta.name},\n}}\n{meta.schema}"
        self.fingerprint = _fnv1a(self.schema)
        self.alignment = max(8, meta.alignment) if self.is_pod else 1
        header = 8 + 8 + 4 + _POD_ERROR_CAPACITY if response else 24
        if self.is_pod:
            self.payload_offset = _align(header, meta.alignment)
            self.size = _align(self.payload_offset + meta.size, self.alignment)
        else:
            self.payload_offset = self.size = 0

    def open(self, name: str) -> "_core.Topic":
        return _core.Topic(name, self.name, self.fingerprint, self.schema, self.is_pod, self.size,
                           self.alignment, 64, 16 * 1024, False)

    # A POD frame is the C++ struct's bytes; a serialized one is MessagePack
    # [ids..., payload], the payload being the message's own encoding.
    def pack(self, head: tuple, payload) -> bytes:
        body = payload.to_bytes()
        if self.is_pod:
            out = bytearray(self.size)
            if len(head) == 3:
                struct.pack_into("<QQQ", out, 0, *head)
            else:
                error = head[3].encode()[:_POD_ERROR_CAPACITY]
                struct.pack_into("<QQI", out, 0, *head[:3])
                out[20:20 + len(error)] = error
            out[self.payload_offset:self.payload_offset + len(body)] = body
            return bytes(out)
        msgpack = _msgpack()
        return b"".join([_array_header(len(head) + 1),
                         *(msgpack.packb(v, use_bin_type=True) for v in head), body])

    def unpack(self, data: bytes, fields: int):
        """(head values, payload message) of a frame with `fields` values before the payload."""
        if self.is_pod:
            if fields == 3:
                head = struct.unpack_from("<QQQ", data, 0)
            else:
                cid, rid, status = struct.unpack_from("<QQI", data, 0)
                head = (cid, rid, status, data[20:256].split(b"\0", 1)[0].decode("utf-8", "replace"))
            body = data[self.payload_offset:self.payload_offset + self.payload_type.__horus__.size]
            return head, self.payload_type.from_bytes(body)
        unpacker = _msgpack().Unpacker(raw=False)
        unpacker.feed(data)
        if unpacker.read_array_header() != fields + 1:
            raise ValueError(f"{self.name}: not a frame of {fields + 1} fields")
        head = tuple(unpacker.unpack() for _ in range(fields))
        return head, self.payload_type.from_bytes(data[unpacker.tell():])


def _array_header(n: int) -> bytes:
    return bytes([0x90 | n])


def _msgpack():
    import msgpack  # python3-msgpack, only for serialized services

    return msgpack


def _endpoint_id() -> int:
    return (os.getpid() << 32) | next(_ids)


def _registration_topic(service) -> "_core.Topic":
    text = ("message horus.ServiceRegistration {\n  server_instance: u64,\n  fingerprint: u64,\n"
            "  request_type: string<256>,\n  response_type: string<256>,\n  server_pid: u64,\n}\n")
    return _core.Topic(f"{service.name}.service", "horus.ServiceRegistration", _fnv1a(text), text,
                       True, _REGISTRATION.size, 8, 4, 16 * 1024, False)


def _registration(topic) -> tuple | None:
    """(server_instance, server_pid) of the latest registration, or None."""
    data = topic.read_latest()
    if data is None:
        return None
    instance, _fingerprint, _req, _res, pid = _REGISTRATION.unpack(data)
    return instance, pid


def _announced_use(role: str, service) -> "_core.AnnouncedUse":
    """The server or client in this process's presence announcement (horus/presence.hpp)."""
    return _core.AnnouncedUse(role, service.name, service.Request.__horus__.name,
                              service.Response.__horus__.name)


def _alive(pid: int) -> bool:
    if pid == 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rsplit(b")", 1)[1].split()[0] not in (b"Z", b"X")
    except (OSError, IndexError):
        return False


class ServiceClient:
    """Calls a generated service's server (C++ or Python, in any process).

    `call(request, timeout)` blocks (the GIL released while waiting) and returns the response or
    raises a ServiceError; `call_async` returns a concurrent.futures.Future. A client is used by
    one thread at a time, like a Topic (call_async runs on the client's own worker thread).
    """

    def __init__(self, service) -> None:
        self.service = service
        self._request = _Frame(service.Request, response=False)
        self._response = _Frame(service.Response, response=True)
        self._requests = self._request.open(service.request_topic)
        self._reply_index, self._responses = self._open_reply_topic()
        self._registration_topic = _registration_topic(service)
        self._announced = _announced_use("client", service)
        self.client_id = _endpoint_id()
        self._last_request = 0
        self._executor = None
        self._lock = threading.Lock()

    def _open_reply_topic(self):
        prefix = f"{self.service.response_topic}."
        with _picking:
            for attempt in itertools.count():
                taken = set()
                for topic in _core.list_topics(""):
                    suffix = topic["name"][len(prefix):]
                    if topic["subscribers"] and topic["name"].startswith(prefix) and suffix.isdigit():
                        taken.add(int(suffix))
                index = next(i for i in itertools.count() if i not in taken)
                name = f"{prefix}{index}"
                replies = self._response.open(name)
                replies.try_recv()  # marks the handle a subscriber: the index is taken
                users = next((t["subscribers"] for t in _core.list_topics("") if t["name"] == name), 0)
                if attempt >= _MAX_REPLY_COLLISIONS or users <= 1:
                    return index, replies
                time.sleep(random.uniform(0.0001, 0.002))

    def _live_server(self) -> int:
        current = _registration(self._registration_topic)
        if current is None or current[1] == 0:
            raise NoServerError(f"no server for {self.service.name} in namespace "
                                f"{_core.current_namespace()}")
        if not _alive(current[1]):
            raise TransportError(f"the server of {self.service.name} (pid {current[1]}) died")
        return current[0]

    def wait_for_server(self, timeout: float) -> bool:
        """Waits up to `timeout` seconds for a live server; False if none came."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                self._live_server()
                return True
            except ServiceError:
                pass
            now = time.monotonic()
            if now >= deadline:
                return False
            self._registration_topic.recv(min(deadline - now, _CHECK_INTERVAL))

    def call(self, request, timeout: float = 1.0):
        """The server's response to `request`, waiting up to `timeout` seconds."""
        with self._lock:
            return self._call(request, timeout)

    def _call(self, request, timeout: float):
        if not isinstance(request, self.service.Request):
            raise TypeError(f"{self.service.name} takes a {self.service.Request.__name__}, "
                            f"not {type(request).__name__}")
        deadline = time.monotonic() + timeout
        instance = self._live_server()
        self._last_request += 1
        request_id = self._last_request
        frame = self._request.pack((self.client_id, request_id, self._reply_index), request)
        if not self._requests.send(frame):
            raise TransportError(f"the request topic {self.service.request_topic} refused the "
                                 "request (too large for its slots, or a stalled publisher)")
        next_check = time.monotonic() + _CHECK_INTERVAL
        while True:
            now = time.monotonic()
            if now >= deadline:
                raise ServiceTimeout(f"no answer from {self.service.name} in time")
            if now >= next_check:
                self._check_server(instance)
                next_check = now + _CHECK_INTERVAL
            data = self._responses.recv(max(0.0, min(deadline, next_check) - now))
            if data is None:
                continue
            (client_id, answered, status, error), payload = self._response.unpack(data, 4)
            if client_id != self.client_id or answered != request_id:
                continue  # a stale answer to a call that timed out
            if status != _STATUS_OK:
                raise _ERROR_OF_STATUS.get(status, ServiceFailed)(error)
            return payload

    def _check_server(self, instance: int) -> None:
        current = _registration(self._registration_topic)
        name = self.service.name
        if current is None or current[1] == 0:
            raise TransportError(f"the server of {name} stopped before answering")
        if current[0] != instance:
            raise TransportError(f"the server of {name} was restarted; the request was lost")
        if not _alive(current[1]):
            raise TransportError(f"the server of {name} (pid {current[1]}) died before answering")

    def call_async(self, request, timeout: float = 1.0) -> concurrent.futures.Future:
        """call() on the client's worker thread: a Future of the response (or the ServiceError);
        `await asyncio.wrap_future(f)` from asyncio code."""
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(
                max_workers=1, thread_name_prefix=f"horus-{self.service.name}")
        return self._executor.submit(self.call, request, timeout)

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None
        self._announced.close()

    def __enter__(self) -> "ServiceClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ServiceServer:
    """Serves a generated service with `handler(request) -> response` on a thread of its own;
    an exception from the handler is the client's ServiceFailed with its text; with
    `forward_errors`, a ServiceError the handler raises reaches the client as its own kind (a
    handler that forwards each call to another server: the DDS bridge's stand-in for a remote
    service). Registering fails
    (HorusError) while another live server serves the service. stop() (or leaving a `with`
    block) finishes the request in hand and withdraws the registration."""

    def __init__(self, service, handler, forward_errors: bool = False) -> None:
        if not callable(handler):
            raise TypeError(f"ServiceServer({service.name}) needs a callable handler")
        self.service = service
        self._handler = handler
        self._forward_errors = forward_errors
        self._request = _Frame(service.Request, response=False)
        self._response = _Frame(service.Response, response=True)
        self._incoming = self._request.open(service.request_topic)
        self._registration_topic = _registration_topic(service)
        self._replies: dict[int, object] = {}
        self.instance = _endpoint_id()
        self.requests = self.failures = 0
        current = _registration(self._registration_topic)
        if current is not None and current[1] != 0 and _alive(current[1]):
            raise _core.HorusError(f"service {service.name} in namespace "
                                   f"{_core.current_namespace()} already has a server "
                                   f"(pid {current[1]})")
        self._publish_registration(self.instance, os.getpid())
        self._announced = _announced_use("server", service)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"horus-{service.name}",
                                        daemon=True)
        self._thread.start()

    def _publish_registration(self, instance: int, pid: int) -> None:
        record = _REGISTRATION.pack(instance, self.service.fingerprint,
                                    self.service.Request.__horus__.name.encode(),
                                    self.service.Response.__horus__.name.encode(), pid)
        if not self._registration_topic.send(record):
            raise _core.HorusError(f"service {self.service.name}: cannot publish its registration")

    def _serve(self) -> None:
        while not self._stopping.is_set():
            data = self._incoming.recv(_IDLE_WAKE)
            if data is None:
                continue
            (client_id, request_id, reply_to), request = self._request.unpack(data, 3)
            if client_id == 0:
                continue  # stop()'s wake-up
            self._answer(client_id, request_id, reply_to, request)

    def _answer(self, client_id: int, request_id: int, reply_to: int, request) -> None:
        status, error, response = _STATUS_OK, "", None
        try:
            response = self._handler(request)
            if not isinstance(response, self.service.Response):
                raise TypeError(f"the handler returned {type(response).__name__}, not "
                                f"{self.service.Response.__name__}")
        except Exception as failure:  # noqa: BLE001 - every failure goes back to the caller
            if self._forward_errors and isinstance(failure, ServiceError):
                status, error = _STATUS_OF_KIND[failure.kind], str(failure)
            else:
                status = _STATUS_FAILED
                error = f"the handler raised: {type(failure).__name__}: {failure}"
            response = self.service.Response()
            self.failures += 1
        self.requests += 1
        replies = self._replies.get(reply_to)
        if replies is None:
            replies = self._replies[reply_to] = self._response.open(
                f"{self.service.response_topic}.{reply_to}")
        frame = self._response.pack((client_id, request_id, status, error), response)
        if not replies.send(frame):
            failure = self._response.pack(
                (client_id, request_id, _STATUS_FAILED,
                 f"the response does not fit in a slot of {self.service.response_topic}.{reply_to}"),
                self.service.Response())
            replies.send(failure)

    def stop(self) -> None:
        if self._stopping.is_set():
            return
        self._stopping.set()
        self._incoming.send(self._request.pack((0, 0, 0), self.service.Request()))
        if self._thread is not threading.current_thread():
            self._thread.join()
        current = _registration(self._registration_topic)
        if current is not None and current[0] == self.instance:
            self._publish_registration(0, 0)
        self._announced.close()

    def __enter__(self) -> "ServiceServer":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def __del__(self) -> None:
        if hasattr(self, "_stopping"):
            self.stop()
