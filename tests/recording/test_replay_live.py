"""Deterministic replay against the live run it replays (docs/recording.md): a live Python session
of a node publishing random values at 200 Hz and one folding whatever arrived into a running sum
at 70 Hz, on threads of their own, replayed into the folding node alone. Its outputs must be the
ones the live run recorded, byte for byte from its first tick, and again on a second replay. The
C++ pair is tests/unit/replay_live_test.cpp."""
from __future__ import annotations

import random

from mcap.reader import make_reader

from horus import Node, Scheduler


def _fold() -> Node:
    """Publishes its running sum every tick, also when nothing arrived: an input one tick late,
    or one tick too many, changes its outputs."""
    total = [0.0]

    def tick(node):
        while (value := node.recv("values")) is not None:
            total[0] += value
        node.send("sum", total[0])
    return Node(name="fold", tick=tick, rate=70, order=1, subs=["values"], pubs=["sum"])


def _messages(path, topic: str) -> list[bytes]:
    with open(path, "rb") as f:
        return [m.data for _, _, m in make_reader(f).iter_messages(topics=[topic],
                                                                   log_time_order=False)]


def test_a_replayed_python_node_gives_the_outputs_it_recorded_live_from_its_first_tick():
    live = Scheduler(recording=True)
    live.add(Node(name="source", tick=lambda node: node.send("values", random.random()),
                  rate=200, order=0, pubs=["values"]))
    live.add(_fold())
    # Real time: the fold starts once the source has run for a while, so its ticks fall in other
    # cycles than they do in a replay, and values arrive while it ticks.
    live.tick_for(0.05, ["source"])
    live.tick_for(1.0)
    [path] = live.stop_recording()
    recorded = _messages(path, "sum")
    assert len(recorded) >= 20
    assert len(_messages(path, "values")) > len(recorded)

    def replay() -> list[bytes]:
        again = Scheduler(deterministic=True, replay=path, recording=True)
        again.add(_fold())
        again.tick_for((len(recorded) + 3) / 70)  # simulated: a few ticks more than live
        [replayed] = again.stop_recording()
        return _messages(replayed, "sum")

    first = replay()
    assert len(first) > len(recorded)
    assert first[:len(recorded)] == recorded
    assert replay() == first
