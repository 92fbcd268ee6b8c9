"""A bridge that fails or is restarted carries on: restarted mid-stream, the importing side
resumes in order, with the gap of what was sent while no exporting bridge ran visible in the
sequence numbers (never a duplicate); a DDS sample that does not decode is one line on stderr
with its count, and the topic's next sample still arrives."""
from __future__ import annotations

import re
import signal
import threading

import pytest

from processes import wait_line, wait_until
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
    # Two restarts: the messages sent while no exporting bridge ran are missing, and a new DDS
    # writer may lose a few more just after its first sample while discovery completes on the
    # reader's side (a volatile reader; docs/dds-bridge.md "Not done yet"): two gaps a restart.
    assert len(gaps) <= 4, f"messages lost while a bridge ran: {gaps}"


# Writes rt/<topic> as a plain DDS program would (no HORUS identity, the type information idlc
# gives its IDL, as the C++ bridge spells it): a sample cut short, then a good one, once the importing bridge's reader matches.
BAD_THEN_GOOD = """
import sys, time
from horus._core import dds as _dds
from horus.msg import CmdVel
import dds_cdr
from dds_test import Kinds
domain, topic = int(sys.argv[1]), sys.argv[2]
good, dds_type = {
    "kinds": (Kinds(big=7, name="after the bad one"), "dds_test::dds_::Kinds_"),
    "cmd_vel": (CmdVel(stamp_nanos=7, linear=2.5), "horus::msg::dds_::CmdVel_")}[topic]
participant = _dds.Participant(domain)
info = type(good).__horus__
_, type_info, type_map = _dds.type_on_wire(info.description)
writer = _dds.Writer(participant, "rt/" + topic, dds_type, type_info=type_info,
                     type_map=type_map)
deadline = time.monotonic() + 30
while writer.matched() == 0 and time.monotonic() < deadline:
    time.sleep(0.02)
cdr = dds_cdr.CdrCodec(type(good)).encode(good)
writer.write(cdr[:9])
writer.write(cdr)
time.sleep(2)  # reliable delivery before the writer goes
"""


# kinds is serialized (the bridge's Python thread), cmd_vel POD (its C++ pump, whose CdrPlan
# says how far the body reached).
@pytest.mark.parametrize("topic, type_name, good, reason", [
    ("kinds", "dds_test.Kinds", "'name': 'after the bad one'", ""),
    ("cmd_vel", "horus.msg.CmdVel", "'linear': 2.5",
     "8 bytes wanted at offset 8 of a 8-byte body")])
def test_a_sample_that_does_not_decode_is_one_line_and_the_topic_carries_on(
        topic, type_name, good, reason, dds_domain, worlds, children, generated):
    from test_bridge import HOLDER
    target = worlds[1]
    holder = children.python(HOLDER, python_env(target, generated), topic, type_name)
    wait_line(holder, "ready")
    importer = bridge(children, target, generated, dds_domain, "--import", topic)
    writer = children.python(BAD_THEN_GOOD, python_env(target, generated), str(dds_domain),
                             topic)
    out, errors = holder.communicate(timeout=60)
    assert holder.returncode == 0 and good in out, errors
    writer.communicate(timeout=30)
    importer.send_signal(signal.SIGTERM)
    _, said = importer.communicate(timeout=30)
    assert importer.returncode == 0, said
    lines = said.splitlines()
    assert len(lines) == 1 and re.match(
        f"horus bridge: topic '{topic}': a DDS sample from writer [0-9a-f]{{32}} does not decode: "
        f"a CDR sample does not decode as {re.escape(type_name)}: {reason}",
        lines[0]) and lines[0].endswith(
        "(failure 1 of it); dropped it, and more of the same from that writer are counted, not "
        "said"), said
