"""One Foxglove WebSocket client, the same for both servers: subscribes to `cmd_vel` and `camera`,
stamps each message's arrival with CLOCK_REALTIME and subtracts the publish time the message
carries (CmdVel's stamp_nanos in its JSON; the RawImage's timestamp, protobuf field 1). Keeps the
messages that arrive between START_NS and END_NS (CLOCK_REALTIME), so that every client of a run
measures the same window as the server's CPU, and prints one JSON object: per topic, the
latencies in microseconds, and how its channel was advertised (so that the benchmark can check
that both servers serve the same streams).

Usage: client.py URL START_NS END_NS
"""
from __future__ import annotations

import asyncio
import json
import struct
import sys
import time

from websockets.asyncio.client import connect

TOPICS = ("cmd_vel", "camera")
MESSAGE_DATA = 0x01
PAYLOAD_AT = 13  # opcode (1 byte), subscription id (u32), receive time (u64)
# The one the SDK's server speaks (it refuses foxglove.websocket.v1); horus-view speaks both.
SUBPROTOCOL = "foxglove.sdk.v1"


def varint(data: bytes, at: int) -> tuple[int, int]:
    """The base-128 varint at `at`; (its value, the index after it)."""
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, at
        shift += 7


def image_stamp_ns(message: bytes, at: int) -> int:
    """foxglove.RawImage's timestamp (field 1, google.protobuf.Timestamp), read in place from
    the payload at `at` (both servers write it first; the pixels are not copied)."""
    if message[at] != 0x0A:
        raise ValueError(f"RawImage: expected the timestamp first, found tag byte {message[at]:#x}")
    size, at = varint(message, at + 1)
    end = at + size
    seconds = nanos = 0
    while at < end:
        tag, at = varint(message, at)
        value, at = varint(message, at)
        if tag == 0x08:
            seconds = value
        elif tag == 0x10:
            nanos = value
    return seconds * 1_000_000_000 + nanos


def command_stamp_ns(message: bytes, at: int) -> int:
    # Both servers write u64 as a string of digits (a JSON number is a double).
    return int(json.loads(message[at:])["stamp_nanos"])


async def measure(url: str, start_ns: int, end_ns: int) -> dict:
    latencies: dict[str, list[float]] = {topic: [] for topic in TOPICS}
    advertised: dict[str, dict] = {}
    async with connect(url, subprotocols=[SUBPROTOCOL], max_size=None,
                       compression=None, ping_interval=None, max_queue=None) as socket:
        stamp_of: dict[int, tuple[str, object]] = {}
        channels: dict[str, int] = {}
        while len(channels) < len(TOPICS):
            message = await asyncio.wait_for(socket.recv(), timeout=20)
            if isinstance(message, str) and (parsed := json.loads(message))["op"] == "advertise":
                for channel in parsed["channels"]:
                    if channel["topic"] in TOPICS:
                        channels[channel["topic"]] = channel["id"]
                        advertised[channel["topic"]] = {
                            key: channel[key]
                            for key in ("encoding", "schemaName", "schemaEncoding", "schema")}
        subscriptions = []
        for number, topic in enumerate(TOPICS, start=1):
            subscriptions.append({"id": number, "channelId": channels[topic]})
            stamp_of[number] = (topic, command_stamp_ns if topic == "cmd_vel" else image_stamp_ns)
        await socket.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        while True:
            message = await socket.recv()
            arrived = time.time_ns()
            if arrived >= end_ns:
                return {"latencies_us": latencies, "channels": advertised}
            if isinstance(message, str) or message[0] != MESSAGE_DATA or arrived < start_ns:
                continue
            (subscription,) = struct.unpack_from("<I", message, 1)
            topic, stamp = stamp_of[subscription]
            latencies[topic].append((arrived - stamp(message, PAYLOAD_AT)) / 1000)


def main() -> None:
    url, start_ns, end_ns = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    print(json.dumps(asyncio.run(measure(url, start_ns, end_ns))))


if __name__ == "__main__":
    main()
