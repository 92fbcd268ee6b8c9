"""`horus blackbox`: runs horus-blackbox, which prints a scheduler's flight-recorder file."""
from __future__ import annotations

import argparse
import os

from horus_cli.common import CommandFailed

# Filled in by the launcher (bin/horus) with the horus-blackbox beside it.
BLACKBOX_PROGRAM = os.environ.get("HORUS_BLACKBOX_PROGRAM", "horus-blackbox")


def blackbox(args) -> int:
    try:
        os.execvp(BLACKBOX_PROGRAM, [BLACKBOX_PROGRAM, *args.blackbox_args])
    except OSError as error:
        raise CommandFailed(f"cannot run {BLACKBOX_PROGRAM}: {error.strerror}") from None


def register(commands) -> None:
    # main() hands it every word after `blackbox`, its options (--help) first too, which
    # argparse's REMAINDER would not take.
    sub = commands.command("blackbox", help="print a scheduler flight-recorder file",
                           description="Runs horus-blackbox with the given arguments.",
                           add_help=False)
    sub.add_argument("blackbox_args", nargs=argparse.REMAINDER)
    sub.set_defaults(handler=blackbox)
