"""The package as users get it: stubs for every name, `cmake --install` where Debian's
/usr/bin/python3 finds it, and an import that says what to install where numpy or msgpack is
missing."""
from __future__ import annotations

import ast
import inspect
import os
import subprocess
import sys
from pathlib import Path

import pytest

import horus

STUBS = Path(horus.__file__).with_name("__init__.pyi")


def _stub_names() -> dict[str, set[str]]:
    tree = ast.parse(STUBS.read_text())
    names: dict[str, set[str]] = {"": set()}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            names[""].add(node.name)
            names[node.name] = {n.name for n in node.body if isinstance(n, ast.FunctionDef)} | {
                n.target.id for n in node.body if isinstance(n, ast.AnnAssign)}
        elif isinstance(node, ast.FunctionDef):
            names[""].add(node.name)
        elif isinstance(node, ast.AnnAssign):
            names[""].add(node.target.id)
    return names


def test_stubs_declare_every_public_name_and_method():
    stubs = _stub_names()
    assert set(horus.__all__) <= stubs[""], set(horus.__all__) - stubs[""]
    for cls in (horus.Node, horus.Scheduler, horus.Topic, horus.ServiceClient, horus.ServiceServer):
        public = {name for name, _ in inspect.getmembers(cls) if not name.startswith("_")}
        assert public <= stubs[cls.__name__], (cls.__name__, public - stubs[cls.__name__])
    assert (STUBS.parent / "py.typed").exists()


def _install(tmp_path: Path, prefix: str, destdir: Path | None) -> None:
    env = {**os.environ, **({"DESTDIR": str(destdir)} if destdir else {})}
    result = subprocess.run(["cmake", "--install", os.environ["HORUS_BUILD_DIR"], "--prefix", prefix],
                            capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stdout + result.stderr


def _use_installed(site: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    code = ("import horus, horus.msg\n"
            "from horus.msg import CmdVel\n"
            "t = horus.Topic(CmdVel, 'installed')\n"
            "u = horus.Topic(CmdVel, 'installed')\n"
            "t.send(CmdVel(linear=1.0))\n"
            "print(horus.__file__, horus.msg.__file__, u.try_recv().linear)\n")
    return subprocess.run(["/usr/bin/python3", "-c", code], capture_output=True, text=True, env=env)


def test_installed_into_a_prefix_imports_with_its_dist_packages(tmp_path):
    prefix = tmp_path / "prefix"
    _install(tmp_path, str(prefix), None)
    site = prefix / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "dist-packages"
    result = _use_installed(site)
    assert result.returncode == 0, result.stderr
    runtime, messages, value = result.stdout.split()
    assert runtime.startswith(str(site)) and messages.startswith(str(site)) and value == "1.0"


def test_default_prefix_lands_on_debians_python_path(tmp_path):
    # DESTDIR stages the /usr/local install; Debian's python3 searches that exact folder.
    _install(tmp_path, "/usr/local", tmp_path / "stage")
    relative = f"lib/python{sys.version_info[0]}.{sys.version_info[1]}/dist-packages"
    debian_path = subprocess.run(["/usr/bin/python3", "-c", "import sys; print('\\n'.join(sys.path))"],
                                 capture_output=True, text=True, env={}).stdout.split()
    assert f"/usr/local/{relative}" in debian_path
    staged = tmp_path / "stage" / "usr" / "local" / relative
    assert (staged / "horus" / "__init__.py").exists()
    result = _use_installed(staged)
    assert result.returncode == 0, result.stderr


# Another interpreter than Debian's (pyenv's, a venv without system packages) loads the
# extension but finds neither: a meta-path finder that refuses them stands for it.
REFUSING = """
import sys
class Refuse:
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in {missing!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Refuse())
import pytest

import horus
"""


@pytest.mark.parametrize("missing", [["msgpack"], ["numpy"], ["numpy", "msgpack"]])
def test_import_says_what_to_install_when_numpy_or_msgpack_is_missing(missing):
    child = subprocess.run([sys.executable, "-c", REFUSING.format(missing=missing)],
                           capture_output=True, text=True)
    assert child.returncode == 1
    last = child.stderr.strip().splitlines()[-1]
    assert last == (f"ImportError: horus needs numpy and msgpack, and {sys.executable} finds no "
                    f"{missing[0]}: install Debian's python3-numpy and python3-msgpack (apt "
                    "install python3-numpy python3-msgpack) and run Debian's /usr/bin/python3"), \
        child.stderr
