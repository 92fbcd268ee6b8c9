"""bench/dds: one-way latency and throughput from a publisher in namespace A to a subscriber in
namespace B through two `horus bridge` processes on Cyclone DDS over loopback, against Cyclone's
own `ddsperf` ping-pong, plus the pieces in between (run.sh runs it; RESULTS.md records it).

    bench.py ROLE ...   (run.sh starts the roles as processes of their own)
"""
from __future__ import annotations

import contextlib
import json
import os
import statistics
import sys
import time

WARMUP = 200  # messages discarded at the start of each latency run
THROUGHPUT_S = 3.0  # how long the publisher floods in a throughput run


def say(text: str) -> None:
    """One line on stdout in one write(2). print() makes two (the text, then its newline) when
    stdout is unbuffered (PYTHONUNBUFFERED, python -u), and a line the bridge's threads write
    between them is glued to the text: `ready` swallows the `exporting 'bench'` run.sh waits for
    next (or the other way round)."""
    data = (text + "\n").encode()
    while data:
        data = data[os.write(1, data):]


def message_class(kind: str):
    if kind == "cmdvel":
        from horus.msg import CmdVel
        return CmdVel
    from bench_dds import Blob1500
    return Blob1500


def make(cls, seq: int):
    """A message stamped now (CLOCK_MONOTONIC, shared by every process of the host)."""
    if cls.__name__ == "CmdVel":
        return cls(stamp_nanos=time.monotonic_ns(), linear=float(seq), angular=0.0)
    return cls(stamp_nanos=time.monotonic_ns(), seq=seq)


def seq_of(message) -> int:
    return int(message.linear) if type(message).__name__ == "CmdVel" else message.seq


def in_process(domain: str | None, **patterns):
    """With a DDS domain, a scheduler whose horus.Network carries `bench` inside this process
    (the in-process option: no bridge process); else nothing to enter."""
    import horus
    if domain is None:
        return contextlib.nullcontext()
    return horus.Scheduler(network=horus.Network(domain=int(domain), **patterns))


def publish(kind: str, mode: str, count: str, period_us: str, domain: str | None = None) -> None:
    import horus
    cls = message_class(kind)
    topic = horus.Topic(cls, "bench")
    with in_process(domain, export=["bench"]):
        say("ready")
        sys.stdin.readline()  # run.sh says go once both bridges carry the topic
        period = int(period_us) * 1e-6
        next_send = time.monotonic()
        end = next_send + THROUGHPUT_S
        seq = 0
        while seq < int(count) if mode == "latency" else time.monotonic() < end:
            topic.send(make(cls, seq))
            seq += 1
            if mode == "latency":
                # Sleeping, not spinning (two cores): each message is stamped when it is sent.
                next_send += period
                time.sleep(max(0.0, next_send - time.monotonic()))
        say(f"sent {seq}")


def subscribe(kind: str, mode: str, count: str, domain: str | None = None) -> None:
    import horus
    cls = message_class(kind)
    topic = horus.Topic(cls, "bench")
    with in_process(domain, import_=["bench"]):
        say("ready")
        result = receive(topic, mode, int(count))
    say(json.dumps(result))


