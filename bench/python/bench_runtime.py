#!/usr/bin/python3
"""The Python runtime's benchmark (results: RESULTS.md, "Python runtime").

One-way latency of a CmdVel (typed, and as a dict) Python<->Python and Python<->C++, as half the
round trip of a ping-pong between two processes pinned to CPUs 0 and 1, each busy-polling with
try_recv(); against the floor: two Python processes ping-ponging a sequence number and 16 bytes
through a raw mmap with struct. "typed" takes horus.Topic's C path for scalar POD messages,
"general" the same CmdVel through the path every other type takes (to_bytes / from_bytes and the
pybind11 calls). And the scheduler's overhead per Python tick: an empty callback
at 1 kHz (the node's measured tick duration, GIL and call included) against calling the same
function in a plain Python loop.

    bench/python/runtime.sh [--quick]      # builds build-bench/ in Release and runs this
"""
from __future__ import annotations

import argparse
import functools
import mmap
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
import uuid

ROUNDS = 20000
WARMUP = 2000


def pin(cpu: int) -> None:
    # Children inherit the parent's CPU 0: pin by the machine's CPUs, not the inherited mask.
    if (os.cpu_count() or 1) > 1:
        os.sched_setaffinity(0, {cpu})


def summary(samples_ns: list[int]) -> dict:
    samples = sorted(s / 2 for s in samples_ns[WARMUP:])  # one way = half the round trip
    pick = lambda q: samples[min(len(samples) - 1, int(q * len(samples)))] / 1000  # noqa: E731
    return {"p50": pick(0.5), "p99": pick(0.99), "mean": statistics.fmean(samples) / 1000}


# -- the floor: raw mmap + struct + a sequence number ----------------------------------------

FLOOR = struct.Struct("<Qq8s")  # seq, payload stamp, payload rest (16 B of payload in all)


def floor_ping(path: str, rounds: int) -> list[int]:
    with open(path, "r+b") as f:
        shm = mmap.mmap(f.fileno(), 128)
    pack, unpack, clock = FLOOR.pack_into, FLOOR.unpack_from, time.perf_counter_ns
    samples = []
    for seq in range(1, rounds + 1):
        start = clock()
        pack(shm, 64, seq, start, b"cmd_vel!")
        while unpack(shm, 0)[0] != seq:
            pass
        samples.append(clock() - start)
    return samples


def floor_pong(path: str, rounds: int) -> None:
    with open(path, "r+b") as f:
        shm = mmap.mmap(f.fileno(), 128)
    pack, unpack = FLOOR.pack_into, FLOOR.unpack_from
    for seq in range(1, rounds + 1):
        while True:
            got, stamp, rest = unpack(shm, 64)
            if got == seq:
                break
        pack(shm, 0, seq, stamp, rest)


# -- horus topics ----------------------------------------------------------------------------

def endpoints(kind: str, outgoing: str, incoming: str):
    """(send, try_recv) of two topics: send on `outgoing`, receive from `incoming`."""
    import horus
    from horus.msg import CmdVel
    msg_type = dict if kind == "dict" else CmdVel
    out, into = horus.Topic(msg_type, outgoing), horus.Topic(msg_type, incoming)
    if kind == "general":  # the class's methods, not the C path's instance attributes
        return functools.partial(horus.Topic.send, out), functools.partial(horus.Topic.try_recv, into)
    return out.send, into.try_recv


def make_message(kind: str, i: int):
    if kind == "dict":
        return {"stamp_nanos": i, "linear": 0.5, "angular": 0.1}
    from horus.msg import CmdVel
    return CmdVel(stamp_nanos=i, linear=0.5, angular=0.1)


def topic_ping(kind: str, rounds: int) -> list[int]:
    send, try_recv = endpoints(kind, "ping", "pong")
    clock = time.perf_counter_ns
    messages = [make_message(kind, i) for i in range(rounds)]
    samples = []
    for msg in messages:
        start = clock()
        send(msg)
        while try_recv() is None:
            pass
        samples.append(clock() - start)
    return samples


