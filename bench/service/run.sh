#!/usr/bin/env bash
# Builds the service benchmark in Release and runs it; writes bench/service/RESULTS.md.
# Usage: bench/service/run.sh [round trips per measurement, default 20000]
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="${HORUS_BENCH_BUILD_DIR:-$here/../../build-bench-service}"
calls="${1:-20000}"

cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target horus_service_bench

load="$(cut -d" " -f1-3 /proc/loadavg)"
table="$("$build/horus_service_bench" "$calls")"
{
  echo "# Service round-trip latency"
  echo
  echo "Produced by \`bench/service/run.sh $calls\` on $(date -u +%Y-%m-%d)."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r)."
  echo "Load average when it started: $load (other work on the machine shows in p99)."
  echo
  echo "A client process calls a server process (a ServiceServer thread) and waits for the answer."
  echo "The floor is two processes waking each other through two futex words, the least any"
  echo "request/response that sleeps while waiting can cost; the Topic row is the same exchange over"
  echo "two bare topics (the transport alone). All rows run in interleaved blocks in one run, so load"
  echo "from other work on the machine weighs on them alike. Goal: services at most 1.5x the floor."
  echo
  echo "$table"
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
