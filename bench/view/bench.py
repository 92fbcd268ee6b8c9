"""bench/view's measurement (run.sh sets it up): horus-view and the Foxglove SDK's WebSocket server
serving the same two streams (publish_horus.py, publish_sdk.py), one after the other in rounds
(horus, SDK, horus, SDK, ...), each measured the same way with the same client (client.py):

- the serving process's CPU (utime + stime from /proc/PID/stat) over a window with no client;
- then 1 client, then 4, each over a window of the same length: every client's latencies
  (publish stamp to arrival, CLOCK_REALTIME) and messages received, and the serving process's CPU
  in the window less its CPU with no client, per client.

Prints the Markdown tables that RESULTS.md records. Usage:
  bench.py BUILD_DIR VENV_PYTHON WORK_DIR [ROUNDS] [WINDOW_SECONDS]
"""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import select
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
CLIENT_COUNTS = (1, 4)
WARM_UP_S = 2.0
# Time for the clients to start, connect and subscribe before their window opens.
CONNECT_LEAD_S = 3.0
TICKS_PER_SECOND = os.sysconf("SC_CLK_TCK")
SERVERS = ("horus-view", "Foxglove SDK")


@dataclasses.dataclass
class Measured:
    """One server's window with `clients` clients in one round."""
    latencies_us: dict[str, list[float]]
    received_hz: dict[str, float]      # per client
    cpu_per_client: float              # fraction of one CPU, less the no-client window's


def cpu_seconds(pid: int) -> float:
    """utime + stime of the whole process (all its threads) so far."""
    fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    # Fields 14 and 15 of proc(5); fields[0] here is field 3.
    return (int(fields[11]) + int(fields[12])) / TICKS_PER_SECOND


def wait_line(process: subprocess.Popen, prefix: str, timeout: float = 30) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stdout], [], [], deadline - time.monotonic())
        if not ready:
            break
        line = process.stdout.readline()
        if not line:
            sys.exit(f"{process.args[:2]} ended (code {process.wait()}) before saying {prefix!r}")
        if line.startswith(prefix):
            return line.strip()
    sys.exit(f"{process.args[:2]} did not say {prefix!r} within {timeout} s")


class Side:
    """One server and its publisher, started for one round and stopped after it."""

    def __init__(self, name: str, build: pathlib.Path, venv_python: str,
                 work: pathlib.Path, round_number: int) -> None:
        self.children: list[subprocess.Popen] = []
        if name == "horus-view":
            shm = work / f"shm_{round_number}"
            shm.mkdir(mode=0o700)
            namespace = f"bench_view_{os.getpid()}_{round_number}"
            env = dict(os.environ, HORUS_SHM_DIR=str(shm), XDG_RUNTIME_DIR=str(shm),
                       HORUS_NAMESPACE=namespace,
                       PYTHONPATH=f"{build}/python:{build}/schemas/horus_gen/horus_msgs/python:"
                                  f"{HERE}")
            publisher = self.start(["/usr/bin/python3", str(HERE / "publish_horus.py")], env)
            wait_line(publisher, "publishing")
            server = self.start([str(build / "bridges/view/horus-view"), "serve", "--namespace",
                                 namespace, "--listen", "127.0.0.1", "--port", "0"], env)
        else:
            server = self.start([venv_python, str(HERE / "publish_sdk.py")],
                                dict(os.environ, PYTHONPATH=str(HERE)))
        self.url = wait_line(server, "ready ws://").split()[1]
        self.server_pid = server.pid

    def start(self, argv: list[str], env: dict[str, str]) -> subprocess.Popen:
        child = subprocess.Popen(argv, env=env, text=True, stdout=subprocess.PIPE,
                                 stderr=subprocess.DEVNULL)
        self.children.append(child)
        return child

    def stop(self) -> None:
        for child in reversed(self.children):
            child.terminate()
            try:
                child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()


def sleep_until_ns(when_ns: int) -> None:
    while (left := when_ns - time.time_ns()) > 0:
        time.sleep(left / 1e9)


def measure_clients(side: Side, venv_python: str, clients: int, window_s: float,
                    idle_cpu_per_s: float) -> tuple[Measured, dict]:
    start_ns = time.time_ns() + int(CONNECT_LEAD_S * 1e9)
    end_ns = start_ns + int(window_s * 1e9)
    running = [subprocess.Popen([venv_python, str(HERE / "client.py"), side.url, str(start_ns),
                                 str(end_ns)], text=True, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE) for _ in range(clients)]
    sleep_until_ns(start_ns)
    cpu_before, wall_before = cpu_seconds(side.server_pid), time.monotonic()
    sleep_until_ns(end_ns)
    cpu_after, wall_after = cpu_seconds(side.server_pid), time.monotonic()
    latencies: dict[str, list[float]] = {}
    received: dict[str, int] = {}
    channels: dict = {}
    for client in running:
        out, err = client.communicate(timeout=60)
        if client.returncode != 0:
            sys.exit(f"a client of {side.url} failed ({client.returncode}): {err.strip()}")
        result = json.loads(out)
        channels = result["channels"]
        for topic, values in result["latencies_us"].items():
            latencies.setdefault(topic, []).extend(values)
            received[topic] = received.get(topic, 0) + len(values)
    wall = wall_after - wall_before
    busy = (cpu_after - cpu_before) / wall - idle_cpu_per_s
    return Measured(latencies, {topic: count / clients / window_s
                                for topic, count in received.items()},
                    busy / clients), channels


