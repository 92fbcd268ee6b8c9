#!/usr/bin/env bash
# bench/remote: round-trip latency of a CmdVel across `horus remote` (laptop topic ping -> link
# -> robot topic ping -> an echo process -> robot topic pong -> link -> laptop topic pong) on
# loopback with TLS, against a plain Cap'n Proto RPC echo of the same bytes with the same TLS in
# the same run (the issue's goal: <= 1.3x); then 1 kHz CmdVel and 30 Hz 640x480 RGB images (a
# CompressedImage and a pool-backed horus::Image) over one link, and the rate each arrives at.
# Writes bench/remote/RESULTS.md.
# Usage: bench/remote/run.sh [BUILD_DIR] [ROUND_TRIPS]   (default: build, 5000)
set -euo pipefail
build=$(realpath "${1:-build}")
trips="${2:-5000}"
here=$(cd "$(dirname "$0")" && pwd)
cmake --build "$build" --target horus-remote horus_remote_bench horus_python >/dev/null  # under flock /tmp/horus-build.lock where the build is shared
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -m 700 "$work/shm_a" "$work/shm_b"
load="$(cut -d" " -f1-3 /proc/loadavg)"
table=$(/usr/bin/python3 - "$build" "$work" "$trips" <<'PY'
import os, subprocess, sys, time
build, work, trips = sys.argv[1:]
bench = f"{build}/bench/remote/horus_remote_bench"
remote = f"{build}/tools/remote/horus-remote"
certs = f"{work}/certs"
subprocess.run([f"{build}/bin/horus", "remote", "keygen", certs, "robot", "laptop"], check=True,
               capture_output=True)
children = []

def env(side):
    return dict(os.environ, HORUS_SHM_DIR=f"{work}/shm_{side}", HORUS_NAMESPACE=f"bench_remote_{side}")

def start(argv, side=None):
    child = subprocess.Popen(argv, env=env(side) if side else None, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    children.append(child)
    return child

def port_of(child, prefix):
    while not (line := child.stdout.readline()).startswith(prefix):
        if not line:
            sys.exit(f"{child.args[:2]} ended before saying {prefix!r}")
    return line.split()[-1]

def row(out):
    name, *numbers = out.split()
    return name, [float(n) for n in numbers]

try:
    # Interleaved blocks, so load from other work weighs on both alike.
    rpc_port = port_of(start([bench, "rpc-serve", certs]), "port")
    start([bench, "topic-echo"], "a")
    server = start([remote, "serve", "--listen", "127.0.0.1:0", "--certs", certs, "--name", "robot",
                    "--allow", "laptop write ping", "--allow", "laptop read pong",
                    "--allow", "laptop read cmd_vel", "--allow", "laptop read camera",
                    "--allow", "laptop read pool_camera"], "a")
    link_port = port_of(server, "serving")
    start([remote, "connect", f"127.0.0.1:{link_port}", "--certs", certs, "--name", "laptop",
           "--server-name", "robot", "--import", "pong", "--import", "cmd_vel", "--import", "camera",
           "--import", "pool_camera", "--export", "ping"], "b")
    results = {"rpc_echo": [], "link_round_trip": []}
    for _ in range(4):
        for argv, side in (([bench, "rpc-ping", rpc_port, certs, str(int(trips) // 4)], None),
                           ([bench, "topic-ping", str(int(trips) // 4)], "b")):
            name, numbers = row(subprocess.run(argv, env=env(side) if side else None, text=True,
                                               capture_output=True, check=True).stdout)
            results[name].append(numbers)
    median = {name: sorted(blocks, key=lambda b: b[0])[len(blocks) // 2]
              for name, blocks in results.items()}
    print("| path | p50 (us) | p99 (us) | mean (us) |")
    print("|---|---|---|---|")
    for name, label in (("rpc_echo", "Cap'n Proto RPC echo, TLS (the floor)"),
                        ("link_round_trip", "CmdVel round trip across `horus remote`, TLS")):
        p50, p99, mean = median[name]
        print(f"| {label} | {p50:.1f} | {p99:.1f} | {mean:.1f} |")
    ratio = median["link_round_trip"][0] / median["rpc_echo"][0]
    print(f"\nRatio of the p50s: **{ratio:.2f}x** (goal <= 1.3x).\n")
    publisher = start([bench, "stream-publish", "14"], "a")
    counted = subprocess.run([bench, "stream-count", "8"], env=env("b"), text=True,
                             capture_output=True, check=True, timeout=60).stdout
    rates = dict(line.split() for line in counted.splitlines())
    print("| stream over one link | sent at (Hz) | arrives at (Hz) |")
    print("|---|---|---|")
    print(f"| CmdVel (16 B) | 1000 | {float(rates['cmd_vel']):.1f} |")
    print(f"| 640x480 RGB image (CompressedImage, 921,600 B of data) | 30.3 | {float(rates['camera']):.1f} |")
    print(f"| 640x480 RGB image (horus::Image: its pool block's 921,600 B cross) | 30.3 | {float(rates['pool_camera']):.1f} |")
finally:
    for child in children:
        child.kill()
        child.wait()
PY
)
# What was tried and measured by hand (written under "## Experiments") stays.
experiments=$(sed -n '/^## Experiments/,$p' "$here/RESULTS.md" 2>/dev/null || true)
{
  echo "# Remote link (horus remote) on loopback"
  echo
  echo "Produced by \`bench/remote/run.sh\` ($trips round trips a row, in 4 interleaved blocks; the"
  echo "block with the median p50 shown) on $(date -u +%Y-%m-%d)."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r)."
  echo "Load average when it started: $load. Build: $(grep -m1 CMAKE_BUILD_TYPE: "$build/CMakeCache.txt" | cut -d= -f2)."
  echo
  echo "The floor is one Cap'n Proto RPC call carrying a CmdVel's bytes (16 B) there and back over"
  echo "kj-tls with the same mutual-TLS setup horus-remote uses. The link's round trip crosses"
  echo "four shared-memory topics, an echo process on the robot's side and the link twice (one"
  echo "streaming message each way, from a forwarder thread that wakes the event loop through an"
  echo "eventfd)."
  echo
  echo "$table"
  if [ -n "$experiments" ]; then
    echo
    echo "$experiments"
  fi
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
