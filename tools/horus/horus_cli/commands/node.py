"""`horus node`: list and inspect the nodes of the namespace's running schedulers."""
from __future__ import annotations

from horus_cli.common import (EXIT_OK, CommandFailed, did_you_mean, emit, format_rate,
                              names_or_table, namespace_name, started)
from horus_cli.live import live_nodes


def node_list(args) -> int:
    nodes = live_nodes(args)

    render = names_or_table(
        args, ["NODE", "PID", "SCHEDULER", "RATE_HZ", "ACHIEVED_HZ", "TICKS", "AVG_US", "MISSES",
               "STATE", "HEALTH"],
        lambda n: [n["name"], n["pid"], n["scheduler"], format_rate(n["rate_hz"]),
                   format_rate(n["achieved_rate_hz"]), n["total_ticks"], f"{n['avg_tick_ns'] / 1e3:.1f}",
                   n["deadline_misses"], n["state"], n["health"]])
    emit(nodes, args.json, render)
    return EXIT_OK


def node_info(args) -> int:
    nodes = live_nodes(args)
    matches = [n for n in nodes if n["name"] == args.node]
    if not matches:
        raise CommandFailed(f"no running node '{args.node}' in namespace '{namespace_name(args)}'"
                            f"{did_you_mean(args.node, [n['name'] for n in nodes])}")

    def render(rows):
        for n in rows:
            print(f"node: {n['name']}")
            print(f"process: pid {n['pid']} (started {started(n['started_wall_ns'])}), "
                  f"scheduler {n['scheduler']}")
            print(f"state: {n['state']}, health: {n['health']}")
            print(f"class: {n['class']}, order: {n['order']}")
            print(f"rate: {format_rate(n['rate_hz'])} Hz requested, {format_rate(n['achieved_rate_hz'])} Hz achieved")
            print(f"ticks: {n['total_ticks']} ({n['failed_ticks']} failed)")
            print(f"tick time: avg {n['avg_tick_ns'] / 1e3:.1f} us, max {n['max_tick_ns'] / 1e3:.1f} us, "
                  f"last {n['last_tick_ns'] / 1e3:.1f} us")
            print(f"misses: {n['deadline_misses']} deadline, {n['budget_overruns']} budget")
            if n.get("deadline_ns") is not None:
                print(f"deadline: {n['deadline_ns'] / 1e3:.1f} us")
            if n.get("scheduler_deadline_misses") is not None:
                total, limit = n["scheduler_deadline_misses"], n["max_deadline_misses"]
                print(f"scheduler misses: {total} (no max_deadline_misses: never stops)"
                      if limit is None else
                      f"scheduler misses: {total} of max_deadline_misses {limit}, where it stops")
            for key in ("publishers", "subscribers"):
                topics = ", ".join(f"{t['topic']} ({t['type'] or '?'})" for t in n[key]) or "-"
                print(f"{key}: {topics}")
    emit(matches, args.json, render)
    return EXIT_OK


def register(commands) -> None:
    node = commands.group("node", "nodes of the running schedulers: list, inspect")
    sub = commands.action(node, "list", "the nodes of the namespace's live schedulers", node_list)
    sub.add_argument("-v", "--verbose", action="store_true",
                     help="with process, rates, ticks, tick time, misses, state and health")
    sub = commands.action(node, "info", "one node: topics, rate, timing, misses, health, state",
                          node_info)
    sub.add_argument("node")
