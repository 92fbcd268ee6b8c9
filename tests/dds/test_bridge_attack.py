"""A hostile DDS participant on the bridge's domain (dds_attacker, a plain Cyclone program built
with idlc from attacker_idl/) writes other layouts under horus.msg.CmdVel's DDS type name on
rt/cmd_vel while a good writer (namespace A's exporting bridge) feeds the same topic: nothing of
the attacker reaches a HORUS subscriber in B, and B's bridge keeps carrying the good writer's
messages. A writer of a different type matches no bridge reader (DDS checks the type information
both announce); one that announces none is refused in one line, or taken on trust under
--accept-untyped-writers, and then each (writer, reason) of its bad samples (a field more, or
cut short) is one line, the rest a count; writers past the report's cap (a small one here, through
HORUS_BRIDGE_DROP_REPORT_CAP) are counted as other writers', not said. The report itself
(horus._core.dds.DropReport, the C++ pumps' and the Python threads') is tested with a clock of
the test's."""
from __future__ import annotations

import re
import signal

import pytest

from processes import wait_line
from test_bridge import bridge, python_env

# The good writer: CmdVel(stamp_nanos=i, linear=0.5 * i, angular=-1), 100 a second, until killed;
# angular=+1 once the file argv[1] exists (sent after the attack: what comes after its samples).
PUBLISHER = """
import os, sys, time, horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel")
print("ready", flush=True)
i = 0
while True:
    after = os.path.exists(sys.argv[1])
    topic.send(CmdVel(stamp_nanos=i, linear=0.5 * i, angular=1.0 if after else -1.0))
    i += 1
    time.sleep(0.01)
"""
AFTER = 30  # good messages sent after the attack that the subscriber must get

# Prints each cmd_vel message as "stamp linear angular" until killed.
SUBSCRIBER = """
import horus
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "cmd_vel", capacity=1024)
print("ready", flush=True)
while True:
    message = topic.recv(timeout=60)
    print(message.stamp_nanos, message.linear, message.angular, flush=True)
"""


def _start(children, worlds, generated, domain: int, *import_options: str):
    """B's subscriber and importing bridge, A's publisher and exporting bridge; returns the
    subscriber, the importing bridge and the messages received, once the first good one has."""
    source, target = worlds
    subscriber = children.python(SUBSCRIBER, python_env(target, generated))
    wait_line(subscriber, "ready")
    importer = bridge(children, target, generated, domain, "--import", "cmd_vel",
                      *import_options)
    publisher = children.python(PUBLISHER, python_env(source, generated), "attacked")
    wait_line(publisher, "ready")
    bridge(children, source, generated, domain, "--export", "cmd_vel")
    return subscriber, importer, [_message(wait_line(subscriber, ""))]


def _message(line: str) -> tuple[int, float, float]:
    stamp, linear, angular = line.split()
    return int(stamp), float(linear), float(angular)


def _attack(children, dds_attacker, domain: int, *argv: str) -> None:
    attacker = children.start([dds_attacker, *argv[:1], str(domain), *argv[1:]])
    out, errors = attacker.communicate(timeout=60)
    assert attacker.returncode == 0 and "wrote" in out, errors


def _good(message: tuple[int, float, float]) -> bool:
    stamp, linear, angular = message
    return linear == 0.5 * stamp and angular in (-1.0, 1.0)


def _after_the_attack(subscriber, received: list) -> list[int]:
    """Has the publisher mark what it sends from now on, and reads what the subscriber got until
    AFTER such messages have come; their stamps."""
    with open("attacked", "w"):
        pass
    after = []
    while len(after) < AFTER:
        received.append(_message(wait_line(subscriber, "")))
        if received[-1][2] == 1.0:
            after.append(received[-1][0])
    return after


def _stop(importer) -> list[str]:
    importer.send_signal(signal.SIGTERM)
    _, said = importer.communicate(timeout=30)
    assert importer.returncode == 0, said
    return said.splitlines()


@pytest.mark.parametrize("typing", ["typed", "untyped"])
def test_a_same_size_writer_of_another_type_delivers_nothing(
        typing, dds_domain, worlds, children, generated, dds_attacker):
    subscriber, importer, received = _start(children, worlds, generated, dds_domain)
    options = ["--untyped"] if typing == "untyped" else []
    _attack(children, dds_attacker, dds_domain, "same-size", "100", *options)
    after = _after_the_attack(subscriber, received)

    wrong = [m for m in received if not _good(m)]
    assert wrong == [], f"the attacker's samples reached the subscriber: {wrong[:5]}"
    assert after == list(range(after[0], after[0] + AFTER)), f"the good writer's: {after}"
    said = _stop(importer)
    if typing == "typed":
        # A type DDS finds not assignable never matches: no sample, nothing to say.
        assert said == [], said
    else:
        assert len(said) == 1 and re.fullmatch(
            r"horus bridge: cannot import topic 'cmd_vel' from DDS writer [0-9a-f]{32}: it "
            r"announces no type information, .*--accept-untyped-writers takes such writers on "
            r"trust\)", said[0]), said


