"""The HORUS side's robot: CmdVel at 1 kHz on `cmd_vel` and a pool-backed 640x480 rgb8
horus::Image at 30 Hz on `camera`, in the namespace of HORUS_NAMESPACE, each stamped with
CLOCK_REALTIME as it is made (stamp_nanos, timestamp_ns). horus-view serves them.
Paced exactly as publish_sdk.py (pacing.py). Runs until killed."""
from __future__ import annotations

import time

import horus
import numpy as np
from horus.msg import CmdVel
from pacing import HEIGHT, WIDTH, run_paced


def main() -> None:
    commands = horus.Topic(CmdVel, "cmd_vel")
    camera = horus.Topic(horus.Image, "camera")
    pixels = np.full((HEIGHT, WIDTH, 3), 128, dtype=np.uint8)

    def send_command() -> None:
        commands.send(CmdVel(stamp_nanos=time.time_ns(), linear=1.5, angular=-0.25))

    def send_image() -> None:
        # Stamped before the frame is made, as publish_sdk.py stamps before its RawImage.
        stamp = time.time_ns()
        image = horus.Image.from_numpy(pixels)
        image.timestamp_ns = stamp
        camera.send(image)

    print("publishing", flush=True)
    run_paced(send_command, send_image)


if __name__ == "__main__":
    main()
