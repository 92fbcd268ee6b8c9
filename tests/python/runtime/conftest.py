"""The Python runtime's suites: `horus` (runtime/python, built into BUILD/python) and the generated
standard package `horus.msg`, both imported from the build tree that ctest (or the caller) names.

BUILD is $HORUS_BUILD_DIR, else the repository's build/ (what ./scripts/test makes), so a plain
`/usr/bin/python3 -m pytest tests/python` after a build runs these suites too.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
BUILD = Path(os.environ.get("HORUS_BUILD_DIR") or ROOT / "build").resolve()
PYTHON_ROOTS = [BUILD / "python", BUILD / "schemas" / "horus_gen" / "horus_msgs" / "python"]

missing = [str(p) for p in PYTHON_ROOTS if not p.is_dir()]
if missing:
    raise RuntimeError(f"the Python runtime is not built: {', '.join(missing)} missing; "
                       "build first (cmake --build build) or set HORUS_BUILD_DIR")
for path in reversed(PYTHON_ROOTS):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))
