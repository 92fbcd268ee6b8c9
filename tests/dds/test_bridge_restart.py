"""A bridge restarted mid-stream: the importing side resumes, in order, with the gap of what was
sent while no exporting bridge ran visible in the sequence numbers (never a duplicate)."""
from __future__ import annotations

import signal
import threading

from conftest import wait_line, wait_until
from test_bridge import PUBLISHER, bridge, python_env

# Prints each cmd_vel stamp as it arrives, until killed.
STREAMER = """
import horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel")
print("ready", flush=True)
while True:
    message = topic.recv(timeout=1.0)
    if message is not None:
        print(message.stamp_nanos, flush=True)
"""

MORE = 20  # messages each exporting bridge must carry before it is stopped


class Stamps:
    """The stamps a streaming subscriber prints, collected by a thread of the test."""

    def __init__(self, process) -> None:
        self.seen: list[int] = []
        self._thread = threading.Thread(target=self._read, args=(process,), daemon=True)
        self._thread.start()

    def _read(self, process) -> None:
        for line in process.stdout:
            self.seen.append(int(line))

    def more_than(self, count: int):
        return lambda: len(self.seen) >= count + MORE


def test_an_exporting_bridge_stopped_or_killed_and_restarted_resumes_in_order(
        dds_domain, worlds, children, generated):
    source, target = worlds
    subscriber = children.python(STREAMER, python_env(target, generated))
    wait_line(subscriber, "ready")
    stamps = Stamps(subscriber)
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    bridge(children, target, generated, dds_domain, "--import", "*")

    for stop in (signal.SIGTERM, signal.SIGKILL, None):
        before = len(stamps.seen)
        exporter = bridge(children, source, generated, dds_domain, "--export", "cmd_vel")
        wait_until(stamps.more_than(before), f"{MORE} messages through exporting bridge "
                   f"#{len(stamps.seen)}", limit=30)
        if stop is not None:
            exporter.send_signal(stop)
            _, errors = exporter.communicate(timeout=30)
            if stop == signal.SIGTERM:
                assert exporter.returncode == 0 and errors == "", errors
            else:
                assert exporter.returncode == -signal.SIGKILL

    seen = list(stamps.seen)
    assert all(a < b for a, b in zip(seen, seen[1:])), f"duplicated or reordered: {seen}"
    gaps = [(a, b) for a, b in zip(seen, seen[1:]) if b != a + 1]
    # Two restarts: the messages sent while no exporting bridge ran are missing, at most twice.
    assert len(gaps) <= 2, f"messages lost while a bridge ran: {gaps}"
