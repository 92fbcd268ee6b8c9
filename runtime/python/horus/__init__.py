"""HORUS: the Python runtime (seed 001's API) over the C++ core.

`horus` shares its name with the generated message packages (`horus.msg`, installed in another
folder of sys.path), so the package path is extended to every `horus/` folder on sys.path.
"""
import sys
from importlib.util import find_spec
from pkgutil import extend_path

__path__ = extend_path(__path__, __name__)


def _check_dependencies() -> None:
    # Messages need them only on first use, deep inside a node's callback: said here instead.
    # Looked up, not imported: numpy alone would double the import time.
    for name in ("numpy", "msgpack"):
        try:
            found = find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            raise ImportError(
                f"horus needs numpy and msgpack, and {sys.executable} finds no {name}: install "
                "Debian's python3-numpy and python3-msgpack (apt install python3-numpy "
                "python3-msgpack) and run Debian's /usr/bin/python3", name=name)


_check_dependencies()

from ._action import (  # noqa: E402
    ActionClient, ActionServer, ActionServerStats, CancelCode, GoalHandle, GoalId, GoalResult,
    GoalState, ServerGoal)
from ._core import HorusError  # noqa: E402
from ._core import budget_remaining, dt, elapsed, now, rng_float, tick, timestamp_now  # noqa: E402
from ._frames import (  # noqa: E402
    DisconnectedFramesError, ExtrapolationError, FrameAuthorityError, FrameCapacityError,
    FrameCycleError, FrameError, FrameInfo, FrameTree, InvalidTransformError, StaleFrameError,
    StampedTransform, Transform, UnknownFrameError, frame_tree_exists, remove_frame_tree,
    transform_point, transform_pose, transform_vector)
from ._network import Network  # noqa: E402
from ._node import Node  # noqa: E402
from ._params import (  # noqa: E402
    Param, ParamChange, ParamError, ParamInfo, Params, ParamSetResult, ParamValues, ParamVerdict,
    dump_params, load_params, param_nodes)
from ._scheduler import Scheduler, run  # noqa: E402
from ._service import (  # noqa: E402
    NoServerError, ServiceClient, ServiceError, ServiceFailed, ServiceServer, ServiceTimeout,
    TransportError)
from ._topic import Topic  # noqa: E402
from ._values import PlainValue, plain_value  # noqa: E402
from ._view import View  # noqa: E402
from ._pool import (  # noqa: E402
    DepthImage, Image, ImageEncoding, PointCloud, PoolExhaustion, PoolTopic, Tensor, TensorDtype,
    TensorPool)

us = 1e-6  # microseconds -> seconds: budget=300 * us
ms = 1e-3  # milliseconds -> seconds: deadline=5 * ms

__all__ = [
    "ActionClient", "ActionServer", "ActionServerStats", "CancelCode", "GoalHandle", "GoalId",
    "GoalResult", "GoalState", "ServerGoal",
    "HorusError", "Network", "Node", "NoServerError", "Param", "ParamChange", "ParamError",
    "ParamInfo", "Params", "ParamSetResult", "ParamValues", "ParamVerdict", "Scheduler", "ServiceClient", "ServiceError",
    "ServiceFailed", "ServiceServer", "ServiceTimeout", "Topic", "TransportError", "PlainValue",
    "View", "dump_params", "load_params", "param_nodes", "plain_value",
    "budget_remaining", "dt", "elapsed", "ms", "now", "rng_float", "run", "tick", "timestamp_now",
    "us",
    "DepthImage", "Image", "ImageEncoding", "PointCloud", "PoolExhaustion", "PoolTopic", "Tensor",
    "TensorDtype", "TensorPool",
    "DisconnectedFramesError", "ExtrapolationError", "FrameAuthorityError", "FrameCapacityError",
    "FrameCycleError", "FrameError", "FrameInfo", "FrameTree", "InvalidTransformError",
    "StaleFrameError", "StampedTransform", "Transform", "UnknownFrameError", "frame_tree_exists",
    "remove_frame_tree", "transform_point", "transform_pose", "transform_vector",
]
