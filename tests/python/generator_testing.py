"""What the generator's test modules share (imported by them and by conftest.py; test modules
never import each other): the repository's folders, horus-gen run as CMake runs it, generated
Python imported, and the C++ tools of the cross-language suite found in the build tree."""
from __future__ import annotations

import importlib
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HORUS_GEN = ROOT / "generator" / "horus-gen"
SCHEMAS = ROOT / "tests" / "schemas"
GOLDEN = ROOT / "tests" / "golden"
# Every test schema, generated together into the session's `test_schemas_root` (conftest.py).
TEST_SCHEMAS = sorted(str(p) for p in (SCHEMAS / "test_msgs").iterdir() if p.suffix in (".hmsg", ".hsrv")) + \
    [str(SCHEMAS / "other_pkg" / "stamp.hmsg"), str(SCHEMAS / "crosslang" / "shapes.hmsg")]

sys.path.insert(0, str(ROOT / "generator"))


def run_horus_gen(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """Runs the generator in its own process with Debian's interpreter, as CMake does."""
    return subprocess.run(["/usr/bin/python3", str(HORUS_GEN), *args], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})


def generate_python(out: Path, *files: str, extra: tuple[str, ...] = ()) -> Path:
    """Runs horus-gen --lang python into `out`; returns OUT/python."""
    result = run_horus_gen("generate", "--lang", "python", "--out", str(out), *extra, *files)
    assert result.returncode == 0, result.stderr
    return out / "python"


def import_from(root: Path, *packages: str):
    """Imports generated packages from `root`; each test package name is unique to its test."""
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    return [importlib.import_module(p) for p in packages]


def load_support_module():
    """runtime/python/_horus_gen_support_v1.py as it is in the repository."""
    path = ROOT / "runtime" / "python" / "_horus_gen_support_v1.py"
    spec = importlib.util.spec_from_file_location("_horus_gen_support_v1", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


CROSSLANG_TOOLS = {"HORUS_CROSSLANG_TOOL": "horus_crosslang", "HORUS_CROSSLANG_ECHO": "horus_crosslang_echo"}


def crosslang_tools() -> tuple[str, str]:
    """The C++ halves of the cross-language suite: named by ctest in HORUS_CROSSLANG_TOOL and
    HORUS_CROSSLANG_ECHO, else taken from the build tree (HORUS_BUILD_DIR, default build/)."""
    build = Path(os.environ.get("HORUS_BUILD_DIR") or ROOT / "build")
    found = []
    for variable, target in CROSSLANG_TOOLS.items():
        path = os.environ.get(variable) or str(build / "tests" / "generated" / "crosslang" / target)
        if not os.access(path, os.X_OK):
            raise FileNotFoundError(
                f"the cross-language suite needs the C++ tool {target}, not found at {path}: build it with "
                f"`cmake --build {build} --target {' '.join(CROSSLANG_TOOLS.values())}`, or name it in "
                f"{variable} (HORUS_BUILD_DIR names another build folder)")
        found.append(path)
    return found[0], found[1]
