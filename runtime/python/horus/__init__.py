"""HORUS: the Python runtime (seed 001's API) over the C++ core.

`horus` shares its name with the generated message packages (`horus.msg`, installed in another
folder of sys.path), so the package path is extended to every `horus/` folder on sys.path.
"""
from pkgutil import extend_path

__path__ = extend_path(__path__, __name__)

from ._core import HorusError  # noqa: E402
from ._core import budget_remaining, dt, elapsed, now, rng_float, tick  # noqa: E402
from ._network import Network  # noqa: E402
from ._node import Node  # noqa: E402
from ._scheduler import Scheduler, run  # noqa: E402
from ._service import (  # noqa: E402
    NoServerError, ServiceClient, ServiceError, ServiceFailed, ServiceServer, ServiceTimeout,
    TransportError)
from ._topic import Topic  # noqa: E402
from ._pool import (  # noqa: E402
    DepthImage, Image, ImageEncoding, PointCloud, PoolExhaustion, PoolTopic, Tensor, TensorDtype,
    TensorPool)

us = 1e-6  # microseconds -> seconds: budget=300 * us
ms = 1e-3  # milliseconds -> seconds: deadline=5 * ms

__all__ = [
    "HorusError", "Network", "Node", "NoServerError", "Scheduler", "ServiceClient", "ServiceError",
    "ServiceFailed", "ServiceServer", "ServiceTimeout", "Topic", "TransportError",
    "budget_remaining", "dt", "elapsed", "ms", "now", "rng_float", "run", "tick", "us",
    "DepthImage", "Image", "ImageEncoding", "PointCloud", "PoolExhaustion", "PoolTopic", "Tensor",
    "TensorDtype", "TensorPool",
]
