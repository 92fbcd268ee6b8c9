"""Names that generated code cannot use, and the file names types are emitted under."""
from __future__ import annotations

import keyword
import re

CPP_KEYWORDS = frozenset("""
alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t char16_t
char32_t class compl concept const consteval constexpr constinit const_cast continue co_await
co_return co_yield decltype default delete do double dynamic_cast else enum explicit export extern
false float for friend goto if inline int long mutable namespace new noexcept not not_eq nullptr
operator or or_eq private protected public register reinterpret_cast requires return short signed
sizeof static static_assert static_cast struct switch template this thread_local throw true try
typedef typeid typename union unsigned using virtual void volatile wchar_t while xor xor_eq
""".split())

PYTHON_KEYWORDS = frozenset(keyword.kwlist)

# Members every generated message already has in C++ or Python.
RESERVED_MEMBERS = frozenset({"log_summary", "to_bytes", "from_bytes", "view"})


def keyword_clash(name: str) -> str | None:
    """Which language reserves `name`, if one does."""
    in_cpp, in_python = name in CPP_KEYWORDS, name in PYTHON_KEYWORDS
    if in_cpp and in_python:
        return "a C++ and Python keyword"
    if in_cpp:
        return "a C++ keyword"
    if in_python:
        return "a Python keyword"
    if name.startswith("__") or (name.startswith("_") and len(name) > 1 and name[1].isupper()):
        return "reserved in C++ (leading underscores)"
    if name.startswith("_horus"):
        return "reserved for the generated Python code"
    return None


_BOUNDARY = re.compile(r"(?<=[a-z])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")


def snake_case(name: str) -> str:
    """MotorFeedback -> motor_feedback, Pose2D -> pose2d, PointXYZRGB -> point_xyzrgb."""
    return _BOUNDARY.sub("_", name).lower()
