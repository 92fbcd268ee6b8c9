#!/usr/bin/env bash
# One command for the frames benchmark against tf2: installs Debian's libtf2-dev when it is
# missing, builds the benchmark in Release, runs it and writes bench/frames/RESULTS.md. The
# lookup rows pin the reader to CPU 0 and the writers to CPU 1; run it on an otherwise idle
# machine. Output is Markdown.
#   bench/frames/run.sh                    40 blocks of 20000 lookups per row
#   bench/frames/run.sh BLOCKS LOOKUPS     other counts
#   HORUS_BENCH_BUILD=dir bench/frames/run.sh   use another build folder
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="${HORUS_BENCH_BUILD:-$root/build-bench}"
blocks="${1:-40}"
lookups="${2:-20000}"
if ! pkg-config --exists tf2 2>/dev/null; then
  echo "frames bench: installing libtf2-dev (tf2::BufferCore, the side compared)" >&2
  if ((EUID == 0)); then
    as_root=()
  elif command -v sudo >/dev/null; then
    as_root=(sudo)
  else
    echo "frames bench: root is needed: run sudo apt-get install libtf2-dev" >&2
    exit 1
  fi
  "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update >/dev/null
  "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y --no-install-recommends libtf2-dev >/dev/null
fi
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHORUS_BUILD_BENCH=ON \
  -DHORUS_BUILD_TESTS=OFF -DHORUS_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "$build" --target frames_bench >/dev/null
if [ "$(nproc)" -lt 2 ]; then
  echo "warning: fewer than 2 CPUs; the reader and the writers share one core" >&2
fi
tf2_version="$(dpkg-query -W -f '${Version}' libtf2-dev 2>/dev/null || echo unknown)"
load="$(cut -d" " -f1-3 /proc/loadavg)"
tables="$("$build/bench/frames/frames_bench" "$blocks" "$lookups")"
{
  echo "# Frames: lookups and memory against tf2"
  echo
  echo "Produced by \`bench/frames/run.sh $blocks $lookups\` on $(date -u '+%Y-%m-%d %H:%M UTC')."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r), $(g++ -dumpfullversion 2>/dev/null | sed 's/^/g++ /')."
  echo "Load average when it started: $load (other work on the machine shows in the best/median spread)."
  echo
  echo "Both sides are fed the same 20-frame tree at 100 Hz: map <- f1 <- ... <- f5 (the chain"
  echo "looked up) and 14 side frames under f1..f5, one of them static; translations move and"
  echo "rotations turn about tilted axes, so every lookup interpolates (linear and slerp) for real."
  echo "Each side starts with 10 s of history (1000 stamps a frame, the history both keep) and is"
  echo "then fed in real time. HORUS: \`horus::FrameTree\` in shared memory, written by another"
  echo "process, read here. tf2: \`tf2::BufferCore\` (Debian's libtf2-dev $tf2_version, ROS 1's tf2;"
  echo "ROS 2's BufferCore is the same algorithm with tf2::TimePoint stamps) in this process, written"
  echo "by a feeder thread under its own mutex, as a node's /tf subscription does; tf2 pays no"
  echo "transport or deserialisation here. Both Release, warm, names held as strings outside the"
  echo "loop. The past time is 5 s before now, fixed per block. Every timed answer is checked"
  echo "against the stream's formulas composed by hand; a wrong one fails the run. Goal: HORUS's"
  echo "lookup <= 0.5x tf2's."
  echo
  echo "$tables"
} >"$here/RESULTS.md"
cat "$here/RESULTS.md"
