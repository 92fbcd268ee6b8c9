"""Coordinate frames: the namespace's transform tree in shared memory (horus/frames.hpp), which
every process of the namespace writes and reads directly.

Units: a stamp (a point in time) is integer nanoseconds since the Unix epoch, as
`horus.timestamp_now()` gives and C++ stamps are, so a stamp crosses languages exactly; a duration
(history, timeout, max_age, an error's `by`) is float seconds, as every other horus timeout.
Translations are (x, y, z) in metres and rotations unit quaternions (x, y, z, w), given as any
sequence of numbers or a numpy array.

    tree = horus.FrameTree()
    tree.set_static_transform("base_link", "lidar", (0.2, 0, 0.1))
    tree.set_transform("odom", "base_link", (x, y, 0), (0, 0, qz, qw), stamp)
    lidar_in_map = tree.lookup("map", "lidar", scan_stamp)
    cloud_in_map = horus.transform_point(lidar_in_map, cloud)   # an (N, 3) array
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple, Sequence

from . import _core
from ._core import (DisconnectedFramesError, ExtrapolationError, FrameAuthorityError,
                    FrameCapacityError, FrameCycleError, FrameError, InvalidTransformError,
                    StaleFrameError, UnknownFrameError)

__all__ = [
    "DisconnectedFramesError", "ExtrapolationError", "FrameAuthorityError", "FrameCapacityError",
    "FrameCycleError", "FrameError", "FrameInfo", "FrameTree", "InvalidTransformError",
    "StaleFrameError", "StampedTransform", "Transform", "UnknownFrameError", "frame_tree_exists",
    "remove_frame_tree", "transform_point", "transform_pose", "transform_vector",
]

Vector = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]
IDENTITY_ROTATION: Quaternion = (0.0, 0.0, 0.0, 1.0)


def _numbers(value: Any, count: int, what: str) -> tuple[float, ...]:
    try:
        numbers = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be {count} numbers, got {value!r}") from None
    if len(numbers) != count:
        raise ValueError(f"{what} must be {count} numbers, got {len(numbers)}: {value!r}")
    return numbers


def _stamp(value: Any, what: str = "a stamp") -> int:
    """An integer number of nanoseconds; a float is refused, since it is most likely seconds."""
    if isinstance(value, bool) or not hasattr(value, "__index__"):
        hint = (" (seconds? stamps are integer nanoseconds since the Unix epoch, as "
                "horus.timestamp_now() gives: multiply by 1e9 and round)"
                if isinstance(value, float) else "")
        raise TypeError(f"{what} must be integer nanoseconds, got {value!r}{hint}")
    return int(value.__index__())


def _optional_stamp(value: Any) -> int | None:
    return None if value is None else _stamp(value, "time")


def _seconds(value: Any, what: str) -> float:
    seconds = float(value)
    if not math.isfinite(seconds) or seconds < 0:
        raise ValueError(f"{what} must be a finite number of seconds >= 0, got {value!r}")
    return seconds


class Transform(NamedTuple):
    """A rigid transform: `rotation` applied first, then `translation`. As a frame's transform
    to its parent (what lookup returns for target <- source), it maps coordinates in the source
    frame to coordinates in the target. Unpacks as (translation, rotation)."""
    translation: Vector = (0.0, 0.0, 0.0)
    rotation: Quaternion = IDENTITY_ROTATION

    def inverse(self) -> Transform:
        return Transform(*_core.inverse_transform(*self))

    def compose(self, other: Transform) -> Transform:
        """`self` after `other`: target_T_source = target_T_middle.compose(middle_T_source)."""
        return Transform(*_core.compose_transforms(*self, *other))

    def interpolate(self, other: Transform, fraction: float) -> Transform:
        """Linear translation, spherical rotation; 0 gives `self`, 1 gives `other`."""
        return Transform(*_core.interpolate_transforms(*self, *other, float(fraction)))

    def as_matrix(self):
        """The 4x4 homogeneous matrix (a numpy array)."""
        import numpy
        matrix = numpy.eye(4)
        for column, axis in enumerate(((1, 0, 0), (0, 1, 0), (0, 0, 1))):
            matrix[:3, column] = transform_vector(self, axis)
        matrix[:3, 3] = self.translation
        return matrix


class StampedTransform(NamedTuple):
    """A transform of `child` (source) to `parent` (target) at `stamp` (ns since the epoch)."""
    parent: str
    child: str
    stamp: int
    transform: Transform


class FrameInfo(NamedTuple):
    """What FrameTree.frames() reports of one frame."""
    name: str
    parent: str | None  # None for a root (a frame only ever named as a parent)
    is_static: bool
    authority_pid: int  # 0: none (a root)
    authority_program: str
    authority_alive: bool
    oldest: int  # stamps (ns) of the oldest answerable and the newest entry; 0 without entries
    latest: int
    updates: int  # transforms ever written to the frame


def _stamped(row) -> StampedTransform:
    parent, child, stamp, (translation, rotation) = row
    return StampedTransform(parent, child, stamp, Transform(tuple(translation), tuple(rotation)))


def _transform(transform: Any) -> tuple[tuple[float, ...], tuple[float, ...]]:
    if isinstance(transform, StampedTransform):
        transform = transform.transform
    translation, rotation = transform
    return _numbers(translation, 3, "a translation"), _numbers(rotation, 4, "a rotation")


def _is_array(value: Any) -> bool:
    return hasattr(value, "__array_interface__") and getattr(value, "ndim", 1) == 2


def transform_point(transform: Transform | StampedTransform, point):
    """A point in the transform's source frame, in its target frame (rotated, then translated).
    A numpy array of shape (N, 3) (a point cloud) gives an (N, 3) float64 array, computed in C++
    with the GIL released; anything else three numbers and a tuple."""
    translation, rotation = _transform(transform)
    if _is_array(point):
        return _core.transform_points(translation, rotation, point)
    return _core.transform_point(translation, rotation, _numbers(point, 3, "a point"))


def transform_vector(transform: Transform | StampedTransform, vector):
    """A direction (a velocity, a normal): rotated only. (N, 3) arrays as in transform_point."""
    translation, rotation = _transform(transform)
    if _is_array(vector):
        return _core.transform_vectors(translation, rotation, vector)
    return _core.transform_vector(translation, rotation, _numbers(vector, 3, "a vector"))


def transform_pose(transform: Transform | StampedTransform, pose) -> Transform:
    """A pose (position, orientation) given in the transform's source frame, in its target."""
    translation, rotation = _transform(transform)
    position, orientation = _transform(pose)
    return Transform(*_core.transform_pose(translation, rotation, position, orientation))


