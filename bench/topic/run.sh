#!/usr/bin/env bash
# One command for the topic benchmark: builds it in Release and runs it. The two processes pin
# themselves to CPUs 0 and 1; run it on an otherwise idle machine. Output is Markdown.
#   bench/topic/run.sh                 build in build-bench/ and print the tables
#   bench/topic/run.sh throughput      only some tables (latency, wakeup, throughput)
#   HORUS_BENCH_BUILD=dir bench/topic/run.sh   use another build folder
# The latency table adds iceoryx side by side: Debian's packages are installed if missing, and
# its daemon (iox-roudi) is started for the run unless one is already running. Without them the
# table leaves iceoryx out.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${HORUS_BENCH_BUILD:-$root/build-bench}"
"$root/scripts/install-deps" iceoryx libiceoryx-posh-dev ||
  echo "warning: iceoryx is not installed; the latency table leaves it out" >&2
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DHORUS_BUILD_BENCH=ON \
  -DHORUS_BUILD_TESTS=OFF -DHORUS_BUILD_EXAMPLES=OFF >/dev/null
cmake --build "$build" --target topic_bench >/dev/null
if [ "$(nproc)" -lt 2 ]; then
  echo "warning: fewer than 2 CPUs; both processes share one core" >&2
fi
# RouDi, iceoryx's daemon, for this run unless one is running already. Its log goes to a file:
# it writes to the terminal while the tables are printed.
start_roudi() {
  pgrep -x iox-roudi >/dev/null && return 0
  iox-roudi >"$build/iox-roudi.log" 2>&1 &
  roudi=$!
  trap 'kill "$roudi" 2>/dev/null; wait "$roudi" 2>/dev/null || true' EXIT
  until grep -q "RouDi is ready" "$build/iox-roudi.log" 2>/dev/null; do
    kill -0 "$roudi" 2>/dev/null || return 1
    sleep 0.1
  done
}
if command -v iox-roudi >/dev/null; then
  if start_roudi; then
    export HORUS_BENCH_ICEORYX=1
  else
    echo "warning: iox-roudi did not start ($build/iox-roudi.log); the latency table leaves" \
      "iceoryx out" >&2
  fi
fi
"$build/bench/topic/topic_bench" "$@"
