#!/usr/bin/env bash
# Builds the action benchmark in Release and runs it; writes bench/action/RESULTS.md.
# Usage: bench/action/run.sh [samples per measurement, default 5000]
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="${HORUS_BENCH_BUILD_DIR:-$here/../../build-bench-action}"
samples="${1:-5000}"

cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target horus_action_bench

load="$(cut -d" " -f1-3 /proc/loadavg)"
table="$("$build/horus_action_bench" "$samples")"
{
  echo "# Action latency"
  echo
  echo "Produced by \`bench/action/run.sh $samples\` on $(date -u +%Y-%m-%d)."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r)."
  echo "Load average when it started: $load (other work on the machine shows in p99)."
  echo
  echo "A client process sends POD Navigate goals (tests/schemas/test_actions) to a server process."
  echo "An action is three services and three topics, so each row is compared with what it is built"
  echo "from, measured in the same run in interleaved blocks: (a) with a plain service call of the"
  echo "same request and response types, (b) and (c) with a one-way topic hop of the feedback"
  echo "message. (b) is 0 when the first feedback arrived before the accepted answer (the server"
  echo "hands the goal to its executor before answering). Goals of (a) and (b) are sent 200 us apart"
  echo "(untimed), so each finds the server idle as a service call does; back to back, the previous"
  echo "goal's trailing status and executor wakes share the two cores with it. Goal: each row at"
  echo "most 1.2x its base."
  echo
  echo "$table"
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