TRUSTED = (r"horus bridge: topic 'cmd_vel': DDS writer ([0-9a-f]{32}) announces no type "
           r"information: taking its horus::msg::dds_::CmdVel_ on trust "
           r"\(--accept-untyped-writers\)")
DECODE = "does not decode: a CDR sample does not decode as horus.msg.CmdVel: "


# A field more (the decoder finds bytes left over) and a sample cut short (its body ends within
# CmdVel's two floats, which the pump's plan reads as one 8-byte step).
@pytest.mark.parametrize("kind, count, reason", [
    ("longer", 500, "8 bytes are left over"),
    ("shorter", 200, "8 bytes wanted at offset 8 of a 12-byte body")])
def test_bad_samples_of_an_accepted_untyped_writer_are_one_line_and_a_count(
        kind, count, reason, dds_domain, worlds, children, generated, dds_attacker):
    subscriber, importer, received = _start(children, worlds, generated, dds_domain,
                                            "--accept-untyped-writers")
    _attack(children, dds_attacker, dds_domain, kind, str(count), "--untyped")
    after = _after_the_attack(subscriber, received)
    assert [m for m in received if not _good(m)] == []
    assert after == list(range(after[0], after[0] + AFTER)), f"the good writer's: {after}"
    said = _stop(importer)

    trusted = [line for line in said if "taking its" in line]
    match = re.fullmatch(TRUSTED, trusted[0]) if len(trusted) == 1 else None
    assert match, said
    writer = match[1]
    first = [line for line in said if "a DDS sample from writer" in line]
    assert first == [
        f"horus bridge: topic 'cmd_vel': a DDS sample from writer {writer} {DECODE}{reason} "
        "(failure 1 of it); dropped it, and more of the same from that writer are counted, not "
        "said"], said
    counts = [re.fullmatch(r"horus bridge: topic 'cmd_vel': dropped (\d+) more DDS samples for "
                           r"reasons said before \((\d+) failures of it so far\)", line)
              for line in said if line not in trusted + first]
    assert counts and all(counts), said
    # Every bad sample is counted, in a few lines (one every 5 s at most, and the rest at exit).
    assert sum(int(match[1]) for match in counts) == count - 1, said
    assert counts[-1][2] == str(count) and len(counts) <= 3, said


def _count(line: str, topic: str) -> tuple[int, int, int] | None:
    """A count line's samples for reasons said before, of other writers (past the report's cap),
    and the topic's failures so far; None for another line."""
    match = re.fullmatch(rf"horus bridge: topic '{topic}': dropped (\d+) more DDS samples(?:, "
                         r"(\d+))? for reasons said before(?: and (\d+) of other writers)? "
                         r"\((\d+) failures of it so far\)", line)
    if match is None or (match[2] is None) != (match[3] is None):
        return None
    before, others = (int(match[1]), 0) if match[2] is None else (int(match[2]), int(match[3]))
    return (before, others, int(match[4])) if before + others == int(match[1]) else None


CAP = 4  # the drop report's cap the next test sets (HORUS_BRIDGE_DROP_REPORT_CAP)
WRITERS, EACH = 10, 20


def test_writers_past_the_cap_of_the_drop_report_are_counted_not_said(
        monkeypatch, dds_domain, worlds, children, generated, dds_attacker):
    monkeypatch.setenv("HORUS_BRIDGE_DROP_REPORT_CAP", str(CAP))  # the bridges' environment
    subscriber, importer, received = _start(children, worlds, generated, dds_domain,
                                            "--accept-untyped-writers")
    _attack(children, dds_attacker, dds_domain, "longer", str(EACH), "--untyped", "--writers",
            str(WRITERS))
    after = _after_the_attack(subscriber, received)
    assert [m for m in received if not _good(m)] == []
    assert after == list(range(after[0], after[0] + AFTER)), f"the good writer's: {after}"
    said = _stop(importer)

    trusted = [line for line in said if re.fullmatch(TRUSTED, line)]
    first = [re.fullmatch(rf"horus bridge: topic 'cmd_vel': a DDS sample from writer "
                          rf"([0-9a-f]{{32}}) {re.escape(DECODE)}8 bytes are left over \(failure \d+ of "
                          r"it\); dropped it, and more of the same from that writer are counted, "
                          r"not said", line) for line in said if "a DDS sample from writer" in line]
    # CAP writers said, each once; the next sample of another writer says the cap, once.
    assert len(first) == CAP and all(first) and len({m[1] for m in first}) == CAP, said
    full = [line for line in said if "its most" in line]
    assert len(full) == 1 and re.fullmatch(
        rf"horus bridge: topic 'cmd_vel': a DDS sample {re.escape(DECODE)}8 bytes are left over \(failure "
        rf"\d+ of it\); dropped it: this topic has said {CAP} writers and reasons, its most, so "
        r"the samples of others are counted as other writers', not said", full[0]), said
    # The writers taken on trust: CAP said, one by one, then the rest only counted.
    assert len(trusted) == CAP, said
    unsaid = [line for line in said if "taken on trust were said" in line]
    assert unsaid == [f"horus bridge: {CAP} DDS writers refused or taken on trust were said, the "
                      "most the bridge keeps (HORUS_BRIDGE_DROP_REPORT_CAP): further ones are "
                      "not"], said
    counts = [_count(line, "cmd_vel") for line in said
              if line not in trusted + unsaid and "a DDS sample" not in line]
    assert counts and all(counts) and len(counts) <= 3, said
    # The said writers' other samples, and all the others' but the one that said the cap.
    assert sum(before for before, _, _ in counts) == CAP * (EACH - 1), said
    assert sum(others for _, others, _ in counts) == (WRITERS - CAP) * EACH - 1, said
    assert counts[-1][2] == WRITERS * EACH, said


