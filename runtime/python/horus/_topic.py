"""horus.Topic: a typed (or dict) handle on a shared-memory topic, the same segment C++ opens."""
from __future__ import annotations

import math
import sys

from . import _core
from ._values import plain_value_of

_FOREVER_SLICE = 0.1  # a wait without timeout wakes this often to let Ctrl+C through


def _wait_for(receive, timeout: float | None):
    """What `receive(seconds)` returns within `timeout` seconds (None or inf: however long it
    takes, asked in slices so Ctrl+C gets through), or None on timeout."""
    if timeout is not None and (not math.isfinite(timeout) or timeout < 0):
        if timeout != math.inf:
            raise ValueError(f"timeout must be None or seconds >= 0, got {timeout!r}")
        timeout = None
    while True:
        value = receive(_FOREVER_SLICE if timeout is None else timeout)
        if value is not None or timeout is not None:
            return value


def _generic_message():
    from horus.msg import GenericMessage  # generated; imported only when a dict topic is used

    # Its codec imports msgpack on first use: as the topic opens (a node's init()), not in the
    # first tick that sends, where the import would hold the GIL that other nodes' ticks need.
    GenericMessage.from_value(None).to_value()
    return GenericMessage


def _typed_encoder(name: str, msg_type):
    """msg -> the bytes a topic carrying `msg_type` sends (a closure: no reference to the Topic,
    so the C fast path can hold it without a cycle)."""
    def encode(msg) -> bytes:
        if not isinstance(msg, msg_type):
            raise TypeError(f"topic '{name}' carries {msg_type.__horus__.name}, "
                            f"not {type(msg).__name__}")
        return msg.to_bytes()
    return encode


def _plain_encoder(name: str, value_type):
    to_bytes = value_type.to_bytes

    def encode(value) -> bytes:
        try:
            return to_bytes(value)
        except ValueError as error:
            raise ValueError(f"topic '{name}' carries {error}") from None
    return encode


def _values_encoder(generic_message):
    def encode(value) -> bytes:
        return generic_message.from_value(value).to_bytes()
    return encode


def _scalar_layout(msg_type):
    """[(field, struct format, offset)] when every field of the POD class `msg_type` is a plain
    integer, float or bool (what _core.pod_fast_path handles); None otherwise."""
    meta = msg_type.__horus__
    support = sys.modules.get(type(meta).__module__)  # the support module the class was made with
    scalar = tuple(getattr(support, name, None) for name in ("Int", "Float", "Bool"))
    if None in scalar or not meta.fields:
        return None
    layout = []
    for name, codec, offset in zip(meta.fields, meta.codecs, meta.offsets):
        if type(codec) not in scalar:
            return None
        layout.append((name, codec.fmt, offset))
    return layout


def _summary(value) -> str:
    """The log line's text for a message: its log_summary(), or for a dict topic's value the text
    horus/log_summary.hpp's rules give it (numbers, true/false, "text", short lists)."""
    log_summary = getattr(value, "log_summary", None)
    if log_summary is not None:
        return log_summary()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "%g" % value
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (bytes, bytearray, memoryview)):
        return f"<{len(value)} bytes>"
    if value is None:
        return "none"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{key}: {_summary(item)}" for key, item in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        if numbers and len(value) > 8:
            return (f"[{len(value)} x {type(value[0]).__name__}, min {_summary(min(value))}, "
                    f"max {_summary(max(value))}]")
        if not numbers and len(value) > 4:
            return f"[{len(value)} x {type(value[0]).__name__}]"
        return "[" + ", ".join(_summary(v) for v in value) + "]"
    return repr(value)


