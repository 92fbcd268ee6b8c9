#!/bin/sh
# Builds the scheduler benchmarks (Release) and writes bench/scheduler/RESULTS.md.
#   bench/scheduler/run.sh [seconds per jitter measurement, default 10]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build="${BUILD_DIR:-$here/../../build-bench-scheduler}"
seconds="${1:-10}"
mkdir -p "$build"
if ! { cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release &&
       cmake --build "$build" --target sched_overhead_bench sched_jitter_bench; } >"$build/build.log" 2>&1; then
  cat "$build/build.log" >&2
  echo "run.sh: build failed" >&2
  exit 1
fi
out="$here/RESULTS.md"
{
  echo "# Scheduler benchmarks"
  echo
  echo "Produced by \`bench/scheduler/run.sh\` on $(date -u +%Y-%m-%d), $(nproc) CPUs,"
  echo "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), Linux $(uname -r)."
  echo
  echo "## Overhead per node tick (goal <= 100 ns)"
  echo
  echo "\`per_node\` is the time per node tick; the scheduler's overhead is its difference from"
  echo "PlainLoop (the same virtual tick() calls in a for loop). Timed = Rt nodes with budget,"
  echo "deadline and watchdog checks."
  echo
  echo '```'
  "$build/sched_overhead_bench" --benchmark_min_time=0.2 2>/dev/null | grep -E "^(BM_|Benchmark|-)"
  echo '```'
  echo
  echo "## Release jitter of a 1 kHz node (goal p99 <= 50 us on this non-RT machine)"
  echo
  echo '```'
  "$build/sched_jitter_bench" "$seconds"
  echo '```'
} >"$out"
echo "wrote $out"
