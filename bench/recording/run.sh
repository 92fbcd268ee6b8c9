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
  echo "(6,220,800 B, the plain value \`[u8; 6220800]\` written in place with \`loan()\`: the POD"
  echo "transport carries it whole) for $seconds s; a child process records all 11 topics with"
  echo "\`horus::Recorder\` (zstd level 1 chunks of ~1 MiB, as \`SchedulerConfig::recording(true)\` and"
  echo "\`horus-record\` do). Its CPU is the child's user + system time from wait4(). The floor of the"
  echo "write rate is, in the same run, a plain sequential \`write()\` of as many bytes as the"
  echo "recording file has (1 MiB blocks, then fsync, as the recorder's finish does). The recorder"
  echo "only ever writes as fast as the robot publishes, so its *capacity* is compared: file bytes"
  echo "per second of recorder CPU, against the floor's bytes per second of wall time."
  echo "Rings: 1024 slots per 1 kHz topic, 32 per camera frame (about 1 s of each): what a"
  echo "recorded topic needs to ride out the recorder's pauses on a loaded machine."
  echo "Goals: nothing lost; capacity at least 0.8x the floor."
  echo
  echo "$table"
  if [[ $status != 0 ]]; then
    echo
    echo "Exit status $status (3: messages were lost)."
  fi
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
