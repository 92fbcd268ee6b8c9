"""The streams both publishers send, and their pacing: one loop releasing a command every 1 ms
and an image every 1/30 s on absolute CLOCK_MONOTONIC deadlines (a late release does not shift
the ones after it)."""
from __future__ import annotations

import time
from typing import Callable

WIDTH, HEIGHT = 640, 480
COMMAND_PERIOD_NS = 1_000_000
IMAGE_PERIOD_NS = 1_000_000_000 // 30


def run_paced(send_command: Callable[[], None], send_image: Callable[[], None]) -> None:
    """Calls each at its rate until the process is killed."""
    next_command = next_image = time.monotonic_ns()
    while True:
        wait = min(next_command, next_image) - time.monotonic_ns()
        if wait > 0:
            time.sleep(wait / 1e9)
        now = time.monotonic_ns()
        if now >= next_command:
            send_command()
            next_command += COMMAND_PERIOD_NS
        if now >= next_image:
            send_image()
            next_image += IMAGE_PERIOD_NS
