#!/bin/sh
# Python mirror benchmarks (see RESULTS.md): codec speed against lcm-gen's Python, import time.
set -eu
exec /usr/bin/python3 "$(dirname "$0")/bench_mirror.py" "$@"
