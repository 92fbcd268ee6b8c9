"""The Foxglove SDK side: the same two streams as publish_horus.py, logged in this process to the
SDK's own WebSocket server (foxglove.start_server): CmdVel at 1 kHz on a json channel `cmd_vel`
with the JSON Schema horus-view advertises for horus.msg.CmdVel, and a 640x480 rgb8
foxglove.RawImage at 30 Hz on `camera` through the SDK's RawImageChannel (protobuf), each
stamped with CLOCK_REALTIME as it is made. Prints `ready ws://127.0.0.1:PORT/`;
runs until killed. Run in the benchmark's venv (foxglove-sdk, pinned by run.sh)."""
from __future__ import annotations

import json
import time

import foxglove
from foxglove.channels import RawImageChannel
from foxglove.messages import RawImage, Timestamp
from pacing import HEIGHT, WIDTH, run_paced

# horus-view's channel schema for horus.msg.CmdVel, as it advertises it; the benchmark checks
# that the two servers' advertisements are the same.
COMMAND_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "horus.msg.CmdVel",
    "type": "object",
    "properties": {
        "stamp_nanos": {"type": "string", "pattern": "^[0-9]+$", "description": "[ns]"},
        "linear": {"type": ["number", "null"], "description": "[m/s]"},
        "angular": {"type": ["number", "null"], "description": "[rad/s]"},
    },
    "required": ["stamp_nanos", "linear", "angular"],
    "additionalProperties": False,
}


def main() -> None:
    server = foxglove.start_server(name="bench_view", host="127.0.0.1", port=0)
    commands = foxglove.Channel("cmd_vel", message_encoding="json", schema=foxglove.Schema(
        name="horus.msg.CmdVel", encoding="jsonschema",
        data=json.dumps(COMMAND_SCHEMA, separators=(",", ":")).encode()))
    camera = RawImageChannel("camera")
    pixels = bytes([128]) * (WIDTH * HEIGHT * 3)

    def send_command() -> None:
        commands.log({"stamp_nanos": str(time.time_ns()), "linear": 1.5, "angular": -0.25})

    def send_image() -> None:
        stamp = time.time_ns()
        camera.log(RawImage(timestamp=Timestamp(stamp // 1_000_000_000, stamp % 1_000_000_000),
                            frame_id="camera", width=WIDTH, height=HEIGHT, encoding="rgb8",
                            step=WIDTH * 3, data=pixels))

    print(f"ready ws://127.0.0.1:{server.port}/", flush=True)
    run_paced(send_command, send_image)


if __name__ == "__main__":
    main()