class Topic:
    """One handle on the topic `name`, carrying `msg_type` (a generated message class), a plain
    value type or `dict`.

    A plain value type (float, int, bool, str, bytes, a schema spelling such as "f32" or
    "[f32; 3]", a numpy dtype: horus.plain_value) carries values as a C++ `Topic<double>`,
    `Topic<std::string>`, `Topic<std::array<float, 3>>` does. With `dict`, messages are dicts,
    lists, numbers and strings carried as `horus.msg.GenericMessage`, so a C++
    `Topic<GenericMessage>` reads them. Opening a topic that carries another type raises
    `horus.HorusError` naming both types and fingerprints.

    `verbose=True` (or setting `verbose` later) logs each message this handle sends or receives
    in the runtime's log (`horus log`, the monitor), "<topic> send: <summary>", at most 10 lines
    a second and then a count of the lines suppressed, as a C++ `TopicOptions::verbose` does.
    """

    def __new__(cls, msg_type=None, *args, **options):
        # Image, DepthImage, PointCloud and Tensor send a descriptor of pool memory instead.
        from ._pool import PoolTopic, is_pool_type

        if is_pool_type(msg_type):
            return PoolTopic(msg_type, *args, **options)
        return super().__new__(cls)

    def __init__(self, msg_type, name: str, *, capacity: int = 64,
                 max_message_size: int = 16 * 1024, single_publisher: bool = False,
                 verbose: bool = False) -> None:
        plain = plain_value_of(msg_type)
        self._values = msg_type is dict
        self._plain = plain is not None
        self.type = plain if self._plain else _generic_message() if self._values else msg_type
        meta = getattr(self.type, "__horus__", None)
        if meta is None:
            raise TypeError("horus.Topic needs a generated message class, a plain value type "
                            f"(float, int, bool, str, bytes, 'f32', '[f32; 3]', ...) or dict, got {msg_type!r}")
        self._pod = bool(meta.is_pod)
        self._core = _core.Topic(name, meta.name, meta.fingerprint, meta.schema, self._pod,
                                 meta.size if self._pod else 0, meta.alignment if self._pod else 1, capacity,
                                 max_message_size, single_publisher,
                                 meta.description)
        self._decode = self.type.from_bytes
        self._encode = (_plain_encoder(name, plain) if self._plain else _values_encoder(self.type)
                        if self._values else _typed_encoder(name, self.type))
        self._loan_view = None
        self._loan_buffer = None
        self._log = None
        self._fast = None
        layout = _scalar_layout(self.type) if self._pod and not self._plain else None
        if layout is not None:
            # send() and try_recv() in C for the messages most often sent at high rates (CmdVel
            # and the like): the same bytes, values and errors, a fraction of the cost (see
            # bench/python/RESULTS.md). Instance attributes, so a call is one C call.
            # None: a class (a user's subclass) that keeps fields otherwise.
            self._fast = _core.pod_fast_path(self._core, self.type, meta.size, layout,
                                             self._encode)
        self.verbose = verbose

    @property
    def verbose(self) -> bool:
        """Whether this handle logs the messages it sends and receives."""
        return self._log is not None

    @verbose.setter
    def verbose(self, on: bool) -> None:
        for method in ("send", "try_recv", "recv"):
            self.__dict__.pop(method, None)
        if on:
            if self._log is None:
                self._log = _core.TopicLog(self.name)
            # Instance attributes over the class's methods: a quiet handle pays nothing for it.
            self.send, self.try_recv, self.recv = (self._send_logged, self._try_recv_logged,
                                                   self._recv_logged)
        else:
            self._log = None  # reports the lines it still counts as suppressed
            if self._fast is not None:
                self.send, self.try_recv = self._fast.send, self._fast.try_recv

    def _logged(self, sent: bool, msg) -> None:
        if msg is not None and self._log.admit():
            self._log.write(sent, self.type.log_summary(msg) if self._plain else _summary(msg))

    def _send_logged(self, msg) -> bool:
        sent = Topic.send(self, msg)
        if sent:
            self._logged(True, msg)
        return sent

    def _try_recv_logged(self, *, view: bool = False):
        msg = Topic.try_recv(self, view=view)
        self._logged(False, msg)
        return msg

    def _recv_logged(self, timeout: float | None = None, *, view: bool = False):
        msg = Topic.recv(self, timeout, view=view)
        self._logged(False, msg)
        return msg

    @property
    def name(self) -> str:
        return self._core.name

    def _message(self, data):
        if data is None:
            return None
        msg = self._decode(data)
        return msg.to_value() if self._values else msg

    def send(self, msg) -> bool:
        """Publishes `msg`; never blocks. False when nothing was published (see stats())."""
        return self._core.send(self._encode(msg))

    def try_recv(self, *, view: bool = False):
        """The next message, or None. `view=True` (POD types) gives a zero-copy view over this
        handle's receive buffer, valid until its next receive."""
        if view:
            return self._view(self._core.try_recv(view=True))
        return self._message(self._core.try_recv())

    def recv(self, timeout: float | None = None, *, view: bool = False):
        """The next message, waiting up to `timeout` seconds (None: until one comes) with the GIL
        released; None on timeout."""
        data = _wait_for(lambda seconds: self._core.recv(seconds, view=view), timeout)
        return self._view(data) if view else self._message(data)

    def _view(self, buffer):
        if buffer is None:
            return None
        self._check_message_type("views")
        if not self._pod:
            raise TypeError(f"topic '{self.name}' carries a serialized type; views need POD")
        return self.type.view(buffer)

    def read_latest(self):
        """The newest message ever sent on the topic, or None; does not move this handle."""
        return self._message(self._core.read_latest())

    def has_msg(self) -> bool:
        return self._core.has_msg()

    def lost(self) -> int:
        """Messages this handle lost by falling more than the capacity behind."""
        return self._core.lost()

    def stats(self) -> dict:
        return self._core.stats()

    @property
    def capacity(self) -> int:
        return self._core.capacity

    def loan(self):
        """A view of the next slot (POD types) to write in place; send it with publish()."""
        self._check_message_type("loans")
        if not self._pod:
            raise TypeError(f"topic '{self.name}' carries {self.type.__horus__.name}, "
                            "a serialized type: only POD messages can be written in place")
        self._release_view()
        self._loan_buffer = self._core.loan()
        self._loan_view = self.type.view(self._loan_buffer)
        return self._loan_view

    def _check_message_type(self, what: str) -> None:
        if self._plain:
            raise TypeError(f"topic '{self.name}' carries the plain value {self.type.name}: {what} "
                            "need a message type; send() and try_recv() take the value")

    def publish(self, loaned) -> bool:
        """Makes the loaned message visible; the view is unusable afterwards."""
        if loaned is not self._loan_view or self._loan_view is None:
            raise ValueError("publish() takes the view returned by this topic's last loan()")
        self._drop_view()
        return self._core.publish()

    def _drop_view(self) -> None:
        if self._loan_buffer is not None:
            # The view holds a memoryview of its own over the slot: released too, so a write
            # after publish() raises instead of changing a message subscribers may be reading.
            self._loan_view._horus_buf.release()
            self._loan_buffer.release()
            self._loan_buffer = None
            self._loan_view = None

    def _release_view(self) -> None:
        self._drop_view()
        self._core.release_loan()

    def __repr__(self) -> str:
        return f"horus.Topic({self.type.__horus__.name}, {self.name!r})"
