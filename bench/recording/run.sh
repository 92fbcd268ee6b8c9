#!/usr/bin/env bash
# Builds the recording benchmark in Release and runs it; writes bench/recording/RESULTS.md.
# Usage: bench/recording/run.sh [seconds, default 10] [folder for the files, default /tmp]
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="${HORUS_BENCH_BUILD_DIR:-$here/../../build-bench-recording}"
seconds="${1:-10}"
folder="${2:-/tmp}"

cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target horus_recording_bench

load="$(cut -d" " -f1-3 /proc/loadavg)"
status=0
table="$(nice "$build/horus_recording_bench" "$seconds" "$folder")" || status=$?
load_after="$(cut -d" " -f1-3 /proc/loadavg)"
{
  echo "# Recording throughput"
  echo
  echo "Produced by \`bench/recording/run.sh $seconds $folder\` on $(date -u '+%Y-%m-%d %H:%M UTC') (run under \`nice\`)."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r);"
  echo "files on $(df -T "$folder" | awk 'NR==2 {print $2}') ($folder)."
  echo "Load average before: $load; after: $load_after (other helpers' builds share the 2 CPUs)."
  echo
  echo "One process publishes 10 topics of 64 B at 1 kHz and a 30 Hz stream of 1080p RGB frames"
  echo "(6,220,800 B) for $seconds s; a child process records all 11 topics with \`horus::Recorder\`"
  echo "(zstd level 1 chunks of ~1 MiB, as \`SchedulerConfig::recording(true)\` and \`horus-record\` do)."
  echo "Two sessions one after the other: the frames as the plain value \`[u8; 6220800]\` written in"
  echo "place with \`loan()\` (the POD ring carries each whole), then as pool-backed \`horus::Image\`"
  echo "(\`Topic<Image>\`: the ring carries a descriptor, the pixels stay in a block of the"
  echo "shared-memory pool, from which the recorder copies them). Recorder CPU is the child's user +"
  echo "system time from wait4(). The floor of the write rate is, in the same session, a plain"
  echo "sequential \`write()\` of as many bytes as the recording file has (1 MiB blocks, then fsync,"
  echo "as the recorder's finish does). The headline ratio is the write rate while recording (file"
  echo "bytes per second of the recording) against the floor; the recorder writes only as fast as"
  echo "the robot publishes, so its *capacity* (file bytes per second of recorder CPU) is given too."
  echo "Rings: 1024 slots per 1 kHz topic, 32 per camera (about 1 s of each): what a recorded topic"
  echo "needs to ride out the recorder's pauses on a loaded machine."
  echo "Goals: nothing lost; write rate while recording at least 0.8x the floor."
  echo
  echo "$table"
  if [[ $status != 0 ]]; then
    echo
    echo "Exit status $status (3: messages were lost)."
  fi
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
