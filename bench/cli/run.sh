#!/usr/bin/env bash
# Start-up of the `horus` command: wall time of `horus topic list` on a namespace of 50 topics
# (the issue's bar: <= 150 ms), against the floor of Debian's interpreter starting and importing
# the horus package (what any Python command pays). Median of 21 runs each.
# Usage: bench/cli/run.sh [BUILD_DIR]   (default: build)
set -euo pipefail
build=$(realpath "${1:-build}")
export PYTHONPATH="$build/python:$build/schemas/horus_gen/horus_msgs/python"
HORUS_SHM_DIR=$(mktemp -d)
export HORUS_SHM_DIR HORUS_NAMESPACE=bench_cli
trap 'rm -rf "$HORUS_SHM_DIR"' EXIT
/usr/bin/python3 - <<'PY'
import horus
from horus.msg import CmdVel
for i in range(50):
    horus.Topic(CmdVel, f"topic_{i:02d}").send(CmdVel(linear=1.0, angular=0.0))
PY
/usr/bin/python3 - "$build/bin/horus" <<'PY'
import statistics, subprocess, sys, time
def median_ms(argv):
    samples = []
    for _ in range(21):
        start = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
        samples.append((time.perf_counter() - start) * 1e3)
    return statistics.median(samples)
listed = subprocess.run([sys.argv[1], "topic", "list"], check=True, capture_output=True,
                        text=True).stdout.split()
assert len(listed) == 50, listed
floor = median_ms(["/usr/bin/python3", "-c", "import horus._core"])
command = median_ms([sys.argv[1], "topic", "list"])
print(f"horus topic list, 50 topics: {command:.1f} ms (goal <= 150 ms)")
print(f"floor, python3 -c 'import horus._core': {floor:.1f} ms; ratio {command / floor:.2f}x")
PY
