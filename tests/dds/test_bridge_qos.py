"""Per-topic DDS QoS of `horus bridge` across two namespaces: --transient-local (a latched topic's
last message reaches a bridge that joins later) and --deadline (each missed deadline is a line
with a count, on the exporting side and on the importing side, which follows the writer)."""
from __future__ import annotations

import re
import threading

from processes import wait_line, wait_until
from test_bridge import HOLDER, PUBLISHER, bridge, python_env

# Sends one message on `latched`, then keeps the topic open.
SEND_ONCE = """
import time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "latched")
topic.send(CmdVel(stamp_nanos=42, linear=1.25))
print("ready", flush=True)
time.sleep(300)
"""


def test_a_latched_topic_reaches_a_bridge_that_joins_after_it_was_sent(
        dds_domain, worlds, children, generated):
    source, target = worlds
    publisher = children.python(SEND_ONCE, python_env(source, generated))
    wait_line(publisher, "ready")
    # The message is in A's topic before any bridge runs: the exporting bridge sends the newest
    # message of a latched topic when it starts, and its DDS writer keeps it for late readers.
    exporter = bridge(children, source, generated, dds_domain, "--export", "latched",
                      "--transient-local", "lat*")
    wait_line(exporter, "exporting 'latched'")
    holder = children.python(HOLDER, python_env(target, generated), "latched",
                             "horus.msg.CmdVel")
    wait_line(holder, "ready")
    # The importing bridge's reader is transient-local too: it follows the writer it finds.
    bridge(children, target, generated, dds_domain, "--import", "latched")
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0, errors
    assert "'stamp_nanos': 42" in out and "'linear': 1.25" in out, out


class Said:
    """The lines a bridge prints on stderr, collected by a thread of the test."""

    def __init__(self, process) -> None:
        self.lines: list[str] = []
        threading.Thread(target=self._read, args=(process,), daemon=True).start()

    def _read(self, process) -> None:
        for line in process.stderr:
            self.lines.append(line.rstrip("\n"))


MISSED = re.compile(r"horus bridge: topic 'cmd_vel': no message within its 200 ms deadline "
                    r"\(missed (\d+) times so far\)")


def missed_counts(said: Said) -> list[int]:
    counts = []
    for line in said.lines:
        match = MISSED.fullmatch(line)
        assert match, f"an unexpected line: {line!r}"
        counts.append(int(match.group(1)))
    return counts


def test_a_missed_deadline_is_a_line_with_a_count_on_both_sides(
        dds_domain, worlds, children, generated):
    source, target = worlds
    holder = children.python(HOLDER, python_env(target, generated), "cmd_vel",
                             "horus.msg.CmdVel")
    wait_line(holder, "ready")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", "cmd_vel")
    exporter = bridge(children, source, generated, dds_domain, "--export", "cmd_vel",
                      "--deadline", "cmd_*=200")
    said = {"exporter": Said(exporter), "importer": Said(importer)}
    # A message crosses: the importer's reader matched the writer's offered deadline.
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0 and "'stamp_nanos'" in out, errors
    publisher.kill()  # from now on nothing is sent: each side misses the deadline
    for side, lines in said.items():
        wait_until(lambda: len(missed_counts(lines)) >= 2, f"two deadline lines from the {side}",
                   limit=30)
        counts = missed_counts(lines)
        assert counts == sorted(set(counts)) and counts[0] >= 1, f"{side}: {lines.lines}"


def test_a_deadline_without_a_pattern_or_milliseconds_is_a_usage_error(worlds, generated):
    from test_bridge import horus_in
    for given in ("cmd_*=soon", "=5", "cmd_vel", "cmd_*=0"):
        result = horus_in(worlds[0], generated, "bridge", "--export", "cmd_*", "--deadline", given)
        assert result.returncode == 2 and result.stderr.strip().splitlines() == [
            f"horus: --deadline wants PATTERN=MS (a whole number of milliseconds, at least 1), "
            f"got {given!r}"], result.stderr
