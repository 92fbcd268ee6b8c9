"""The tensor pool and the types that live in it: Image, DepthImage, PointCloud, Tensor.

Their data stays in a shared-memory pool (runtime/src/pool/README.md); a topic of them sends only
a descriptor. `numpy.asarray(value)` and `value.__dlpack__()` give the pool memory itself (no
copy), read-only for a received value (DLPack says so in the versioned capsule a consumer asking
for 1.0 gets); `Image.from_numpy(a)` copies `a` once into the pool.
`horus.Topic(Image, name)` opens a PoolTopic.
"""
from __future__ import annotations

from . import _core
from ._topic import _wait_for

Image = _core.Image
DepthImage = _core.DepthImage
PointCloud = _core.PointCloud
Tensor = _core.Tensor
TensorPool = _core.TensorPool
PoolExhaustion = _core.PoolExhaustion
ImageEncoding = _core.ImageEncoding
TensorDtype = _core.TensorDtype

_CORE_TOPICS = {
    Image: _core.ImageTopic,
    DepthImage: _core.DepthImageTopic,
    PointCloud: _core.PointCloudTopic,
    Tensor: _core.TensorTopic,
}


def is_pool_type(value_type) -> bool:
    return value_type in _CORE_TOPICS


class PoolTopic:
    """A topic of Image, DepthImage, PointCloud or Tensor: the descriptor goes, the data stays.

    The ring's `capacity` (4 by default) is also how many frames a sender keeps alive for
    subscribers that have not taken them yet; `refused()` counts descriptors whose block was
    freed or reused since (e.g. dropped by the sender's PoolExhaustion.DropOldest), or that
    name another pool.
    """

    def __init__(self, value_type, name: str, *, capacity: int = 4, namespace: str = "") -> None:
        if value_type not in _CORE_TOPICS:
            raise TypeError(f"PoolTopic carries Image, DepthImage, PointCloud or Tensor, not {value_type!r}")
        self.type = value_type
        self._core = _CORE_TOPICS[value_type](name, capacity, namespace)

    @property
    def name(self) -> str:
        return self._core.name

    @property
    def capacity(self) -> int:
        return self._core.capacity

    def send(self, value) -> bool:
        """Publishes the descriptor of `value`; never blocks. False when nothing was published."""
        if not isinstance(value, self.type):
            raise TypeError(f"topic '{self.name}' carries {self.type.__name__}, not {type(value).__name__}")
        return self._core.send(value)

    def try_recv(self):
        """The next value, or None."""
        return self._core.try_recv()

    def recv(self, timeout: float | None = None):
        """The next value, waiting up to `timeout` seconds (None: until one comes) with the GIL
        released; None on timeout."""
        return _wait_for(self._core.recv, timeout)

    def read_latest(self):
        """The newest value sent on the topic if its block still holds it, or None."""
        return self._core.read_latest()

    def has_msg(self) -> bool:
        return self._core.has_msg()

    def lost(self) -> int:
        return self._core.lost()

    def refused(self) -> int:
        return self._core.refused()

    def __repr__(self) -> str:
        return f"horus.Topic({self.type.__name__}, {self.name!r})"
