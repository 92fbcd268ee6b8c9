#!/usr/bin/env bash
# The Python runtime benchmark (bench_runtime.py): builds the horus package, the standard
# messages and the C++ echo in Release in build-bench/, then runs it. Output is Markdown.
#   bench/python/runtime.sh [--quick]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${HORUS_BENCH_BUILD:-$root/build-bench}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHORUS_BUILD_BENCH=ON \
  -DHORUS_BUILD_TESTS=OFF -DHORUS_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "$build" --target horus_python horus_msgs_generate horus_py_bench_echo >/dev/null
export PYTHONPATH="$build/python:$build/schemas/horus_gen/horus_msgs/python"
export HORUS_PY_BENCH_ECHO="$build/bench/python/horus_py_bench_echo"
exec /usr/bin/python3 "$root/bench/python/bench_runtime.py" "$@"
