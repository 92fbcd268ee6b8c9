"""Naming rules every language shares: members the generated classes own, and the snake_case
spelling of type names in file and module names. Each language's keywords are in lang/<lang>.py."""
from __future__ import annotations

import re

# Members every generated message already has in C++ or Python.
RESERVED_MEMBERS = frozenset({"log_summary", "to_bytes", "from_bytes", "view"})


_BOUNDARY = re.compile(r"(?<=[a-z])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")


def snake_case(name: str) -> str:
    """MotorFeedback -> motor_feedback, Pose2D -> pose2d, PointXYZRGB -> point_xyzrgb."""
    return _BOUNDARY.sub("_", name).lower()