def receive(topic, mode: str, total: int) -> dict:
    """What arrives on `topic`: latency p50/p99 after the warm-up, or the rate of a flood."""
    latencies, first, last, received, last_seq = [], None, None, 0, -1
    while True:
        # The first message comes once both bridges run; then 2 s of silence is the end.
        message = topic.recv(timeout=60.0 if first is None else 2.0)
        now = time.monotonic_ns()
        if message is None:
            break  # the publisher is done (or the stream stalled)
        seq = seq_of(message)
        received += 1
        last_seq = seq
        if mode == "latency" and seq >= WARMUP:
            latencies.append((now - message.stamp_nanos) / 1e3)
        if first is None:
            first = now
        last = now
        if mode == "latency" and seq == total - 1:
            break
    result = {"received": received, "last_seq": last_seq}
    if latencies:
        latencies.sort()
        result.update(p50=latencies[len(latencies) // 2],
                      p99=latencies[min(len(latencies) - 1, int(len(latencies) * 0.99))],
                      samples=len(latencies))
    if mode == "throughput" and received > 1:
        result["rate"] = (received - 1) / ((last - first) / 1e9)
        result["sent"] = last_seq + 1
    return result


def dds_pong(domain: str, size: str) -> None:
    """Echoes raw CDR samples of `ping` to `pong` through horus._core.dds (the bridge's endpoints)."""
    from horus._core import dds as _dds
    participant = _dds.Participant(int(domain))
    reader = _dds.Reader(participant, "bench_ping", "bench::Raw_")
    writer = _dds.Writer(participant, "bench_pong", "bench::Raw_")
    say("ready")
    while True:
        for sample in reader.take(1.0):
            writer.write(sample)


def dds_ping(domain: str, size: str, count: str) -> None:
    """Round trip / 2 of raw CDR samples through horus._core.dds from Python, ping-pong."""
    from horus._core import dds as _dds
    participant = _dds.Participant(int(domain))
    writer = _dds.Writer(participant, "bench_ping", "bench::Raw_")
    reader = _dds.Reader(participant, "bench_pong", "bench::Raw_")
    while writer.matched() == 0 or reader.matched() == 0:
        time.sleep(0.01)
    sample = b"\x00\x01\x00\x00" + bytes(int(size))
    halves = []
    for i in range(int(count)):
        start = time.perf_counter_ns()
        writer.write(sample)
        while not reader.take(1.0):
            pass
        if i >= WARMUP:
            halves.append((time.perf_counter_ns() - start) / 2e3)
    halves.sort()
    say(json.dumps({"p50": halves[len(halves) // 2], "p99": halves[int(len(halves) * 0.99)]}))


def dds_sub(domain: str, count: str) -> None:
    """One-way latency of paced raw CDR samples through horus._core.dds from Python (no bridge)."""
    import struct
    from horus._core import dds as _dds
    participant = _dds.Participant(int(domain))
    reader = _dds.Reader(participant, "bench_oneway", "bench::Raw_")
    say("ready")
    latencies = []
    while len(latencies) < int(count):
        for sample in reader.take(5.0):
            now = time.monotonic_ns()
            seq, stamp = struct.unpack_from("<QQ", sample, 4)
            if seq >= WARMUP:
                latencies.append((now - stamp) / 1e3)
    latencies.sort()
    say(json.dumps({"p50": latencies[len(latencies) // 2],
                    "p99": latencies[int(len(latencies) * 0.99)]}))


def dds_pub(domain: str, size: str, count: str, period_us: str) -> None:
    import struct
    from horus._core import dds as _dds
    participant = _dds.Participant(int(domain))
    writer = _dds.Writer(participant, "bench_oneway", "bench::Raw_")
    while writer.matched() == 0:
        time.sleep(0.01)
    time.sleep(0.5)
    padding = bytes(max(0, int(size) - 16))
    next_send = time.monotonic()
    for seq in range(int(count) + WARMUP):
        writer.write(b"\x00\x01\x00\x00" + struct.pack("<QQ", seq, time.monotonic_ns()) + padding)
        next_send += int(period_us) * 1e-6
        time.sleep(max(0.0, next_send - time.monotonic()))


def costs(kind: str) -> None:
    """The bridge's conversion per message, in one process: for a POD type the C++ CdrPlan its
    pumps run (timed here through a Python call each, so an upper bound), and what a Python
    thread did before (and still does for serialized types)."""
    import dds_cdr
    from horus._core import dds as _dds
    cls = message_class(kind)
    codec = dds_cdr.CdrCodec(cls)
    info = cls.__horus__
    plan = _dds.CdrPlan.from_description(info.description)
    message = make(cls, 1)
    data = message.to_bytes()
    cdr = codec.encode(message)

    def per_call(work, n=20000) -> float:
        best = []
        for _ in range(5):
            start = time.perf_counter_ns()
            for _ in range(n):
                work()
            best.append((time.perf_counter_ns() - start) / n / 1e3)
        return statistics.median(best)

    say(json.dumps({
        "export: from_bytes + encode": per_call(lambda: codec.encode(cls.from_bytes(data))),
        "import: decode + to_bytes": per_call(lambda: codec.decode(cdr).to_bytes()),
        "export: CdrPlan.encode": per_call(lambda: plan.encode(data)),
        "import: CdrPlan.decode": per_call(lambda: plan.decode(cdr)),
        "cdr_bytes": len(cdr)}))


if __name__ == "__main__":
    roles = {"publish": publish, "subscribe": subscribe, "dds-pong": dds_pong,
             "dds-ping": dds_ping, "dds-sub": dds_sub, "dds-pub": dds_pub,
             "costs": costs}
    roles[sys.argv[1]](*sys.argv[2:])
