"""horus.ServiceClient and horus.ServiceServer: generated services from Python. They bind the
C++ byte-level services (horus/raw_service.hpp) and only turn bytes into messages and failures
into exceptions, so the frames, registrations and timing rules are C++'s own and either side of a
call may be C++ or Python (the wire format: runtime/src/service/README.md)."""
from __future__ import annotations

import concurrent.futures
import threading

from . import _core

_IDLE_WAKE = 0.2  # how often an idle server thread looks at its stop flag (stop() wakes it too)


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


# Each error's `kind` as the name of the C++ kind it stands for (horus::ServiceErrorKind).
_CPP_KIND = {"service_failed": "ServiceFailed", "no_server": "NoServer", "timeout": "Timeout",
             "transport": "Transport"}
_ERROR_OF_KIND = {_CPP_KIND[error.kind]: error
                  for error in (ServiceFailed, NoServerError, ServiceTimeout, TransportError)}


class ServiceClient:
    """Calls a generated service's server (C++ or Python, in any process).

    `call(request, timeout)` blocks (the GIL released while waiting) and returns the response or
    raises a ServiceError; `call_async` returns a concurrent.futures.Future. A client is used by
    one thread at a time, like a Topic (call_async runs on the client's own worker thread).
    """

    def __init__(self, service) -> None:
        self.service = service
        self._raw = _core.ServiceClient(service)
        self.client_id = self._raw.client_id
        self._executor = None
        self._lock = threading.Lock()

    def _client(self) -> "_core.ServiceClient":
        # After close() a call opens the service's topics again.
        if self._raw is None:
            self._raw = _core.ServiceClient(self.service)
            self.client_id = self._raw.client_id
        return self._raw

    def wait_for_server(self, timeout: float) -> bool:
        """Waits up to `timeout` seconds for a live server; False if none came."""
        with self._lock:  # the C++ client is used by one thread at a time
            return self._client().wait_for_server(timeout)

    def call(self, request, timeout: float = 1.0):
        """The server's response to `request`, waiting up to `timeout` seconds."""
        if not isinstance(request, self.service.Request):
            raise TypeError(f"{self.service.name} takes a {self.service.Request.__name__}, "
                            f"not {type(request).__name__}")
        data = request.to_bytes()
        with self._lock:
            failure, answer = self._client().call(data, timeout)
        if failure is not None:
            raise _ERROR_OF_KIND[failure](answer)
        return self.service.Response.from_bytes(answer)

    def call_async(self, request, timeout: float = 1.0) -> concurrent.futures.Future:
        """call() on the client's worker thread: a Future of the response (or the ServiceError);
        `await asyncio.wrap_future(f)` from asyncio code."""
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(
                max_workers=1, thread_name_prefix=f"horus-{self.service.name}")
        return self._executor.submit(self.call, request, timeout)

    def close(self) -> None:
        """Finishes the pending async calls and closes the service's topics (the client then
        leaves this process's announcement)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None
        with self._lock:
            self._raw = None

    def __enter__(self) -> "ServiceClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ServiceServer:
    """Serves a generated service with `handler(request) -> response` on a thread of its own;
    an exception from the handler is the client's ServiceFailed with its text; with
    `forward_errors`, a ServiceError the handler raises reaches the client as its own kind (a
    handler that forwards each call to another server: the DDS bridge's stand-in for a remote
    service). Registering fails (HorusError) while another live server serves the service.
    stop() (or leaving a `with` block) finishes the request in hand and withdraws the
    registration."""

    def __init__(self, service, handler, forward_errors: bool = False) -> None:
        if not callable(handler):
            raise TypeError(f"ServiceServer({service.name}) needs a callable handler")
        self.service = service
        self._handler = handler
        self._forward_errors = forward_errors
        self.requests = self.failures = 0
        self._raw = _core.ServiceServer(service)
        self.instance = self._raw.instance
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"horus-{service.name}",
                                        daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stopping.is_set():
            request = self._raw.next(_IDLE_WAKE)
            if request is not None:
                self._answer(*request)

    def _answer(self, caller, data: bytes) -> None:
        try:
            response = self._handler(self.service.Request.from_bytes(data))
            if not isinstance(response, self.service.Response):
                raise TypeError(f"the handler returned {type(response).__name__}, not "
                                f"{self.service.Response.__name__}")
            answer = response.to_bytes()
        except Exception as failure:  # noqa: BLE001 - every failure goes back to the caller
            if self._forward_errors and isinstance(failure, ServiceError):
                kind, text = _CPP_KIND[failure.kind], str(failure)
            else:
                kind = "ServiceFailed"
                text = f"the handler raised: {type(failure).__name__}: {failure}"
            self.failures += 1
            self.requests += 1
            self._raw.fail(caller, kind, text)
            return
        self.requests += 1
        self._raw.answer(caller, answer)

    def stop(self) -> None:
        if self._stopping.is_set():
            return
        self._stopping.set()
        self._raw.stop()
        if self._thread is not threading.current_thread():
            self._thread.join()
        self._raw.withdraw()

    def __enter__(self) -> "ServiceServer":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def __del__(self) -> None:
        if hasattr(self, "_thread"):
            self.stop()
