#!/usr/bin/python3
"""Tick lateness of Python nodes against C++ nodes in one scheduler (results: RESULTS.md,
"Python tick lateness").

Each run builds a fresh Scheduler(tick_rate=1000, rt=True) holding seed 001's warehouse AGV's two
1 kHz nodes twice: as Python nodes (`py_safety` on any CPU, `py_motor` on CPU 1) and as C++
nodes (`cpp_safety`, `cpp_motor`, the same placement; horus_bench_probe.LatenessProbe), four
threads at SCHED_FIFO 50 (where allowed). Every node has the safety monitor's budget and
deadline, 100 and 200 us, with on_miss="warn". Lateness is how long after its release a tick's
code began: for a C++ node horus::lateness() (the tick's start), for a Python node the moment its
Python function runs (the scheduler's lateness plus the time to take the GIL). The first tick of
each node in a run is reported apart (the one the scheduler does not judge), over all runs; the
steady ticks are every later one, pooled.

    bench/python/lateness.sh [--quick]     # builds build-bench/ in Release and runs this
    # or, with a built tree's PYTHONPATH and horus_bench_probe on it:
    /usr/bin/python3 bench/python/bench_lateness.py [--runs N] [--seconds S]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys

# horus._core's symbols global, so the probe (built without a runtime of its own) reads the
# framework clock of the very scheduler that runs it.
sys.setdlopenflags(os.RTLD_NOW | os.RTLD_GLOBAL)
import horus  # noqa: E402
from horus import _core, us  # noqa: E402
from horus_bench_probe import LatenessProbe  # noqa: E402

RATE = 1000.0
BUDGET = 100 * us
DEADLINE = 200 * us


def python_probe(name: str, samples: list[int], core: int | None) -> horus.Node:
    lateness, remaining = _core.lateness, horus.budget_remaining

    def tick(node):
        # From the release to now: the scheduler's lateness, then what it took to get here.
        samples.append(round((lateness() + BUDGET - remaining()) * 1e9))

    return horus.Node(name=name, tick=tick, rate=RATE, order=0, budget=BUDGET, deadline=DEADLINE,
                      on_miss="warn", core=core)


def one_run(seconds: float) -> dict[str, tuple[list[int], int]]:
    capacity = int(seconds * RATE) + 100
    py = {"py_safety": [], "py_motor": []}
    cpp = {"cpp_safety": LatenessProbe("cpp_safety", capacity),
           "cpp_motor": LatenessProbe("cpp_motor", capacity)}
    motor_core = 1 if (os.cpu_count() or 1) > 1 else 0
    sched = horus.Scheduler(tick_rate=RATE, rt=True, name="lateness_bench")
    sched.add(python_probe("py_safety", py["py_safety"], None))
    sched.add(python_probe("py_motor", py["py_motor"], motor_core))
    # priority=50 is the default SCHED_FIFO priority: it only keeps each C++ node on a thread
    # of its own rather than in the Python node's group of the same rate and CPU.
    for name, core in (("cpp_safety", None), ("cpp_motor", motor_core)):
        sched.add(cpp[name], order=0, rate=RATE, budget=BUDGET, deadline=DEADLINE,
                  on_miss="warn", core=core, priority=50)
    sched.run(duration=seconds)
    out = {}
    for name in ("py_safety", "py_motor", "cpp_safety", "cpp_motor"):
        samples = py[name] if name in py else list(cpp[name].samples)
        out[name] = (samples, sched.get_node_stats(name)["deadline_misses"])
    return out


def pick(values: list[float], q: float) -> float:
    return values[min(len(values) - 1, int(q * len(values)))]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="3 runs of 0.5 s")
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    runs, seconds = (3, 0.5) if args.quick else (args.runs, args.seconds)
    first: dict[str, list[int]] = {}
    steady: dict[str, list[int]] = {}
    misses: dict[str, int] = {}
    for _ in range(runs):
        for name, (samples, missed) in one_run(seconds).items():
            first.setdefault(name, []).append(samples[0])
            steady.setdefault(name, []).extend(samples[1:])
            misses[name] = misses.get(name, 0) + missed
    caps = horus.Scheduler(rt=True, name="lateness_probe_caps")
    print(f"## Python and C++ tick lateness, 1 kHz, {runs} runs of {seconds:g} s\n")
    rt = "full" if caps.has_full_rt() else "degraded: " + "; ".join(caps.degradations())
    print(f"rt: {rt}\n")
    print("| node | first tick p50 (us) | first tick max (us) | steady p50 (us) | steady p99 (us) "
          "| steady max (us) | steady ticks | deadline misses (200 us) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in ("py_safety", "cpp_safety", "py_motor", "cpp_motor"):
        f = sorted(first[name])
        s = sorted(steady[name])
        print(f"| {name} | {statistics.median(f) / 1e3:.1f} | {f[-1] / 1e3:.1f} | "
              f"{pick(s, 0.5) / 1e3:.1f} | {pick(s, 0.99) / 1e3:.1f} | {s[-1] / 1e3:.1f} | "
              f"{len(s)} | {misses[name]} |")


if __name__ == "__main__":
    main()
