#!/usr/bin/env bash
# One command for the parameters benchmark: builds it in Release, runs it and writes
# bench/params/RESULTS.md. Two processes pin themselves to CPUs 0 and 1; run it on an otherwise
# idle machine. Output is Markdown.
#   bench/params/run.sh                    4000 writes per row, 200000 reads per block
#   bench/params/run.sh WRITES READS       other counts
#   HORUS_BENCH_BUILD=dir bench/params/run.sh   use another build folder
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="${HORUS_BENCH_BUILD:-$root/build-bench}"
writes="${1:-4000}"
reads="${2:-200000}"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHORUS_BUILD_BENCH=ON \
  -DHORUS_BUILD_TESTS=OFF -DHORUS_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "$build" --target params_bench >/dev/null
if [ "$(nproc)" -lt 2 ]; then
  echo "warning: fewer than 2 CPUs; both processes share one core" >&2
fi
load="$(cut -d" " -f1-3 /proc/loadavg)"
tables="$("$build/bench/params/params_bench" "$writes" "$reads")"
{
  echo "# Parameters: reads from another process, writes to the owner's callback"
  echo
  echo "Produced by \`bench/params/run.sh $writes $reads\` on $(date -u +%Y-%m-%d)."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r)."
  echo "Load average when it started: $load (other work on the machine shows in p99)."
  echo
  echo "A node with three parameters (max_speed: f64, retries: i32, frame_id: String) runs in one"
  echo "process; the other reads them through \`ParamStoreReader::param<T>()\` handles, and writes"
  echo "max_speed with \`set_param()\`. Floors in the same run: a plain atomic word in shared memory"
  echo "read the same way (and the String's bytes copied out of shared memory with no protocol);"
  echo "for writes, a ROS-2-style parameter service built from HORUS services (a ServiceServer whose"
  echo "handler checks the value, updates a map and calls a callback) with a request of the same"
  echo "size. Goals: a read <= 50 ns and <= 2x the plain word; set -> callback <= 1.5x the service."
  echo
  echo "$tables"
} >"$here/RESULTS.md"
cat "$here/RESULTS.md"
