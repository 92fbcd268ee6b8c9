"""`horus monitor`: a live terminal view of the namespace's nodes and topics."""
from __future__ import annotations

import sys
import time

from horus_cli.common import (EXIT_OK, EXIT_USAGE, CommandFailed, format_bytes, format_rate,
                              introspection, namespace_name, refresh_interval)
from horus_cli.live import best_rate, is_internal, live_nodes, read_traffic, stamped_rate


class _TopicRates:
    """Each topic's rate and bandwidth: from its send stamps, or counted between two refreshes,
    whichever spans more messages; the bandwidth is the rate times the mean size in the ring."""

    def __init__(self) -> None:
        self.previous: dict[str, tuple[int, float]] = {}

    def sample(self, core, args) -> list[dict]:
        topics = core.list_topics(args.namespace)
        topics = [topic for topic in topics if not is_internal(topic)]
        now, counts = time.time(), {}
        for topic in topics:
            name = topic["name"]
            topic["rate_hz"] = topic["bytes_per_s"] = None
            traffic = read_traffic(core, args, name)
            if traffic is None:
                continue
            count, stamp = counts[name] = traffic["message_count"], time.monotonic()
            previous, counted = self.previous.get(name), None
            # Not for a topic new since the last refresh, or created again (its count restarted).
            if previous is not None and count >= previous[0]:
                counted = (count - previous[0]) / (stamp - previous[1]), count - previous[0]
            rate = best_rate(stamped_rate(traffic, now), counted)
            topic["rate_hz"] = rate
            if rate is not None and traffic["counted"]:
                topic["bytes_per_s"] = rate * traffic["bytes"] / traffic["counted"]
        self.previous = counts
        return topics


def _monitor_lines(args, rates: _TopicRates) -> list[str]:
    core = introspection()
    lines = [f"horus monitor  namespace {namespace_name(args)}  "
             f"{time.strftime('%H:%M:%S')}   q: quit", ""]
    node_rows = [[n["name"], n["pid"], format_rate(n["rate_hz"]),
                  format_rate(n["achieved_rate_hz"]),
                  f"{n['avg_tick_ns'] / 1e3:.1f}", f"{n['max_tick_ns'] / 1e3:.1f}",
                  n["deadline_misses"] + n["budget_overruns"], n["health"], n["state"]]
                 for n in live_nodes(args)]
    topic_rows = [[t["name"], t["type_name"] or "-", t["publishers"], t["subscribers"],
                   format_rate(t["rate_hz"]),
                   "-" if t["bytes_per_s"] is None else format_bytes(t["bytes_per_s"]) + "/s"]
                  for t in rates.sample(core, args)]
    for title, header, rows in (
            ("NODES", ["NODE", "PID", "RATE_HZ", "ACHIEVED_HZ", "AVG_US", "MAX_US", "MISSES",
                       "HEALTH", "STATE"], node_rows),
            ("TOPICS", ["TOPIC", "TYPE", "PUBS", "SUBS", "RATE_HZ", "BANDWIDTH"], topic_rows)):
        lines.append(f"{title} ({len(rows)})")
        widths = [max(len(str(row[i])) for row in [header, *rows]) for i in range(len(header))]
        for row in [header, *rows]:
            lines.append("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip())
        lines.append("")
    return lines


def monitor(args) -> int:
    if not (sys.stdin.isatty() and sys.stdout.isatty()):
        raise CommandFailed("horus monitor needs a terminal; use `node list -v` and "
                            "`topic list -v` in scripts", EXIT_USAGE)
    import curses

    def run(screen) -> None:
        curses.curs_set(0)
        screen.timeout(int(args.interval * 1000))
        rates = _TopicRates()
        while True:
            lines = _monitor_lines(args, rates)
            screen.erase()
            height, width = screen.getmaxyx()
            for row, line in enumerate(lines[:height - 1]):
                screen.addnstr(row, 0, line, width - 1)
            screen.refresh()
            if screen.getch() in (ord("q"), ord("Q")):
                return
    curses.wrapper(run)
    return EXIT_OK


def register(commands) -> None:
    sub = commands.command("monitor", help="live view of nodes and topics (q quits)",
                           description="A live terminal view of the namespace's nodes (rate, "
                                       "tick time, misses, health) and topics (rate, "
                                       "bandwidth), until q or Ctrl+C.", parents=[commands.common])
    sub.add_argument("--interval", type=refresh_interval, default=1.0,
                     help="seconds between refreshes (default 1, at least 0.1)")
    sub.set_defaults(handler=monitor)
