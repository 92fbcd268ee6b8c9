#!/usr/bin/env bash
# bench/dds: the DDS bridge's latency on Cyclone DDS over loopback against Cyclone's own C
# ping-pong (`ddsperf`, round trip / 2), in one run. Writes nothing; prints the tables RESULTS.md
# records.
#
# 1. C++ ping-pong of CmdVel (16 B), round trip / 2 (dds_pingpong.cpp), repetitions interleaved
#    with ddsperf's:
#    (a) each process's scheduler carries its topics over DDS itself (SchedulerConfig::network):
#        the pinging one in namespace A exports `ping` and imports `pong`, the echoing one in
#        namespace B the reverse. Goal: <= 1.3x ddsperf.
#    (b) the same processes without network(), each beside a bridge process of its namespace (a
#        horus::dds::DdsBridge). Goal: <= 1.3x (ddsperf + two HORUS topic hops), the hops measured
#        in the same run as a ping-pong over local topics between two processes of one namespace.
# 2. What send() does in the sending thread (with strace): on a topic nobody exports, and on one
#    its scheduler's Network exports.
# 3. Python publishers (bench.py): one-way latency (p50/p99) and throughput of CmdVel and a 1.5 KB
#    message through two `horus bridge` processes and through horus.Network in each process, and
#    the pieces in between (raw CDR ping-pong through horus._core.dds from Python; the bridge's
#    per-message conversion: the C++ CdrPlan its pumps run for these POD types, and the Python
#    codec of tests/dds/dds_cdr.py for comparison).
# Usage: bench/dds/run.sh [BUILD_DIR] [REPETITIONS]   (default: build, 5)
# BUILD_DIR is a configured build that finds Cyclone DDS (Debian: cyclonedds-dev);
# the run needs ddsperf (Debian: cyclonedds-tools) and, for part 2, strace.
set -euo pipefail
build=$(realpath "${1:-build}")
repetitions="${2:-5}"
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
# Under the lock the shared build tree's other users take, where there is one.
if ! flock /tmp/horus-build.lock cmake --build "$build" --target dds_pingpong horus_python \
    >/dev/null; then
  echo "run.sh: cannot build dds_pingpong in $build (configured with Debian's cyclonedds-dev" \
       "installed?)" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 "$repo/generator/horus-gen" generate --lang python --out "$work/gen" \
  "$here/bench_dds.hmsg" >/dev/null
export CYCLONEDDS_URI="file://$repo/docs/cyclonedds-loopback.xml"
export HORUS_GEN_PROGRAM="$repo/generator/horus-gen"  # for the in-process bridges (horus.Network)
export PYTHONPATH="$build/python:$build/schemas/horus_gen/horus_msgs/python:$work/gen/python:$repo/tests/dds:$here"  # tests/dds: dds_cdr, the Python CDR the costs compare
# Unbuffered, Python writes a line's text and its newline apart (print() in `horus bridge`), and a
# line the bridge's C++ threads write between the two is glued to that text.
unset PYTHONUNBUFFERED
echo "$(date -u '+%Y-%m-%d %H:%M:%S UTC'), load average $(cut -d' ' -f1-3 /proc/loadavg)," \
  "$(nproc) CPUs, Cyclone DDS $(dpkg-query -W -f='${Version}' cyclonedds-tools 2>/dev/null || echo '?')"
echo
/usr/bin/python3 "$here/pingpong.py" "$build/bench/dds/dds_pingpong" "$work" "$repetitions"
echo
mkdir -m 700 "$work/shm_a" "$work/shm_b"
/usr/bin/python3 - "$build/bin/horus" "$work" "$here/bench.py" <<'PY'
import json, os, queue, random, re, statistics, subprocess, sys, threading, time
horus, work, bench = sys.argv[1:]
domain = random.randrange(1, 190)  # DDS domains end at 232: the runs use up to domain + 30

def env(side):
    return dict(os.environ, HORUS_SHM_DIR=f"{work}/shm_{side}", HORUS_NAMESPACE=f"bench_dds_{side}")

