#!/usr/bin/env bash
# Python and C++ tick lateness in one scheduler (bench_lateness.py): builds the horus package and
# the C++ probe node in Release in build-bench/, then runs it. Output is Markdown.
#   bench/python/lateness.sh [--quick]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${HORUS_BENCH_BUILD:-$root/build-bench}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHORUS_BUILD_BENCH=ON \
  -DHORUS_BUILD_TESTS=OFF -DHORUS_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "$build" --target horus_python horus_msgs_generate horus_bench_probe >/dev/null
export PYTHONPATH="$build/python:$build/schemas/horus_gen/horus_msgs/python:$build/bench/python"
exec /usr/bin/python3 "$root/bench/python/bench_lateness.py" "$@"
