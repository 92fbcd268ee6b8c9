#!/usr/bin/env bash
# bench/remote: round-trip latency of a CmdVel across `horus remote` (laptop topic ping -> link
# -> robot topic ping -> an echo process -> robot topic pong -> link -> laptop topic pong) on
# loopback with TLS, against its floor measured in the same run: a plain Cap'n Proto RPC echo of
# the same bytes with the same TLS, plus the same four shared-memory topic hops and echo process
# without the link (a relay process moving ping and pong between two namespaces, one thread
# each way, as the link's forwarders do). The goal: the link's round trip <= 1.3x that sum. Two
# links are measured, interleaved: horus-remote as it runs here (its event loop waiting on the
# topics where the kernel offers io_uring futex waits) and with HORUS_REMOTE_NO_IO_URING=1 (a
# reader thread per topic handing messages to the loop). The same again with 1 ms of delay each way (netem, in a network namespace of its own) where the
# kernel and permissions allow it, else the reason it was skipped. Then 1 kHz CmdVel and 30 Hz
# 640x480 RGB images (a CompressedImage and a pool-backed horus::Image) over one link, and the
# rate each arrives at. Writes bench/remote/RESULTS.md, keeping its "## Experiments".
# Usage: bench/remote/run.sh [BUILD_DIR] [ROUND_TRIPS]   (default: build, 5000)
# BUILD_DIR must be configured with -DHORUS_BUILD_BENCH=ON and find Cap'n Proto.
set -euo pipefail
build=$(realpath "${1:-build}")
trips="${2:-5000}"
here=$(cd "$(dirname "$0")" && pwd)
# Under flock /tmp/horus-build.lock where the build tree is shared.
if ! cmake --build "$build" --target horus-remote horus_remote_bench horus_python >/dev/null; then
  echo "run.sh: cannot build horus-remote and horus_remote_bench in $build (configured with" \
       "-DHORUS_BUILD_BENCH=ON, with Debian's libcapnp-dev installed?)" >&2
  exit 1
fi
work=$(mktemp -d)
netns="horus_bench_remote_$$"
trap 'ip netns del "$netns" 2>/dev/null || true; rm -rf "$work"' EXIT
mkdir -m 700 "$work/shm_a" "$work/shm_b" "$work/shm_c" "$work/shm_d" "$work/shm_local"
# The 1 ms-each-way row: a network namespace whose loopback delays every packet by 1 ms.
delayed=""
if ! why=$(ip netns add "$netns" 2>&1); then
  delayed="skipped: cannot make a network namespace ($why)"
elif ! why=$(ip netns exec "$netns" ip link set lo up 2>&1 &&
             ip netns exec "$netns" tc qdisc add dev lo root netem delay 1ms 2>&1); then
  delayed="skipped: tc cannot delay its loopback with netem (tc said: ${why#Error: };"
  delayed+=" the kernel needs CONFIG_NET_SCH_NETEM)"