def topic_pong(kind: str, rounds: int) -> None:
    send, try_recv = endpoints(kind, "pong", "ping")
    print("ready", flush=True)
    for _ in range(rounds):
        while (msg := try_recv()) is None:
            pass
        send(msg)


# -- the cost of one call ---------------------------------------------------------------------

def call_costs() -> list[tuple[str, float]]:
    """Best-of-7 `timeit` of the calls a hop is made of, in one process (ns per call)."""
    import timeit

    import horus
    from horus.msg import CmdVel
    os.environ["HORUS_NAMESPACE"] = f"bench_{uuid.uuid4().hex[:8]}"
    out, into = horus.Topic(CmdVel, "calls"), horus.Topic(CmdVel, "calls")
    shm = mmap.mmap(-1, 128)
    names = {"out": out, "into": into, "msg": CmdVel(linear=0.5), "Topic": horus.Topic,
             "shm": shm, "pack": FLOOR.pack_into, "unpack": FLOOR.unpack_from}
    calls = [
        ("floor: pack_into (one send)", "pack(shm, 64, 1, 2, b'cmd_vel!')"),
        ("floor: unpack_from (one poll)", "unpack(shm, 0)[0] != 5"),
        ("typed: try_recv(), nothing there", "into.try_recv()"),
        ("typed: send(msg) + try_recv()", "out.send(msg); into.try_recv()"),
        ("general path: try_recv(), nothing there", "Topic.try_recv(into)"),
        ("general path: send(msg) + try_recv()", "Topic.send(out, msg); Topic.try_recv(into)"),
    ]
    number = 100000
    costs = [(label, min(timeit.repeat(stmt, globals=names, number=number, repeat=7)) / number
              * 1e9) for label, stmt in calls]
    import shutil
    shutil.rmtree(horus._core.namespace_directory(os.environ["HORUS_NAMESPACE"]),
                  ignore_errors=True)
    return costs


# -- scheduler overhead ----------------------------------------------------------------------

def scheduler_overhead(seconds: float) -> list[tuple[str, float, float | None]]:
    import timeit

    import horus

    def empty(node):
        pass

    node = horus.Node(name="empty", tick=empty, rate=1000)
    plain = min(timeit.repeat("f(n)", globals={"f": empty, "n": node}, number=100000,
                              repeat=5)) / 100000 * 1e9
    # The same function called at 1 kHz by a plain loop that sleeps in between (caches as cold
    # as the scheduler's), each call timed on its own minus the cost of timing nothing.
    clock = time.perf_counter_ns
    paced, nothing = [], []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        time.sleep(0.001)
        start = clock()
        empty(node)
        paced.append(clock() - start)
        start = clock()
        nothing.append(clock() - start)
    paced_ns = statistics.median(paced) - statistics.median(nothing)
    sched = horus.Scheduler(tick_rate=1000)
    sched.add(node)
    # NodeMetrics keep the mean, the extremes and the last tick: the median comes from sampling
    # the last tick's duration meanwhile (the sampler holds the GIL for a moment each time, so
    # it can only make the node's ticks look slower).
    runner = threading.Thread(target=sched.run, kwargs={"duration": seconds})
    runner.start()
    sampled = []
    while runner.is_alive():
        time.sleep(0.0013)
        stats = sched.get_node_stats("empty")
        if stats is not None and stats["total_ticks"]:
            sampled.append(stats["last_tick_duration"] * 1e9)
    runner.join()
    stats = sched.get_node_stats("empty")
    once = horus.Scheduler(tick_rate=1000, deterministic=True)
    once.add(horus.Node(name="empty", tick=empty, rate=1000))
    count = 20000
    start = time.perf_counter_ns()
    for _ in range(count):
        once.tick_once()
    tick_once_ns = (time.perf_counter_ns() - start) / count
    mean_ns = stats["avg_tick_duration"] * 1e9
    min_ns = stats["min_tick_duration"] * 1e9
    return [
        ("plain Python loop: f(node)", plain, None),
        (f"plain Python loop at 1 kHz (sleeping between calls), median of {len(paced)}",
         paced_ns, None),
        (f"scheduler at 1 kHz, the node's mean tick ({stats['total_ticks']} ticks)", mean_ns,
         mean_ns - plain),
        (f"scheduler at 1 kHz, median of {len(sampled)} sampled ticks", statistics.median(sampled),
         statistics.median(sampled) - plain),
        ("scheduler at 1 kHz, the node's shortest tick", min_ns, min_ns - plain),
        ("tick_once() from Python (GIL released and re-taken)", tick_once_ns,
         tick_once_ns - plain),
    ]


