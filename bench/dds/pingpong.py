"""bench/dds, parts 1 and 2 (run.sh runs it; RESULTS.md records it): the C++ ping-pong of
dds_pingpong.cpp in its three arrangements beside ddsperf's, repetitions interleaved, and what
send() does in the sending thread, traced with strace.

    pingpong.py DDS_PINGPONG WORK_DIR REPETITIONS
"""
from __future__ import annotations

import json
import os
import queue
import random
import re
import shutil
import statistics
import subprocess
import sys
import threading
import time

ROUND_TRIPS = 5000  # measured per arrangement and repetition, after dds_pingpong's warm-up
DDSPERF_SECONDS = 5  # ddsperf reports each second; the first (discovery, warm-up) is dropped
SENDS = 1000  # the traced sends of part 2


class Child:
    """A process whose stdout lines a thread of its own reads into a queue (a wait for a line
    has a timeout) and whose stderr goes to a file (a chatty child never stalls on a full pipe).
    Its stdin stays open until stop(): dds_pingpong's roles end when it closes."""

    def __init__(self, argv: list[str], env: dict[str, str], errors: str):
        self.errors = open(errors, "w+")
        self.process = subprocess.Popen(argv, env=env, text=True, stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=self.errors)
        self.lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.put(line.rstrip("\n"))
        self.lines.put(None)

    def said(self) -> str:
        self.errors.seek(0)
        return self.errors.read()

    def line(self, wanted, timeout: float = 120.0) -> str:
        """The first line for which `wanted(line)` holds (the lines before it are passed over)."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise SystemExit(f"{self.process.args}: no line expected within {timeout} s; "
                                 f"stderr: {self.said()}") from None
            if line is None:
                raise SystemExit(f"{self.process.args} ended before the line expected; "
                                 f"stderr: {self.said()}")
            if wanted(line):
                return line

    def ready(self) -> None:
        self.line(lambda line: line == "ready")

    def stop(self) -> None:
        self.process.stdin.close()
        try:
            self.process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


class Run:
    def __init__(self, program: str, work: str):
        self.program = program
        self.work = work
        self.domain = random.randrange(1, 150)  # DDS domains end at 232
        self.children = 0

    def fresh_domain(self) -> int:
        """A domain no earlier arrangement used: nothing of theirs is discovered."""
        self.domain += 1
        return self.domain

    def side(self, name: str) -> dict[str, str]:
        """The environment of a namespace with a shared-memory root of its own."""
        root = f"{self.work}/shm_{name}"
        shutil.rmtree(root, ignore_errors=True)
        os.mkdir(root, 0o700)
        return dict(os.environ, HORUS_SHM_DIR=root, HORUS_NAMESPACE=f"bench_dds_{name}")

    def start(self, args: list[str], env: dict[str, str]) -> Child:
        self.children += 1
        return Child([self.program, *args], env, f"{self.work}/child-{self.children}.err")

    def ping(self, env: dict[str, str], *args: str) -> dict:
        pinger = self.start(["ping", str(ROUND_TRIPS), *args], env)
        pinger.ready()
        result = json.loads(pinger.line(lambda line: line.startswith("{"), timeout=300))
        pinger.stop()
        return result

    def in_process(self) -> dict:
        """(a): each process's scheduler carries its topics over DDS."""
        domain = str(self.fresh_domain())
        echo = self.start(["echo", domain], self.side("a_echo"))
        echo.ready()
        try:
            return self.ping(self.side("a_ping"), domain)
        finally:
            echo.stop()

    def bridge_processes(self) -> dict:
        """(b): plain processes, each beside a bridge process of its namespace."""
        domain = str(self.fresh_domain())
        pinging, echoing = self.side("b_ping"), self.side("b_echo")
        children = [self.start(["echo"], echoing),
                    self.start(["bridge", domain, "pong", "ping"], echoing),
                    self.start(["bridge", domain, "ping", "pong"], pinging)]
        try:
            for child in children:
                child.ready()
            return self.ping(pinging)
        finally:
            for child in children:
                child.stop()

    def local(self) -> dict:
        """Two HORUS topic hops: the same ping-pong over local topics of one namespace."""
        env = self.side("local")
        echo = self.start(["echo"], env)
        echo.ready()
        try:
            return self.ping(env)
        finally:
            echo.stop()

    def ddsperf(self) -> dict:
        domain = str(self.fresh_domain())
        pong = subprocess.Popen(["ddsperf", "-i", domain, "-D", str(DDSPERF_SECONDS + 10), "pong"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            out = subprocess.run(["ddsperf", "-i", domain, "-D", str(DDSPERF_SECONDS),
                                  "-Qminmatch:1", "-Qinitwait:5", "ping", "size", "16", "waitset"],
                                 capture_output=True, text=True, timeout=60).stdout
        finally:
            pong.kill()
            pong.wait()
        seconds = [(float(p50), float(p99)) for p50, p99 in re.findall(
            r"size \d+ mean \S+ min \S+ 50% ([\d.]+)us 90% \S+ 99% ([\d.]+)us", out)][1:]
        if not seconds:
            raise SystemExit(f"ddsperf measured nothing:\n{out}")
        return {"p50": statistics.median(s[0] for s in seconds),
                "p99": statistics.median(s[1] for s in seconds)}


def latency(run: Run, repetitions: int) -> None:
    arrangements = {"ddsperf": run.ddsperf, "a": run.in_process, "b": run.bridge_processes,
                    "local": run.local}
    names = list(arrangements)
    rows = []
    for repetition in range(repetitions):
        # Each repetition starts with another arrangement: none always runs first or last.
        order = names[repetition % len(names):] + names[:repetition % len(names)]
        rows.append({name: arrangements[name]() for name in order})
        rows[-1]["load"] = os.getloadavg()[0]

    def pair(r: dict) -> str:
        return f"{r['p50']:.1f} / {r['p99']:.1f}"

    def bound(row: dict) -> dict:
        """What (b) is held to: ddsperf's one way plus two HORUS hops (a local round trip)."""
        return {q: row["ddsperf"][q] + 2 * row["local"][q] for q in ("p50", "p99")}

    def ratio(r: dict, floor: dict) -> str:
        return f"{r['p50'] / floor['p50']:.2f}x ({r['p99'] / floor['p99']:.2f}x)"

    print(f"C++ ping-pong of CmdVel (16 B), one way = round trip / 2, p50 / p99 in us; "
          f"{ROUND_TRIPS} round trips per arrangement and repetition (ddsperf: the median of its "
          f"per-second p50s and p99s over {DDSPERF_SECONDS - 1} s); the median row's ratios are the "
          f"medians of the repetitions' ratios. Goals: (a) <= 1.3x ddsperf; (b) <= 1.3x "
          f"(ddsperf + two local hops).")
    print("| repetition (load) | ddsperf ping-pong (C) | (a) Network in each process | "
          "(a) / ddsperf p50 (p99) | (b) beside bridge processes | local hop | "
          "ddsperf + two local hops | (b) / that p50 (p99) |")
    print("|---|---|---|---|---|---|---|---|")
    for number, row in enumerate(rows, 1):
        print(f"| {number} ({row['load']:.1f}) | {pair(row['ddsperf'])} | {pair(row['a'])} | "
              f"{ratio(row['a'], row['ddsperf'])} | {pair(row['b'])} | {pair(row['local'])} | "
              f"{pair(bound(row))} | {ratio(row['b'], bound(row))} |")
    median = {name: {q: statistics.median(row[name][q] for row in rows) for q in ("p50", "p99")}
              for name in names}

    def paired(measured: str, floor) -> str:
        """The median of the repetitions' own ratios: each against the floor of its repetition,
        measured minutes apart at most, so a load that comes and goes between repetitions moves
        both sides of a ratio."""
        p50, p99 = (statistics.median(row[measured][q] / floor(row)[q] for row in rows)
                    for q in ("p50", "p99"))
        return f"{p50:.2f}x ({p99:.2f}x)"

    print(f"| median | {pair(median['ddsperf'])} | {pair(median['a'])} | "
          f"{paired('a', lambda row: row['ddsperf'])} | {pair(median['b'])} | "
          f"{pair(median['local'])} | {pair(bound(median))} | {paired('b', bound)} |")
    resent = sum(row[name].get("resent", 0) for row in rows for name in ("a", "b", "local"))
    if resent:
        print(f"({resent} pings went unanswered for 1 s and were sent again.)")


def traced_sends(run: Run, exported: bool) -> dict[str, int]:
    """The system calls of the sending thread between its lines "sending" and "sent"."""
    trace = f"{run.work}/strace-{'exported' if exported else 'local'}.txt"
    args = ["send", str(SENDS)] + ([str(run.fresh_domain())] if exported else [])
    subprocess.run(["strace", "-f", "-qq", "-o", trace, run.program, *args],
                   env=run.side("trace"), check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, timeout=120)
    with open(trace) as lines:
        calls = [line.split(None, 1) for line in lines if line[:1].isdigit()]
    sender = calls[0][0]  # the process's first thread: its pid
    counts: dict[str, int] = {}
    inside = False
    for thread, call in calls:
        if thread != sender or call.startswith("<..."):
            continue
        if call.startswith('write(1, "sending'):
            inside = True
        elif call.startswith('write(1, "sent'):
            break
        elif inside:
            name = call.split("(", 1)[0]
            if name == "futex":
                name += " " + re.search(r"FUTEX_\w+", call).group(0)
            counts[name] = counts.get(name, 0) + 1
    return counts


def syscalls(run: Run) -> None:
    if shutil.which("strace") is None:
        print("send()'s system calls: not traced (no strace)")
        return
    print(f"System calls of the sending thread over {SENDS} sends 1 ms apart (strace -f), "
          f"besides its {SENDS} clock_nanosleep between them:")
    print("| topic | system calls of send() |")
    print("|---|---|")
    for exported in (False, True):
        counts = traced_sends(run, exported)
        sleeps = counts.pop("clock_nanosleep", 0)
        said = ", ".join(f"{name} x{count}" for name, count in sorted(counts.items())) or "none"
        if sleeps != SENDS:
            said += f" (and {sleeps} clock_nanosleep)"
        name = "exported by its scheduler's Network" if exported else "not exported"
        print(f"| {name} | {said} |")


def main() -> None:
    program, work, repetitions = sys.argv[1], sys.argv[2], int(sys.argv[3])
    run = Run(program, work)
    latency(run, repetitions)
    print()
    syscalls(run)


if __name__ == "__main__":
    main()