def frame_tree_exists(namespace: str | None = None) -> bool:
    """Whether the namespace (None: the current one) has a frame tree; tools ask this to look
    without creating one (a tree's creator fixes its history duration)."""
    return _core.frame_tree_exists(namespace or "")


def remove_frame_tree(namespace: str | None = None) -> bool:
    """Removes the namespace's frame tree (None: the current one); whether there was one.
    Processes that have it open keep using their mapping."""
    return _core.remove_frame_tree(namespace or "")


class FrameTree:
    """One namespace's frame tree, opened (created when missing) in shared memory.

    A process is the authority of the child frames it sets: a second live process setting the
    same child gets FrameAuthorityError naming the first (a dead one's frames are taken over).
    Static transforms hold at every time and outlive their writer; dynamic ones keep `history`
    seconds (the tree's creator's choice) that lookups interpolate in. Lookups never block a
    writer. Errors are subclasses of FrameError.
    """

    def __init__(self, namespace: str | None = None, history: float = 10.0) -> None:
        history = _seconds(history, "history")
        if history == 0:
            raise ValueError("history must be above 0 seconds")
        self._tree = _core.FrameTree(namespace or "", history)

    def set_transform(self, parent: str, child: str, translation: Sequence[float],
                      rotation: Sequence[float] = IDENTITY_ROTATION,
                      stamp: int | None = None) -> None:
        """The transform of `child` to `parent` at `stamp` (ns; None: horus.timestamp_now()).
        A child's stamps must not go back. Raises InvalidTransformError (NaN, a rotation that is
        not a unit quaternion), FrameCycleError, FrameAuthorityError, FrameCapacityError."""
        stamp_ns = _core.timestamp_now() if stamp is None else _stamp(stamp)
        self._tree.set_transform(parent, child, _numbers(translation, 3, "a translation"),
                                 _numbers(rotation, 4, "a rotation"), stamp_ns)

    def set_static_transform(self, parent: str, child: str, translation: Sequence[float],
                             rotation: Sequence[float] = IDENTITY_ROTATION) -> None:
        """A transform that holds at every time (a sensor bolted to the base), kept after this
        process exits; setting it again replaces it."""
        self._tree.set_static_transform(parent, child, _numbers(translation, 3, "a translation"),
                                        _numbers(rotation, 4, "a rotation"))

    def lookup(self, target: str, source: str, time: int | None = None,
               max_age: float | None = None) -> Transform:
        """The transform taking coordinates in `source` to `target` at `time` (ns; None: the
        latest time every frame of the chain has), interpolated between the entries around it.
        `max_age` (seconds): every dynamic frame of the chain must have an entry newer than that
        (StaleFrameError). Raises ExtrapolationError, UnknownFrameError,
        DisconnectedFramesError."""
        return self.lookup_stamped(target, source, time, max_age).transform

    def lookup_stamped(self, target: str, source: str, time: int | None = None,
                       max_age: float | None = None) -> StampedTransform:
        """lookup() with the time the answer holds for (parent: target, child: source)."""
        age = None if max_age is None else _seconds(max_age, "max_age")
        return _stamped(self._tree.lookup_stamped(target, source, _optional_stamp(time), age))

    def can_lookup(self, target: str, source: str, time: int | None = None) -> bool:
        """Whether lookup() would answer (why_not() says why not)."""
        return self.why_not(target, source, time) is None

    def why_not(self, target: str, source: str, time: int | None = None) -> str | None:
        """None when lookup() would answer, else the message of the error it would raise."""
        return self._tree.why_not(target, source, _optional_stamp(time))

    def wait_for(self, target: str, source: str, time: int | None = None,
                 timeout: float = 1.0) -> bool:
        """Sleeps (woken by every write to the tree, no polling, GIL released) until lookup()
        can answer (True) or `timeout` seconds pass (False)."""
        return self._tree.wait_for(target, source, _optional_stamp(time),
                                   _seconds(timeout, "timeout"))

    def frames(self) -> list[FrameInfo]:
        """Every frame, in the order they were first named."""
        return [FrameInfo(name, parent or None, *rest)
                for name, parent, *rest in self._tree.frames()]

    def history(self, frame: str) -> list[StampedTransform]:
        """A frame's answerable entries, oldest first (one for a static frame)."""
        return [_stamped(row) for row in self._tree.history(frame)]

    def change_count(self) -> int:
        """Counts every write to the tree (wraps at 2**32)."""
        return self._tree.change_count()

    def wait_for_change(self, seen: int, timeout: float) -> int:
        """Sleeps while change_count() == seen, at most `timeout` seconds; the count then."""
        return self._tree.wait_for_change(seen, _seconds(timeout, "timeout"))

    @property
    def history_duration(self) -> float:
        """Seconds dynamic transforms stay answerable (the tree's creator's choice)."""
        return self._tree.history_s()

    @property
    def path(self) -> str:
        """The tree's file."""
        return self._tree.path()

    def as_text(self) -> str:
        """The tree as indented text: each frame with its parent, authority and rate."""
        return self._tree.as_text()

    def as_dot(self) -> str:
        """The tree as a Graphviz digraph (parent -> child; static edges dashed)."""
        return self._tree.as_dot()

    def __repr__(self) -> str:
        return f"FrameTree({self.path!r})"