fi
load_before="$(cut -d" " -f1-3 /proc/loadavg)"
table=$(/usr/bin/python3 - "$build" "$work" "$trips" "$netns" "$delayed" <<'PY'
import os, subprocess, sys
build, work, trips, netns, delayed = sys.argv[1:]
bench = f"{build}/bench/remote/horus_remote_bench"
remote = f"{build}/bridges/remote/horus-remote"
certs = f"{work}/certs"
subprocess.run([f"{build}/bin/horus", "remote", "keygen", certs, "robot", "laptop"], check=True,
               capture_output=True)
BLOCKS = 4

def env(side):
    """The robot's (a) and laptop's (b) worlds, those of the link with reader threads (c, d), and
    the relays' namespaces in one more."""
    base = {k: v for k, v in os.environ.items() if k != "HORUS_REMOTE_NO_IO_URING"}
    if side in ("c", "d"):
        base["HORUS_REMOTE_NO_IO_URING"] = "1"
    if side in ("near", "far", "handing_near", "handing_far"):
        return dict(base, HORUS_SHM_DIR=f"{work}/shm_local",
                    HORUS_NAMESPACE=f"bench_remote_{side}")
    return dict(base, HORUS_SHM_DIR=f"{work}/shm_{side}",
                HORUS_NAMESPACE=f"bench_remote_{side}")

def topic_wait(side):
    return subprocess.run([bench, "topic-wait"], env=env(side), text=True, capture_output=True,
                          check=True).stdout.strip()
WAITS = {"link_round_trip": topic_wait("a"), "threaded_link_round_trip": topic_wait("c")}

def port_of(child, prefix):
    while not (line := child.stdout.readline()).startswith(prefix):
        if not line:
            sys.exit(f"{child.args[:2]} ended before saying {prefix!r}")
    return line.split()[-1]

def measure(prefix, count):
    """Median-p50 block of each path, run under `prefix` (a network namespace or nothing)."""
    children = []
    def start(argv, side=None):
        child = subprocess.Popen(prefix + argv, env=env(side) if side else None, text=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        children.append(child)
        return child
    def run(argv, side):
        out = subprocess.run(prefix + argv, env=env(side) if side else None, text=True,
                             capture_output=True, check=True, timeout=600).stdout
        name, *numbers = out.split()
        return name, [float(n) for n in numbers]
    try:
        rpc_port = port_of(start([bench, "rpc-serve", certs]), "port")
        start([bench, "topic-echo"], "a")
        start([bench, "topic-echo"], "far")
        start([bench, "topic-relay", "bench_remote_near", "bench_remote_far"], "far")
        start([bench, "topic-echo"], "handing_far")
        start([bench, "topic-relay", "bench_remote_handing_near", "bench_remote_handing_far",
               "hand-off"], "handing_far")
        start([bench, "topic-echo"], "c")
        for robot, laptop in (("a", "b"), ("c", "d")):
            server = start([remote, "serve", "--listen", "127.0.0.1:0", "--certs", certs,
                            "--name", "robot", "--allow", "laptop write ping", "--allow",
                            "laptop read pong", "--allow", "laptop read cmd_vel", "--allow",
                            "laptop read camera", "--allow", "laptop read pool_camera"], robot)
            link_port = port_of(server, "serving")
            start([remote, "connect", f"127.0.0.1:{link_port}", "--certs", certs, "--name",
                   "laptop", "--server-name", "robot", "--import", "pong", "--import", "cmd_vel",
                   "--import", "camera", "--import", "pool_camera", "--export", "ping"], laptop)
        results = {}
        # Interleaved blocks, so load from other work weighs on every path alike.
        for _ in range(BLOCKS):
            for argv, side in (([bench, "rpc-ping", rpc_port, certs, str(count)], None),
                               ([bench, "topic-ping", str(count), "local_round_trip"], "near"),
                               ([bench, "topic-ping", str(count), "handing_round_trip"],
                                "handing_near"),
                               ([bench, "topic-ping", str(count), "link_round_trip"], "b"),
                               ([bench, "topic-ping", str(count), "threaded_link_round_trip"],
                                "d")):
                name, numbers = run(argv, side)
                results.setdefault(name, []).append(numbers)
        return {name: sorted(blocks, key=lambda b: b[0])[len(blocks) // 2]
                for name, blocks in results.items()}
    finally:
        for child in children:
            child.kill()
            child.wait()

def rows(median, where):
    floor = median["rpc_echo"][0] + median["local_round_trip"][0]
    for name, label in (("rpc_echo", "Cap'n Proto RPC echo, TLS"),
                        ("local_round_trip", "the same four topic hops and echo, no link"),
                        ("handing_round_trip", "the same, each hop handed to a second thread "
                                               "through an eventfd (not in the floor)"),
                        ("link_round_trip", "CmdVel round trip across `horus remote`, TLS; "
                                            + WAITS["link_round_trip"]),
                        ("threaded_link_round_trip", "the same; "
                                                     + WAITS["threaded_link_round_trip"])):
        p50, p99, mean = median[name]
        print(f"| {where} | {label} | {p50:.1f} | {p99:.1f} | {mean:.1f} |")
    print(f"| {where} | **the floor: RPC echo + topic hops** | {floor:.1f} | | |")
    return (median["link_round_trip"][0] / floor, median["threaded_link_round_trip"][0] / floor)

count = int(trips) // BLOCKS
print("| network | path | p50 (us) | p99 (us) | mean (us) |")
print("|---|---|---|---|---|")
ratios = [("loopback", rows(measure([], count), "loopback"))]
if not delayed:
    # Fewer trips: each takes 4 ms more.
    in_netns = ["ip", "netns", "exec", netns]
    ratios.append(("1 ms each way",
                   rows(measure(in_netns, max(count // 20, 50)), "1 ms each way")))
print()
for where, (ratio, threaded) in ratios:
    print(f"Ratio of the p50s, {where}: link / floor = **{ratio:.2f}x** (goal <= 1.3x); "
          f"with HORUS_REMOTE_NO_IO_URING=1, {threaded:.2f}x.")
if delayed:
    print(f"\nThe 1 ms-each-way row: {delayed}.")
print()

children = []
try:
    def start(argv, side):
        child = subprocess.Popen(argv, env=env(side), text=True, stdout=subprocess.PIPE,
                                 stderr=subprocess.DEVNULL)
        children.append(child)
        return child
    server = start([remote, "serve", "--listen", "127.0.0.1:0", "--certs", certs, "--name",
                    "robot", "--allow", "laptop read *"], "a")
    link_port = port_of(server, "serving")
    start([remote, "connect", f"127.0.0.1:{link_port}", "--certs", certs, "--name", "laptop",
           "--server-name", "robot", "--import", "cmd_vel", "--import", "camera", "--import",
           "pool_camera"], "b")
    start([bench, "stream-publish", "14"], "a")
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
load_after="$(cut -d" " -f1-3 /proc/loadavg)"
# What was tried and measured by hand (written under "## Experiments") stays.
experiments=$(sed -n '/^## Experiments/,$p' "$here/RESULTS.md" 2>/dev/null || true)
{
  echo "# Remote link (horus remote) on loopback"
  echo
  echo "Produced by \`bench/remote/run.sh\` ($trips round trips a path, in 4 interleaved blocks;"
  echo "the block with the median p50 shown) on $(date -u '+%Y-%m-%d %H:%M UTC')."
  echo "Machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), Linux $(uname -r)."
  echo "Load average before: $load_before; after: $load_after. Build: $(grep -m1 CMAKE_BUILD_TYPE: "$build/CMakeCache.txt" | cut -d= -f2)."
  echo
  echo "The floor is what the link's round trip cannot do without: one Cap'n Proto RPC call"
  echo "carrying a CmdVel's bytes (16 B) there and back over kj-tls with the mutual-TLS setup"
  echo "horus-remote uses, plus the same four shared-memory topic hops and echo process with a"
  echo "relay process in place of the link (one thread each way, waiting on its topic as the"
  echo "link's forwarder threads do). The link's round trip crosses the four topics, the echo"
  echo "process and the link twice (one streaming message each way), which the event loop takes"
  echo "off the topic itself where its row says so (io_uring futex waits), and a reader thread"
  echo "hands to the event loop through an eventfd where it says reader thread; both links run"
  echo "side by side, their blocks interleaved. The hand-off row is the relay again with each hop"
  echo "handed from the thread that waits on the topic to a second thread through a queue and an"
  echo "eventfd the second waits on with epoll, as a reader thread hands a message to the event"
  echo "loop: what the hand-offs alone cost (the floor does not include it)."
  echo
  echo "$table"
  if [ -n "$experiments" ]; then
    echo
    echo "$experiments"
  fi
} > "$here/RESULTS.md"
cat "$here/RESULTS.md"