# A child's stdout is read by a thread of its own into a queue, line by line, and its stderr goes
# to a file: waiting for a line never blocks past a timeout, and a child that says much on stderr
# (a bridge's failure lines) never stalls on a full pipe before its `ready`.
class Child:
    def __init__(self, argv, side=None, stdin=False):
        self.errors = open(f"{work}/child-{time.monotonic_ns()}.err", "w+")
        self.process = subprocess.Popen(argv, env=env(side) if side else None, text=True,
                                        stdout=subprocess.PIPE, stderr=self.errors,
                                        stdin=subprocess.PIPE if stdin else None)
        self.lines = queue.Queue()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.process.stdout:
            self.lines.put(line.rstrip("\n"))
        self.lines.put(None)  # the end of its output

    def said(self):
        self.errors.seek(0)
        return self.errors.read()

    def wait_for(self, prefix, timeout=120):
        """The first line starting with `prefix` (those before it are skipped)."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise SystemExit(f"no line {prefix!r} within {timeout} s: {self.said()}") from None
            if line is None:
                raise SystemExit(f"expected {prefix!r}, the child ended: {self.said()}")
            if line.startswith(prefix):
                return line

    def tell(self, text):
        self.process.stdin.write(text)
        self.process.stdin.flush()

    def last_line(self, timeout=300):
        """The last line it prints before it ends (it is waited for)."""
        self.process.wait(timeout=timeout)
        self.reader.join()
        last = None
        while (line := self.lines.get()) is not None:
            last = line
        return last

    def kill(self):
        self.process.kill()
        self.process.wait()
        self.reader.join()

def start(argv, side=None, stdin=False):
    return Child(argv, side, stdin)

def wait_for(child, prefix):
    return child.wait_for(prefix)

def stop(*children):
    for child in children:
        child.kill()

def through_bridges(kind, mode, count, period_us):
    global domain
    domain += 1  # a fresh domain: no endpoint of an earlier run is discovered
    py = [sys.executable, bench]
    subscriber = start(py + ["subscribe", kind, mode, str(count)], "b")
    wait_for(subscriber, "ready")
    publisher = start(py + ["publish", kind, mode, str(count), str(period_us)], "a", stdin=True)
    wait_for(publisher, "ready")
    importer = start([horus, "bridge", "--domain", str(domain), "--import", "bench"], "b")
    exporter = start([horus, "bridge", "--domain", str(domain), "--export", "bench"], "a")
    wait_for(exporter, "exporting 'bench'")
    wait_for(importer, "importing")
    time.sleep(1.0)  # the DDS reader and writer match
    publisher.tell("go\n")
    result = json.loads(subscriber.last_line())
    stop(publisher)
    for child in (importer, exporter):
        child.kill()
        result.setdefault("bridge_errors", []).extend(child.said().splitlines()[:3])
    return result

def in_process(kind, count, period_us):
    """The same, each side's bridge a horus.Network inside the publisher's and the subscriber's
    own processes (no bridge process)."""
    global domain
    domain += 1
    py = [sys.executable, bench]
    subscriber = start(py + ["subscribe", kind, "latency", str(count), str(domain)], "b")
    wait_for(subscriber, "ready")
    publisher = start(py + ["publish", kind, "latency", str(count), str(period_us), str(domain)],
                      "a", stdin=True)
    wait_for(publisher, "exporting 'bench'")
    wait_for(subscriber, "importing")
    time.sleep(1.0)  # the DDS reader and writer match
    publisher.tell("go\n")
    result = json.loads(subscriber.last_line())
    stop(publisher)
    return result

def local_hop(kind, count, period_us):
    """The same publisher and subscriber in one namespace, no bridge: one HORUS hop."""
    py = [sys.executable, bench]
    subscriber = start(py + ["subscribe", kind, "latency", str(count)], "a")
    wait_for(subscriber, "ready")
    publisher = start(py + ["publish", kind, "latency", str(count), str(period_us)], "a",
                      stdin=True)
    wait_for(publisher, "ready")
    publisher.tell("go\n")
    result = json.loads(subscriber.last_line())
    stop(publisher)
    return result

def paced_dds(size, count, period_us):
    py = [sys.executable, bench]
    subscriber = start(py + ["dds-sub", str(domain + 30), str(count)])
    wait_for(subscriber, "ready")
    publisher = start(py + ["dds-pub", str(domain + 30), str(size), str(count), str(period_us)])
    result = json.loads(subscriber.last_line())
    stop(publisher)
    return result

def ddsperf(size):
    pong = subprocess.Popen(["ddsperf", "-i", str(domain + 10), "-D", "14", "pong"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out = subprocess.run(["ddsperf", "-i", str(domain + 10), "-D", "10", "-Qminmatch:1",
                          "-Qinitwait:5", "ping", "size", str(size), "waitset"],
                         capture_output=True, text=True, timeout=60).stdout
    pong.kill()
    pong.wait()
    seconds = [(float(m[0]), float(m[1])) for m in
               re.findall(r"size \d+ mean \S+ min \S+ 50% ([\d.]+)us 90% \S+ 99% ([\d.]+)us", out)]
    seconds = seconds[1:]  # the first second carries discovery and warm-up
    return {"p50": statistics.median(s[0] for s in seconds),
            "p99": statistics.median(s[1] for s in seconds)}

def python_dds(size):
    py = [sys.executable, bench]
    pong = start(py + ["dds-pong", str(domain + 20), str(size)])
    wait_for(pong, "ready")
    out = subprocess.run(py + ["dds-ping", str(domain + 20), str(size), "5200"],
                         capture_output=True, text=True, timeout=120, check=True).stdout
    stop(pong)
    return json.loads(out)

COUNT, PERIOD_US = 2200, 2000  # latency runs: 2000 messages measured, 500 a second
rows = []
for kind, size in (("cmdvel", 16), ("blob", 1512)):
    latency = through_bridges(kind, "latency", COUNT, PERIOD_US)
    networks = in_process(kind, COUNT, PERIOD_US)
    throughput = through_bridges(kind, "throughput", 0, 0)
    floor = ddsperf(size)
    raw = python_dds(size)
    paced = paced_dds(size, COUNT - 200, PERIOD_US)
    hop = local_hop(kind, COUNT, PERIOD_US)
    cost = json.loads(subprocess.run([sys.executable, bench, "costs", kind], capture_output=True,
                                     text=True, check=True).stdout)
    rows.append((kind, size, latency, throughput, floor, raw, cost, paced, hop, networks))

print("Python publishers (bench.py), paced at 500 a second: one-way latency p50 / p99 in us; "
      "ratio = bridge / ddsperf.")
print("| message | through two bridges | ddsperf ping-pong (C) | ratio p50 (p99) | "
      "through two in-process horus.Network | its ratio p50 (p99) | "
      "horus._core.dds ping-pong from Python | horus._core.dds one-way, paced, Python | one HORUS hop, "
      "paced, Python | CdrPlan from Python (export; import) | the Python codec (export; import) |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
def pair(r):
    return f"{r['p50']:.1f} / {r['p99']:.1f}" if "p50" in r else f"none measured: {r}"
def ratio(r, floor):
    return f"{r['p50'] / floor['p50']:.1f}x ({r['p99'] / floor['p99']:.1f}x)" if "p50" in r else "-"
for kind, size, latency, throughput, floor, raw, cost, paced, hop, networks in rows:
    name = "CmdVel (16 B)" if kind == "cmdvel" else "Blob1500 (1512 B)"
    print(f"| {name} | {pair(latency)} | {pair(floor)} | {ratio(latency, floor)} | "
          f"{pair(networks)} | {ratio(networks, floor)} | {pair(raw)} | {pair(paced)} | {pair(hop)} | "
          f"{cost['export: CdrPlan.encode']:.2f}; {cost['import: CdrPlan.decode']:.2f} | "
          f"{cost['export: from_bytes + encode']:.1f}; {cost['import: decode + to_bytes']:.1f} |")
print()
print("Throughput: the publisher in A sends as fast as it can for 3 s.")
print("| message | sent in A | received in B | received per second |")
print("|---|---|---|---|")
for kind, size, latency, throughput, *_ in rows:
    name = "CmdVel (16 B)" if kind == "cmdvel" else "Blob1500 (1512 B)"
    print(f"| {name} | {throughput.get('sent', 0):,} (last seq seen + 1) | "
          f"{throughput['received']:,} | {throughput.get('rate', 0):,.0f} |")
for kind, size, latency, throughput, *_ in rows:
    for line in latency.get("bridge_errors", []) + throughput.get("bridge_errors", []):
        print(f"{kind}: a bridge said: {line}")
PY
echo
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg), $(date -u '+%H:%M:%S UTC')"