def child(argv: list[str]) -> None:
    role, kind, rounds = argv[0], argv[1], int(argv[2])
    pin(1)
    if role == "floor-pong":
        floor_pong(kind, rounds)
    else:
        topic_pong(kind, rounds)


def run_pair(name: str, kind: str, rounds: int, peer: list[str]) -> dict:
    env = {**os.environ, "HORUS_NAMESPACE": f"bench_{uuid.uuid4().hex[:8]}"}
    os.environ["HORUS_NAMESPACE"] = env["HORUS_NAMESPACE"]
    proc = subprocess.Popen(peer, stdout=subprocess.PIPE, text=True, env=env)
    assert proc.stdout.readline().strip() == "ready", f"{name}: the peer did not start"
    samples = topic_ping(kind, rounds)
    proc.wait(timeout=60)
    import shutil

    import horus
    shutil.rmtree(horus._core.namespace_directory(env["HORUS_NAMESPACE"]), ignore_errors=True)
    return summary(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds, for a smoke run")
    parser.add_argument("--echo", default=os.environ.get("HORUS_PY_BENCH_ECHO", ""),
                        help="the C++ echo program (horus_py_bench_echo)")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    rounds = 4000 if args.quick else ROUNDS
    pin(0)
    me = [sys.executable, os.path.abspath(__file__), "--child"]
    results = {}
    with tempfile.NamedTemporaryFile(dir="/dev/shm", prefix="horus_py_floor") as f:
        f.truncate(128)
        f.flush()
        proc = subprocess.Popen([*me, "floor-pong", f.name, str(rounds)])
        results["floor (raw mmap + struct)"] = summary(floor_ping(f.name, rounds))
        proc.wait(timeout=60)
    for kind in ("typed", "general", "dict"):
        results[f"Python <-> Python, {kind}"] = run_pair(
            "py", kind, rounds, [*me, "pong", kind, str(rounds)])
        if args.echo:
            echo_kind = "dict" if kind == "dict" else "typed"
            results[f"Python <-> C++, {kind}"] = run_pair(
                "cpp", kind, rounds, [args.echo, echo_kind, str(rounds)])
    floor = results["floor (raw mmap + struct)"]["p50"]
    print(f"One-way latency, {rounds} round trips after {WARMUP} warm-up (µs):\n")
    print("| pair | p50 | p99 | mean | p50 / floor |")
    print("|---|---:|---:|---:|---:|")
    for name, r in results.items():
        print(f"| {name} | {r['p50']:.2f} | {r['p99']:.2f} | {r['mean']:.2f} | "
              f"{r['p50'] / floor:.2f}× |")
    print("\nCost of one call, `timeit` in one process (ns):\n")
    print("| call | ns |")
    print("|---|---:|")
    for name, value in call_costs():
        print(f"| {name} | {value:.0f} |")
    overhead = scheduler_overhead(1.0 if args.quick else 5.0)
    print("\nPer-tick cost of an empty Python callback (ns):\n")
    print("| measure | ns | above the plain call (hot loop) |")
    print("|---|---:|---:|")
    for name, value, above in overhead:
        print(f"| {name} | {value:.0f} | {'' if above is None else f'{above:.0f}'} |")


if __name__ == "__main__":
    main()
