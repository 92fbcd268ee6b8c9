#!/bin/sh
# Python benchmarks (see RESULTS.md): the mirror types' codec speed against lcm-gen's Python and
# import time (bench_mirror.py); the runtime's topic latency and per-tick overhead (runtime.sh);
# Python ticks' lateness against C++ ticks' in one scheduler (lateness.sh).
set -eu
here=$(dirname "$0")
/usr/bin/python3 "$here/bench_mirror.py" "$@"
echo
"$here/runtime.sh" "$@"
echo
"$here/lateness.sh" "$@"
