"""The `horus` command: see and clean a running HORUS system from the shell.

Every listing takes --json; exit status is 0 on success, 1 when something asked for is not found
(or a wait timed out) and 2 on a usage error. Errors are one line on stderr, never a traceback.
Imports of the runtime happen inside the commands, so `--help` and completion stay instant.

This module assembles the parser from the command modules (commands/, one per noun) and runs the
handler the arguments name.
"""
from __future__ import annotations

import argparse
import os
import sys

from horus_cli.commands import (action, blackbox, bridge, completion, frame, launch, log, monitor,
                                msg, node, param, process, record, remote, service, shm, topic,
                                view)
from horus_cli.common import EXIT_NOT_FOUND, EXIT_OK, CommandFailed, Commands

# In the order `horus --help` lists them.
COMMANDS = (topic, process, node, service, action, param, frame, msg, log, shm, monitor, blackbox,
            record, bridge, remote, view, launch, completion)


def build_parser() -> argparse.ArgumentParser:
    commands = Commands("horus", "See, poke and clean a running HORUS system.")
    for command in COMMANDS:
        command.register(commands)
    return commands.parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    words = view.with_default_action(sys.argv[1:] if argv is None else argv)
    args = record.parse_record(words)  # `record` parses its own arguments
    if args is None:
        args, unknown = parser.parse_known_args(words)
        if getattr(args, "handler", None) is blackbox.blackbox:
            # Everything after `blackbox` is horus-blackbox's, its options (--help) first too,
            # which argparse's REMAINDER would not take.
            args.blackbox_args = words[words.index("blackbox") + 1:]
        elif unknown:
            parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if getattr(args, "handler", None) is None:
        parser.parse_args([*words, "--help"])
    args.root_parser = parser
    args.namespace = getattr(args, "namespace", None) or ""
    if args.namespace:
        # Handles the command opens (echo, pub, call) read the namespace from the environment.
        os.environ["HORUS_NAMESPACE"] = args.namespace
    try:
        return args.handler(args)
    except CommandFailed as failure:
        print(f"horus: {failure}", file=sys.stderr)
        return failure.status
    except KeyboardInterrupt:
        return EXIT_OK
    except BrokenPipeError:
        return EXIT_OK
    except Exception as error:  # noqa: BLE001 (any failure is one line, never a traceback)
        if type(error).__name__ == "HorusError":  # the runtime's refusal: a problem of the input
            print(f"horus: {error}", file=sys.stderr)
            return EXIT_NOT_FOUND
        if os.environ.get("HORUS_DEBUG") == "1":
            raise
        reason = " ".join(str(error).split())
        print(f"horus: internal error: {type(error).__name__}: {reason} (HORUS_DEBUG=1 shows "
              "the traceback)", file=sys.stderr)
        return EXIT_NOT_FOUND
