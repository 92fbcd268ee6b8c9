"""horus.Topic: a typed (or dict) handle on a shared-memory topic, the same segment C++ opens."""
from __future__ import annotations

import math
import sys

from . import _core

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


class Topic:
    """One handle on the topic `name`, carrying `msg_type` (a generated message class) or `dict`.

    With `dict`, messages are plain values (dicts, lists, numbers, strings) carried as
    `horus.msg.GenericMessage`, so a C++ `Topic<GenericMessage>` reads them. Opening a topic that
    carries another type raises `horus.HorusError` naming both types and fingerprints.
    """

    def __new__(cls, msg_type=None, *args, **options):
        # Image, DepthImage, PointCloud and Tensor send a descriptor of pool memory instead.
        from ._pool import PoolTopic, is_pool_type

        if is_pool_type(msg_type):
            return PoolTopic(msg_type, *args, **options)
        return super().__new__(cls)

    def __init__(self, msg_type, name: str, *, capacity: int = 64,
                 max_message_size: int = 16 * 1024, single_publisher: bool = False) -> None:
        self._values = msg_type is dict
        self.type = _generic_message() if self._values else msg_type
        meta = getattr(self.type, "__horus__", None)
        if meta is None:
            raise TypeError(f"horus.Topic needs a generated message class or dict, got {msg_type!r}")
        self._pod = bool(meta.is_pod)
        self._core = _core.Topic(name, meta.name, meta.fingerprint, meta.schema, self._pod,
                                 meta.size if self._pod else 0, meta.alignment if self._pod else 1, capacity,
                                 max_message_size, single_publisher)
        self._decode = self.type.from_bytes
        self._encode = _values_encoder(self.type) if self._values else _typed_encoder(name, self.type)
        self._loan_view = None
        self._loan_buffer = None
        layout = _scalar_layout(self.type) if self._pod else None
        if layout is not None:
            # send() and try_recv() in C for the messages most often sent at high rates (CmdVel
            # and the like): the same bytes, values and errors, a fraction of the cost (see
            # bench/python/RESULTS.md). Instance attributes, so a call is one C call.
            fast = _core.pod_fast_path(self._core, self.type, meta.size, layout, self._encode)
            if fast is not None:  # None: a class (a user's subclass) that keeps fields otherwise
                self.send, self.try_recv = fast.send, fast.try_recv

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
        if not self._pod:
            raise TypeError(f"topic '{self.name}' carries {self.type.__horus__.name}, "
                            "a serialized type: only POD messages can be written in place")
        self._release_view()
        self._loan_buffer = self._core.loan()
        self._loan_view = self.type.view(self._loan_buffer)
        return self._loan_view

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
