"""A process for test_launch_run.py to launch: says "ready NAME PID" on stdout and a line on stderr,
appends "start NAME" / "stop NAME" to a journal (the order processes started and stopped in), and
runs until SIGINT, unless told to end, crash, hold a topic or a child of its own, or ignore SIGINT.
"""
import argparse
import os
import signal
import subprocess
import sys
import time

parser = argparse.ArgumentParser()
parser.add_argument("name")
parser.add_argument("--journal", help="file the start and the stop are appended to")
parser.add_argument("--exit", type=int, help="end with this status after --after seconds")
parser.add_argument("--after", type=float, default=0.0)
parser.add_argument("--ignore-sigint", action="store_true", help="only SIGKILL ends it")
parser.add_argument("--topic", help="publish horus.msg.CmdVel on this topic every 50 ms")
parser.add_argument("--grandchild", action="store_true",
                    help="start a child of its own (a sleep) and say 'grandchild PID'")
parser.add_argument("--daemon", action="store_true",
                    help="start a sleep in a session of its own (out of its process group, as a "
                         "daemon does) and say 'daemon PID'")
options = parser.parse_args()


def note(event: str) -> None:
    if options.journal:
        with open(options.journal, "a") as journal:
            journal.write(f"{event} {options.name}\n")


stopping = False


def on_sigint(_signo, _frame) -> None:
    global stopping
    stopping = True


signal.signal(signal.SIGINT, signal.SIG_IGN if options.ignore_sigint else on_sigint)
note("start")
topic = None
if options.topic:
    import horus
    from horus.msg import CmdVel
    topic = horus.Topic(CmdVel, options.topic)
if options.grandchild:
    sleeper = subprocess.Popen(["sleep", "300"])
    print(f"grandchild {sleeper.pid}", flush=True)
if options.daemon:
    daemon = subprocess.Popen(["sleep", "300"], start_new_session=True)
    print(f"daemon {daemon.pid}", flush=True)
print(f"ready {options.name} {os.getpid()}", flush=True)
print(f"{options.name} says hello on stderr", file=sys.stderr, flush=True)
started = time.monotonic()
while not stopping:
    if options.exit is not None and time.monotonic() - started >= options.after:
        note("end")
        sys.exit(options.exit)
    if topic is not None:
        topic.send(CmdVel(linear=1.0))
    time.sleep(0.05)
note("stop")
