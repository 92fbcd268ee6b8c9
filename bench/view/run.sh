#!/usr/bin/env bash
# bench/view: the live view (horus-view) side by side with the Foxglove SDK's own WebSocket
# server, in one run, serving the same streams: 1 kHz CmdVel (json, the same JSON Schema) and
# 30 Hz 640x480 RGB images (protobuf foxglove.RawImage). Publish-to-client latency p50/p99 and
# the serving process's CPU per client, with 1 and 4 clients of one program (client.py), the
# servers in turn (horus, SDK, horus, SDK, ...). The goal: latency <= 1.0x and CPU <= 0.5x of the
# SDK's. Writes bench/view/RESULTS.md, keeping its "## Experiments".
# Usage: bench/view/run.sh [BUILD_DIR] [ROUNDS] [WINDOW_SECONDS]   (default: build, 2, 10)
# The SDK and the client's websockets come from PyPI into a venv of the build dir, pinned here.
set -euo pipefail
build=$(realpath "${1:-build}")
rounds="${2:-2}"
window="${3:-10}"
here=$(cd "$(dirname "$0")" && pwd)
venv="$build/bench/view/venv"
pins=(foxglove-sdk==0.30.3 websockets==17.4)
# Under flock /tmp/horus-build.lock where the build tree is shared.
if ! flock /tmp/horus-build.lock cmake --build "$build" --target horus-view horus_python \
    >/dev/null; then
  echo "run.sh: cannot build horus-view and horus_python in $build (horus-view needs Debian's" \
       "libcapnp-dev)" >&2
  exit 1
fi
installed=$("$venv/bin/python" -m pip freeze 2>/dev/null || true)
if ! grep -qx "${pins[0]}" <<<"$installed" || ! grep -qx "${pins[1]}" <<<"$installed"; then
  /usr/bin/python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet "${pins[@]}"
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
load_before="$(cut -d" " -f1-3 /proc/loadavg)"
started="$(date -u '+%Y-%m-%d %H:%M UTC')"
table=$(/usr/bin/python3 "$here/bench.py" "$build" "$venv/bin/python" "$work" "$rounds" "$window")
load_after="$(cut -d" " -f1-3 /proc/loadavg)"
# What was tried and measured by hand (written under "## Experiments") stays.
experiments=$(sed -n '/^## Experiments/,$p' "$here/RESULTS.md" 2>/dev/null || true)
{
  echo "# Live view (horus-view) against the Foxglove SDK's WebSocket server"
  echo
  echo "Produced by \`bench/view/run.sh\` on $started ($rounds rounds, ${window} s windows)."
  cpu_model=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
  build_type=$(grep -m1 CMAKE_BUILD_TYPE: "$build/CMakeCache.txt" | cut -d= -f2)
  echo "Machine: $(nproc) CPUs, $cpu_model, Linux $(uname -r)."
  echo "Load average before: $load_before; after: $load_after. Build: $build_type."
  echo "The SDK: PyPI foxglove-sdk ${pins[0]#*==} (its Rust server, in the publisher's" \
       "process); the client: Python websockets ${pins[1]#*==}."
  echo "What is measured and how: README.md beside this file."
  echo
  echo "$table"
  if [ -n "$experiments" ]; then
    echo
    echo "$experiments"
  fi
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
