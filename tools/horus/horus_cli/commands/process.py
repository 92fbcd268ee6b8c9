"""`horus process list`: the processes using the namespace."""
from __future__ import annotations

from horus_cli.common import EXIT_OK, emit, started, table
from horus_cli.live import list_processes


def process_list(args) -> int:
    processes = list_processes(args)

    def render(rows):
        table(["PID", "STARTED", "PROGRAM", "NODES", "TOPICS", "SERVICES"],
              [[p["pid"], started(p["started_wall_ns"]), p["program"],
                ",".join(p["nodes"]) or "-",
                ",".join(t["topic"] for t in p["topics"]) or "-",
                ",".join(f"{s['service']}({s['role']})" for s in p["services"]) or "-"]
               for p in rows])
    emit(processes, args.json, render)
    return EXIT_OK


def register(commands) -> None:
    process = commands.group("process", "the processes using the namespace")
    commands.action(process, "list", "live processes with their nodes, open topics and services",
                    process_list)
