"""`horus view`: see the namespace live in Foxglove, Lichtblick or the built-in page
(docs/live-view.md).

serve (the action when none is named) runs horus-view serve (bridges/view) with every further
argument as it is, so its options (--listen, --port, --tls, --allow, --tokens...) are its own;
status reads the status file each horus-view serving the namespace rewrites every second.
"""
from __future__ import annotations

import argparse
import os

from horus_cli.common import (EXIT_OK, CommandFailed, emit, introspection, live_status_files,
                               table)

# Set by the launcher (bin/horus) to the horus-view beside it (`horus view serve`).
VIEW_PROGRAM = os.environ.get("HORUS_VIEW_PROGRAM", "horus-view")
ACTIONS = ("serve", "status")


def with_default_action(words: list[str]) -> list[str]:
    """`words` with `serve` after `view` where no action follows it (`horus view --port 0`), so
    that serving, the common case, needs no action word; help keeps listing the actions."""
    at = 0
    while at < len(words) and words[at] in ("-n", "--namespace"):
        at += 2
    while at < len(words) and words[at].startswith("--namespace="):
        at += 1
    if at >= len(words) or words[at] != "view":
        return words
    rest = words[at + 1:]
    if rest and (rest[0] in ACTIONS or rest[0] in ("-h", "--help")):
        return words
    return [*words[:at + 1], "serve", *rest]


def servers(namespace: str) -> list[dict]:
    """The status of each live horus-view serving `namespace` (bridges/view/src/main.cpp writes
    it), by process id."""
    return live_status_files("horus-view", namespace)


def _rows(server: dict) -> list[list]:
    """One row per subscription of each client; a client with none has one row of its own."""
    rows = []
    for client in server["clients"]:
        who = [server["pid"], client["id"], client["address"]]
        for subscription in client["subscriptions"]:
            rate = subscription.get("max_rate_hz") or "-"
            rows.append([*who, subscription["topic"], subscription["sent"],
                         subscription["dropped"], rate])
        if not client["subscriptions"]:
            rows.append([*who, "-", client["sent"], client["dropped"], "-"])
    return rows


def view_status(args) -> int:
    namespace = args.namespace or introspection().current_namespace()
    found = servers(namespace)

    def render(found):
        if not found:
            print(f"no horus view serves namespace '{namespace}'")
            return
        for server in found:
            count = len(server["clients"])
            print(f"horus-view {server['pid']} on {server['listen']}: {count} "
                  f"client{'' if count == 1 else 's'}, {server['counters']['messages_sent']} "
                  f"messages sent, {server['counters']['messages_dropped']} dropped")
        rows = [row for server in found for row in _rows(server)]
        if rows:
            table(["PID", "CLIENT", "ADDRESS", "TOPIC", "SENT", "DROPPED", "MAX HZ"], rows)
    emit(found, args.json, render)
    return EXIT_OK


def view_serve(args) -> int:
    # The namespace reaches horus-view through HORUS_NAMESPACE, which main() set.
    try:
        os.execvp(VIEW_PROGRAM, [VIEW_PROGRAM, "serve", *args.view_args])
    except FileNotFoundError:
        raise CommandFailed(f"cannot run {VIEW_PROGRAM}: it is not there (the live view is built "
                            "where Cap'n Proto is installed: Debian's libcapnp-dev and capnproto)"
                            ) from None
    except OSError as error:
        raise CommandFailed(f"cannot run {VIEW_PROGRAM}: {error.strerror}") from None


def register(commands) -> None:
    view = commands.group("view", "see this namespace live in Foxglove, Lichtblick or the "
                                  "built-in page (docs/live-view.md)")
    help_text = ("serve this namespace over the Foxglove WebSocket protocol (runs horus-view "
                 "serve: --listen ADDR, --port N, --tls, --allow, --tokens...; `horus view serve "
                 "--help` lists them); the action when none is named")
    # '+' as the prefix: every argument, options too, goes to horus-view as it is.
    sub = view.add_parser("serve", help=help_text, description=help_text, prefix_chars="+",
                          add_help=False)
    sub.add_argument("view_args", nargs=argparse.REMAINDER)
    sub.set_defaults(handler=view_serve)
    commands.action(view, "status", "the clients of each horus view serving this namespace: "
                    "their subscriptions, messages sent and dropped (latest wins for a slow "
                    "viewer)", view_status)
