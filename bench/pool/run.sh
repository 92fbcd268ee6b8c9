#!/usr/bin/env bash
# One command for the tensor pool benchmark: builds it in Release and runs it. The processes pin
# themselves to CPUs 0 and 1; run it on an otherwise idle machine. Output is Markdown.
#   bench/pool/run.sh              build in build-bench/ and print both tables
#   bench/pool/run.sh latency      one table (latency, throughput)
#   HORUS_BENCH_BUILD=dir bench/pool/run.sh   use another build folder
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${HORUS_BENCH_BUILD:-$root/build-bench}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHORUS_BUILD_BENCH=ON \
  -DHORUS_BUILD_TESTS=OFF -DHORUS_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "$build" --target pool_bench >/dev/null
if [ "$(nproc)" -lt 2 ]; then
  echo "warning: fewer than 2 CPUs; the processes share one core" >&2
fi
"$build/bench/pool/pool_bench" "$@"
