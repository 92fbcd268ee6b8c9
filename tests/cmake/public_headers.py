#!/usr/bin/env python3
"""Checks of the runtime's public surface.

`includes`: the tools, the Python bindings and the bridges use the runtime through its public
headers only. None of their sources may include `horus/detail/...` (internals the installed
headers need, free to change) nor `horus/internal/...` (runtime/src/include: not installed at
all). Every offender is printed as file:line.

`standalone`: every installed header (runtime/include/horus, detail/ included) compiles on its own
in a TU of one #include, with the project's warnings as errors.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

# The folders whose sources must use public headers only, from the repository root.
SCANNED = ("tools", "runtime/python", "bridges")
SOURCE_SUFFIXES = {".c", ".cc", ".cpp", ".cxx", ".h", ".hh", ".hpp", ".hxx", ".ipp"}
PRIVATE_INCLUDE = re.compile(
    r'^\s*#\s*include\s*[<"](?P<path>horus/(?:detail|internal)/[^">]*|[^">]*runtime/src/[^">]*)[">]')

def private_includes(root: Path) -> list[str]:
    """The offending lines as "file:line: includes ..."."""
    offenders: list[str] = []
    for folder in SCANNED:
        for path in sorted((root / folder).rglob("*")):
            if path.suffix not in SOURCE_SUFFIXES or not path.is_file():
                continue
            relative = path.relative_to(root).as_posix()
            for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                match = PRIVATE_INCLUDE.match(line)
                if match:
                    offenders.append(f"{relative}:{number}: includes {match.group('path')}")
    return offenders


def check_includes(root: Path) -> int:
    offenders = private_includes(root)
    if offenders:
        print(f"{len(offenders)} include(s) of runtime internals outside the runtime (use the "
              "public headers of runtime/include/horus, or give what is needed a public API):")
        for offender in offenders:
            print(f"  {offender}")
        return 1
    print(f"{', '.join(SCANNED)}: public headers only")
    return 0


def compile_alone(compiler: str, flags: list[str], header: str, work: Path) -> str | None:
    """The compiler's complaint about a TU of only `#include <header>`, or None."""
    source = work / (header.replace("/", "_") + ".cpp")
    source.write_text(f"#include <{header}>\n")
    done = subprocess.run([compiler, *flags, "-fsyntax-only", str(source)],
                          capture_output=True, text=True, check=False)
    return None if done.returncode == 0 else done.stderr.strip()


def check_standalone(root: Path, compiler: str, include_dirs: list[str]) -> int:
    include_root = root / "runtime" / "include"
    headers = sorted(path.relative_to(include_root).as_posix()
                     for path in (include_root / "horus").rglob("*.hpp"))
    # The compiler's own folders stay out: -I/usr/include breaks libstdc++'s #include_next.
    folders = dict.fromkeys(folder for folder in [str(include_root), *include_dirs]
                            if folder and folder not in ("/usr/include", "/usr/local/include"))
    flags = ["-std=c++20", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-DMSGPACK_NO_BOOST",
             *(f"-I{folder}" for folder in folders)]
    failures: list[tuple[str, str]] = []
    with tempfile.TemporaryDirectory() as scratch, \
            concurrent.futures.ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
        results = pool.map(lambda h: (h, compile_alone(compiler, flags, h, Path(scratch))), headers)
        failures = [(header, error) for header, error in results if error is not None]
    for header, error in failures:
        print(f"--- {header} does not compile on its own:\n{error}\n")
    print(f"{len(headers) - len(failures)} of {len(headers)} installed headers compile on their own")
    return 1 if failures else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("check", choices=("includes", "standalone"))
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[2],
                        help="the repository (default: the one holding this script)")
    parser.add_argument("--compiler", default="c++", help="standalone: the C++ compiler")
    parser.add_argument("--include-dirs", default="",
                        help="standalone: further include folders, separated by ':' (the "
                             "generated standard messages, msgpack)")
    args = parser.parse_args()
    if args.check == "includes":
        return check_includes(args.root)
    return check_standalone(args.root, args.compiler, args.include_dirs.split(os.pathsep))


if __name__ == "__main__":
    sys.exit(main())
