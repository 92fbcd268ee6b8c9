"""An authenticated peer that attacks the robot (test_attacks.py), written with pycapnp from
bridges/remote/remote.capnp alone, as any third party could: nothing of HORUS's own code.

    attacker.py SCHEMA PORT CERTS subscribe COUNT HOLD
        COUNT subscriptions to cmd_vel at once, then a tenth as many to a topic that does not
        exist and to generic as a CmdVel; prints "granted G refused R", holds what it was granted HOLD seconds,
        drops it all and prints "dropped".
    attacker.py SCHEMA PORT CERTS publish COUNT
        COUNT publishes to cmd_vel with another type name, another fingerprint, another size
        and bytes that are no type description each, COUNT messages of the wrong size, then one
        message of zeros of the right size (which a subscriber on the robot may get), then one
        over the connection's limit; prints "refused TYPE FINGERPRINT SIZE DESCRIPTION
        MESSAGES" before the last.
    attacker.py SCHEMA PORT CERTS stall
        5 subscriptions to every topic it may read, into a Sink that never answers (the
        robot's streams fill and stall); prints "granted G refused R", and holds them.
    attacker.py SCHEMA PORT CERTS outside TOPIC
        one subscription to TOPIC, which the policy does not let it read; prints "refused" (or
        "granted") and ends its connection.
"""
from __future__ import annotations

import asyncio
import os
import ssl
import sys

import capnp

SCHEMA, PORT, CERTS, MODE = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
remote = capnp.load(SCHEMA, imports=[os.path.dirname(os.path.dirname(capnp.__file__))])


class Sink(remote.Sink.Server):
    """Takes whatever the robot streams, and forgets it."""

    async def message(self, sequence, dropped, data, **kwargs):
        return None


class StalledSink(remote.Sink.Server):
    """Never acknowledges a message: the robot must not keep more for it than its bounds."""

    async def message(self, sequence, dropped, data, **kwargs):
        await asyncio.sleep(3600)


async def refused(calls) -> tuple[list, int]:
    """The answers of `calls` that succeeded, and how many failed."""
    answers = await asyncio.gather(*calls, return_exceptions=True)
    granted = [a for a in answers if not isinstance(a, BaseException)]
    return granted, len(answers) - len(granted)


def info_of(template, **changes):
    return remote.TopicInfo.new_message(**{**template.to_dict(), **changes})


async def subscribe(session, cmd_vel, count: int, hold: float) -> None:
    sink = Sink()
    calls = [session.subscribe(topic="cmd_vel", type=cmd_vel.type, fingerprint=cmd_vel.fingerprint,
                               sink=sink, queue=1024) for _ in range(count)]
    calls += [session.subscribe(topic="no_such_topic", type=cmd_vel.type,
                                fingerprint=cmd_vel.fingerprint, sink=sink, queue=1)
              for _ in range(count // 10)]
    calls += [session.subscribe(topic="generic", type=cmd_vel.type,
                                fingerprint=cmd_vel.fingerprint, sink=sink, queue=1)
              for _ in range(count // 10)]
    granted, failed = await refused(calls)
    print(f"granted {len(granted)} refused {failed}", flush=True)
    await asyncio.sleep(hold)
    granted.clear()
    print("dropped", flush=True)
    await asyncio.sleep(1.0)


async def publish(session, cmd_vel, count: int) -> None:
    wrong = {"type": {"type": "horus.msg.Fake"}, "fingerprint": {"fingerprint": 12345},
             "size": {"maxMessageSize": cmd_vel.maxMessageSize + 8},
             "description": {"description": b"\x92\x01\x02"}}
    counts = []
    for changes in wrong.values():
        _, failed = await refused([session.publish(info=info_of(cmd_vel, **changes))
                                   for _ in range(count)])
        counts.append(failed)
    bad_messages = 0
    for _ in range(count):
        sink = (await session.publish(info=info_of(cmd_vel))).sink
        try:
            await sink.message(sequence=0, dropped=0, data=b"\xab" * (cmd_vel.maxMessageSize + 1))
        except capnp.KjException:
            bad_messages += 1
    sink = (await session.publish(info=info_of(cmd_vel))).sink
    await sink.message(sequence=0, dropped=0, data=bytes(cmd_vel.maxMessageSize))
    print("refused", *counts, bad_messages, flush=True)
    # 9 MiB: over the 8 MiB the robot reads from a peer that may write only small topics.
    try:
        await sink.message(sequence=1, dropped=0, data=bytes(9 << 20))
    except capnp.KjException:
        pass
    await asyncio.sleep(1.0)


async def stall(session, topics) -> None:
    sink = StalledSink()
    granted, failed = await refused(
        [session.subscribe(topic=topic.name, type=topic.type, fingerprint=topic.fingerprint,
                           sink=sink, queue=1024) for topic in topics for _ in range(5)])
    print(f"granted {len(granted)} refused {failed}", flush=True)
    await asyncio.sleep(3600)


async def main() -> None:
    tls = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=f"{CERTS}/ca.crt")
    tls.load_cert_chain(f"{CERTS}/attacker.crt", f"{CERTS}/attacker.key")
    stream = await capnp.AsyncIoStream.create_connection(host="127.0.0.1", port=PORT, ssl=tls,
                                                         server_hostname="robot")
    session = capnp.TwoPartyClient(stream).bootstrap().cast_as(remote.Session)
    topics = (await session.topics()).topics
    if MODE == "outside":
        _, failed = await refused([session.subscribe(topic=sys.argv[5], type="horus.msg.CmdVel",
                                                     fingerprint=1, sink=Sink(), queue=1)])
        print("refused" if failed else "granted", flush=True)
        return
    if MODE == "stall":
        await stall(session, topics)
        return
    cmd_vel = next(topic for topic in topics if topic.name == "cmd_vel")
    if MODE == "subscribe":
        await subscribe(session, cmd_vel, int(sys.argv[5]), float(sys.argv[6]))
    else:
        await publish(session, cmd_vel, int(sys.argv[5]))


asyncio.run(capnp.run(main()))
