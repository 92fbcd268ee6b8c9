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

# Members a generated node class already has: horus::Node's (C++) and horus.Node's (Python)
# methods and attributes, and what the generated base class adds (node_config, add_to, params). A
# node's topic, service, data or params member so named would hide one of them.
NODE_RESERVED_MEMBERS = frozenset({
    "name", "init", "tick", "shutdown", "is_safe_state", "enter_safe_state", "on_error", "publishers",
    "subscribers", "request_stop", "node_config", "add_to", "run_node", "topic_capacities",
    "rate", "order", "budget", "deadline", "watchdog", "on_miss", "failure_policy", "compute", "on",
    "priority", "core", "subs", "pubs", "is_async", "open_topics", "send", "recv", "has_msg",
    "log_info", "log_warning", "log_error", "log_debug",
    "params", "declare_param", "param_declarations", "on_param_change",
})
