"""A hostile DDS participant on the bridge's domain (dds_attacker, a plain Cyclone program built
with idlc from attacker_idl/) writes other layouts under horus.msg.CmdVel's DDS type name on
rt/cmd_vel while a good writer (namespace A's exporting bridge) feeds the same topic: nothing of
the attacker reaches a HORUS subscriber in B, and B's bridge keeps carrying the good writer's
messages. A writer of a different type matches no bridge reader (DDS checks the type information
both announce); one that announces none is refused in one line, or taken on trust under
--accept-untyped-writers, and then each (writer, reason) of its bad samples is one line, the rest
a count."""
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


def test_bad_samples_of_an_accepted_untyped_writer_are_one_line_and_a_count(
        dds_domain, worlds, children, generated, dds_attacker):
    subscriber, importer, received = _start(children, worlds, generated, dds_domain,
                                            "--accept-untyped-writers")
    _attack(children, dds_attacker, dds_domain, "longer", "500", "--untyped")
    after = _after_the_attack(subscriber, received)
    assert [m for m in received if not _good(m)] == []
    assert after == list(range(after[0], after[0] + AFTER)), f"the good writer's: {after}"
    said = _stop(importer)

    trusted = [line for line in said if "taking its" in line]
    match = re.fullmatch(
        r"horus bridge: topic 'cmd_vel': DDS writer ([0-9a-f]{32}) announces no type "
        r"information: taking its horus::msg::dds_::CmdVel_ on trust \(--accept-untyped-writers\)",
        trusted[0]) if len(trusted) == 1 else None
    assert match, said
    writer = match[1]
    first = [line for line in said if "a DDS sample from writer" in line]
    assert first == [
        f"horus bridge: topic 'cmd_vel': a DDS sample from writer {writer} does not decode: a "
        "CDR sample does not decode as horus.msg.CmdVel: 8 bytes are left over (failure 1 of "
        "it); dropped it, and more of the same from that writer are counted, not said"], said
    counts = [re.fullmatch(r"horus bridge: topic 'cmd_vel': dropped (\d+) more DDS samples for "
                           r"reasons said before \((\d+) failures of it so far\)", line)
              for line in said if line not in trusted + first]
    assert counts and all(counts), said
    # Every bad sample is counted, in a few lines (one every 5 s at most, and the rest at exit).
    assert sum(int(match[1]) for match in counts) == 499 and counts[-1][2] == "500", said
    assert len(counts) <= 3, said


def test_the_python_threads_say_each_writer_and_reason_once_and_count_the_rest(
        monkeypatch, capsys):
    import horus_bridge
    clock = [100.0]
    monkeypatch.setattr(horus_bridge.time, "monotonic", lambda: clock[0])
    drops = horus_bridge._DropReport("topic 'kinds'")
    # 500 samples of one writer over 10 s, each a different size: one reason.
    for failure in range(1, 501):
        drops.dropped("w1", f"does not decode: {failure} bytes are left over", failure)
        clock[0] += 0.02
    drops.dropped("w2", "does not decode: 8 bytes are left over", 501)
    drops.due(501, now=float("inf"))

    said = capsys.readouterr().err.splitlines()
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