def percentile(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


def check_same_streams(advertised: dict[str, dict]) -> None:
    """Both servers must advertise the same channels, or the comparison means nothing."""
    horus, sdk = (advertised[name] for name in SERVERS)
    for topic in ("cmd_vel", "camera"):
        for key in ("encoding", "schemaName", "schemaEncoding"):
            if horus[topic][key] != sdk[topic][key]:
                sys.exit(f"{topic}: horus-view advertises {key} {horus[topic][key]!r}, "
                         f"the SDK {sdk[topic][key]!r}")
    if json.loads(horus["cmd_vel"]["schema"]) != json.loads(sdk["cmd_vel"]["schema"]):
        sys.exit("cmd_vel: the two servers advertise different JSON Schemas for CmdVel")


def main() -> None:
    build, venv_python, work = pathlib.Path(sys.argv[1]), sys.argv[2], pathlib.Path(sys.argv[3])
    rounds = int(sys.argv[4]) if len(sys.argv) > 4 else 2
    window_s = float(sys.argv[5]) if len(sys.argv) > 5 else 10.0
    results: dict[tuple[str, int], list[Measured]] = {}
    idle: dict[str, list[float]] = {}
    advertised: dict[str, dict] = {}
    for round_number in range(rounds):
        for name in SERVERS:
            print(f"round {round_number + 1}: {name}", file=sys.stderr, flush=True)
            side = Side(name, build, venv_python, work, round_number)
            try:
                time.sleep(WARM_UP_S)
                cpu_before, wall_before = cpu_seconds(side.server_pid), time.monotonic()
                time.sleep(window_s)
                idle_per_s = ((cpu_seconds(side.server_pid) - cpu_before)
                              / (time.monotonic() - wall_before))
                idle.setdefault(name, []).append(idle_per_s)
                for clients in CLIENT_COUNTS:
                    measured, advertised[name] = measure_clients(side, venv_python, clients,
                                                                 window_s, idle_per_s)
                    results.setdefault((name, clients), []).append(measured)
            finally:
                side.stop()
    check_same_streams(advertised)
    report(results, idle, rounds, window_s)


def report(results: dict[tuple[str, int], list[Measured]], idle: dict[str, list[float]],
           rounds: int, window_s: float) -> None:
    print(f"{rounds} rounds of {window_s:.0f} s windows; latencies of all rounds and clients "
          "pooled; CPU per client the mean of the rounds; each round's CmdVel p50, CmdVel and "
          "image received per client, and CPU per client in the last column.")
    print()
    print("| clients | server | CmdVel p50 / p99 (µs) | image p50 / p99 (µs) | received per "
          "client: CmdVel / image (Hz) | server CPU per client (% of a CPU) | each round: CmdVel "
          "p50 (µs), received (Hz), CPU (%) |")
    print("|---|---|---|---|---|---|---|")
    summary: dict[tuple[str, int], dict[str, float]] = {}
    for clients in CLIENT_COUNTS:
        for name in SERVERS:
            runs = results[(name, clients)]
            row: dict[str, float] = {}
            cells = []
            for topic in ("cmd_vel", "camera"):
                pooled = [value for run in runs for value in run.latencies_us[topic]]
                row[f"{topic}_p50"] = percentile(pooled, 0.50)
                row[f"{topic}_p99"] = percentile(pooled, 0.99)
                cells.append(f"{row[f'{topic}_p50']:.0f} / {row[f'{topic}_p99']:.0f}")
            rates = [sum(run.received_hz[topic] for run in runs) / len(runs)
                     for topic in ("cmd_vel", "camera")]
            row["cpu"] = sum(run.cpu_per_client for run in runs) / len(runs)
            each = "; ".join(f"{percentile(run.latencies_us['cmd_vel'], 0.5):.0f}, "
                             f"{run.received_hz['cmd_vel']:.0f}/{run.received_hz['camera']:.1f}, "
                             f"{100 * run.cpu_per_client:.1f}" for run in runs)
            summary[(name, clients)] = row
            print(f"| {clients} | {name} | {cells[0]} | {cells[1]} | {rates[0]:.0f} / "
                  f"{rates[1]:.1f} | {100 * row['cpu']:.1f} | {each} |")
    print()
    print("| clients | horus-view / SDK | CmdVel p50 | CmdVel p99 | image p50 | image p99 | "
          "CPU per client |")
    print("|---|---|---|---|---|---|---|")
    for clients in CLIENT_COUNTS:
        horus, sdk = summary[(SERVERS[0], clients)], summary[(SERVERS[1], clients)]
        ratios = [horus[key] / sdk[key] for key in ("cmd_vel_p50", "cmd_vel_p99", "camera_p50",
                                                     "camera_p99", "cpu")]
        cells = [f"{ratio:.2f}x" if ratio >= 0.1 else f"{ratio:.3f}x" for ratio in ratios]
        print(f"| {clients} | ratio | " + " | ".join(cells) + " |")
    print()
    print("Goals: latency <= 1.0x, CPU <= 0.5x of the SDK's. Each server's CPU with no client "
          "(subtracted): " + "; ".join(
              f"{name} " + ", ".join(f"{100 * value:.1f}" for value in values) + " %"
              for name, values in idle.items()) + ".")


if __name__ == "__main__":
    main()
