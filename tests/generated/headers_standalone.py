"""Every generated header compiles on its own: a file that includes only it passes
`-fsyntax-only` with the project's warnings. The package's .cpp includes all of a package's
headers together, so without this a header that forgets an include would go unnoticed.

    headers_standalone.py --compiler CXX --runtime-include DIR [--flag F ...] GENERATED_CPP_DIR...
"""
from __future__ import annotations

import argparse
import concurrent.futures
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--compiler", required=True)
    parser.add_argument("--runtime-include", required=True)
    parser.add_argument("--flag", action="append", default=[], help="compiler flag (repeatable)")
    parser.add_argument("roots", nargs="+", type=Path, help="the cpp/ folders of generated packages")
    args = parser.parse_args()
    headers = sorted({(root, h.relative_to(root)) for root in args.roots for h in root.rglob("*.hpp")})
    if not headers:
        print(f"no generated headers under {', '.join(map(str, args.roots))}", file=sys.stderr)
        return 1
    includes = [f"-I{args.runtime_include}"] + [f"-I{root}" for root in args.roots]
    with tempfile.TemporaryDirectory(prefix="horus-headers-") as work:
        def check(entry: tuple[Path, Path]) -> str | None:
            root, header = entry
            source = Path(work) / (str(header).replace("/", "__") + ".cpp")
            source.write_text(f'#include "{header}"\n')
            result = subprocess.run([args.compiler, "-std=c++20", "-fsyntax-only", *args.flag, *includes,
                                     str(source)], capture_output=True, text=True)
            if result.returncode != 0 or result.stderr.strip():
                return f"{root / header} does not compile on its own:\n{result.stderr}"
            return None

        with concurrent.futures.ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
            failures = [f for f in pool.map(check, headers) if f]
    for failure in failures:
        print(failure, file=sys.stderr)
    print(f"{len(headers) - len(failures)} of {len(headers)} generated headers compile on their own")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
