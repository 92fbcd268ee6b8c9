#!/usr/bin/python3
"""The Python subscriber of the four-process launch (tests/launch/test_launch_demo.py,
fourproc.yaml): reads the C++ talker's CmdVel on "fourproc.cmd" (linear = 1, 2, 3, ...), prints
"fourproc listener steady: N in order" once N messages came one after the other, and runs until
SIGINT or SIGTERM, as a launched process does, then prints how many it received."""
import signal
import sys
import time

import horus
from horus.msg import CmdVel

STEADY_AFTER = 20  # messages in a row, none lost or out of order

print(f"fourproc listener started at {time.monotonic_ns()}", flush=True)
stopping = False


def request_stop(_signal, _frame) -> None:
    global stopping
    stopping = True


signal.signal(signal.SIGINT, request_stop)
signal.signal(signal.SIGTERM, request_stop)
topic = horus.Topic(CmdVel, "fourproc.cmd")
received = in_a_row = 0
previous = None
while not stopping:
    message = topic.recv(timeout=0.1)
    if message is None:
        continue
    received += 1
    in_a_row = in_a_row + 1 if previous is not None and message.linear == previous + 1 else 1
    previous = message.linear
    if in_a_row == STEADY_AFTER:
        print(f"fourproc listener steady: {STEADY_AFTER} in order", flush=True)
print(f"fourproc listener stopped: {received} received", flush=True)
sys.exit(0)