def _lines(said: list[str]) -> list[str]:
    """What a thread says of `said` (DropReport's lines; "" for none), as a topic's lines."""
    return [f"horus bridge: topic 'kinds': {line}" for line in said if line]


def test_the_drop_report_says_each_writer_and_reason_once_and_counts_the_rest():
    from horus._core import dds as _dds
    clock = 100.0
    drops = _dds.DropReport()
    said = []
    # 500 samples of one writer over 10 s, each a different size: one reason.
    for failure in range(1, 501):
        said.append(drops.dropped("w1", f"does not decode: {failure} bytes are left over",
                                  failure, clock))
        clock += 0.02
    said.append(drops.dropped("w2", "does not decode: 8 bytes are left over", 501, clock))
    said.append(drops.due(501, float("inf")))

    said = _lines(said)
    prefix = "horus bridge: topic 'kinds': "
    assert said[0] == (f"{prefix}a DDS sample from writer w1 does not decode: 1 bytes are left "
                       "over (failure 1 of it); dropped it, and more of the same from that "
                       "writer are counted, not said")
    assert said[2] == (f"{prefix}a DDS sample from writer w2 does not decode: 8 bytes are left "
                       "over (failure 501 of it); dropped it, and more of the same from that "
                       "writer are counted, not said")
    counts = [re.fullmatch(rf"{prefix}dropped (\d+) more DDS samples for reasons said before "
                           r"\((\d+) failures of it so far\)", line)
              for line in said[1:2] + said[3:]]
    assert len(said) == 4 and all(counts), said
    assert sum(int(match[1]) for match in counts) == 499, said
    assert drops.kept == 2 and _dds.DropReport.EVERY_S == 5.0


def test_the_drop_report_keeps_cap_writers_and_reasons_and_counts_others_as_other_writers():
    from horus._core import dds as _dds
    drops = _dds.DropReport(cap=3)
    said = []
    failure = 0
    # 100 writers, each with two reasons: a participant making writers without end.
    for writer in range(100):
        for reason in ("does not decode: 8 bytes are left over", "was refused"):
            failure += 1
            said.append(drops.dropped(f"w{writer}", reason, failure, 1000.0 + failure))
    # A writer past WriterGuids' cap (its GUID not looked up), and one said before.
    said.append(drops.dropped(None, "does not decode: 8 bytes are left over", 201, 2000.0))
    said.append(drops.dropped("w0", "was refused", 202, 2000.0))
    said.append(drops.due(202, float("inf")))

    said = _lines(said)
    prefix = "horus bridge: topic 'kinds': "
    assert drops.kept == 3 and _dds.DropReport.CAP == 1024
    assert said[:3] == [
        f"{prefix}a DDS sample from writer w0 does not decode: 8 bytes are left over (failure "
        "1 of it); dropped it, and more of the same from that writer are counted, not said",
        f"{prefix}a DDS sample from writer w0 was refused (failure 2 of it); dropped it, and "
        "more of the same from that writer are counted, not said",
        f"{prefix}a DDS sample from writer w1 does not decode: 8 bytes are left over (failure "
        "3 of it); dropped it, and more of the same from that writer are counted, not said"]
    assert said[3] == (f"{prefix}a DDS sample was refused (failure 4 of it); dropped it: this "
                       "topic has said 3 writers and reasons, its most, so the samples of others "
                       "are counted as other writers', not said")
    counts = [_count(line, "kinds") for line in said[4:]]
    assert counts and all(counts), said
    # Counted every 5 s of the clock: about 200 s of drops, a line per 5 s at most.
    assert len(counts) <= 200 // 5 + 2 and counts[-1][2] == 202, said
    assert sum(before for before, _, _ in counts) == 1, said  # w0's refusal, said before
    assert sum(others for _, others, _ in counts) == 202 - 4 - 1, said
