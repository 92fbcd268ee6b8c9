"""`horus log`: the namespace's log ring, filtered, once or followed."""
from __future__ import annotations

import json
import time

from horus_cli.common import EXIT_OK, emit, introspection, positive_float

LEVELS = ("debug", "info", "warn", "error")


def _log_filter(args):
    minimum = LEVELS.index(args.level) if args.level else 0
    since_ns = None
    if args.since is not None:
        since_ns = int((time.time() - args.since) * 1e9)

    def keep(record: dict) -> bool:
        return (LEVELS.index(record["level"].lower()) >= minimum
                and (args.node is None or record["source"] == args.node)
                and (since_ns is None or record["wall_time_ns"] >= since_ns))
    return keep


def log(args) -> int:
    core = introspection()
    keep = _log_filter(args)
    snapshot = core.read_log(args.namespace)
    records = [r for r in snapshot["records"] if keep(r)]
    if not args.follow:
        emit(records, args.json, lambda rows: [print(r["text"]) for r in rows])
        return EXIT_OK
    seen = snapshot["written"]

    def show(rows):
        for row in rows:
            print(json.dumps(row, sort_keys=True) if args.json else row["text"], flush=True)
    show(records)
    while True:
        time.sleep(0.1)
        snapshot = core.read_log(args.namespace)
        show([r for r in snapshot["records"] if r["sequence"] >= seen and keep(r)])
        seen = snapshot["written"]


def register(commands) -> None:
    sub = commands.command("log", help="the namespace's log ring",
                           description="Lines nodes logged, oldest first.",
                           parents=[commands.common, commands.listing])
    sub.set_defaults(handler=log)
    sub.add_argument("--node", help="only lines of this node (its name, '-' or '@<scheduler>')")
    sub.add_argument("--level", choices=LEVELS, help="only lines at this level or above")
    sub.add_argument("--since", type=positive_float, metavar="SECONDS",
                     help="only lines of the last SECONDS seconds")
    sub.add_argument("--follow", "-f", action="store_true",
                     help="keep printing new lines until Ctrl+C")
