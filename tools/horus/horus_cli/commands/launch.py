"""`horus launch`: start a whole robot from one file (launch/plan.py reads it, launch/runner.py runs
it), and see, stop and restart a running launch from another terminal (launch/control.py).

    horus launch FILE [NAME:=VALUE ...] [--dry-run] [--log-dir DIR] [--namespace NS]
    horus launch status [LAUNCH] [--json]
    horus launch stop [LAUNCH] [PROCESS]
    horus launch restart [LAUNCH] PROCESS

The first word picks the action: status, stop and restart are actions, anything else the file (a
file named like an action is written ./status). LAUNCH (a launch's name or its launcher's pid) may
be left out when exactly one launch of this user runs.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

from horus_cli.common import (EXIT_OK, EXIT_USAGE, CommandFailed, UsageParser, did_you_mean, emit,
                              table)

ACTIONS = ("status", "stop", "restart")


def _run_parser() -> UsageParser:
    parser = UsageParser(prog="horus launch", add_help=False)
    parser.add_argument("file")
    parser.add_argument("arguments", nargs="*")
    parser.add_argument("--dry-run", action="store_true")
    parser.add_argument("--log-dir")
    parser.add_argument("--namespace", "-n")
    return parser


def _action_parser(action: str) -> UsageParser:
    parser = UsageParser(prog=f"horus launch {action}", add_help=False)
    parser.add_argument("words", nargs="*")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--namespace", "-n")
    return parser


def launch(args) -> int:
    words = list(args.words)
    if args.dry_run:
        words.append("--dry-run")
    if args.log_dir:
        words += ["--log-dir", args.log_dir]
    if args.namespace:
        words += ["--namespace", args.namespace]
    if args.json:
        words.append("--json")
    if not words:
        raise CommandFailed("launch needs a launch file (horus launch FILE) or an action: "
                            f"{', '.join(ACTIONS)} (horus launch --help)", EXIT_USAGE)
    if "-h" in words or "--help" in words:
        args.launch_parser.print_help()
        return EXIT_OK
    if words[0] in ACTIONS:
        options = _action_parser(words[0]).parse_intermixed_args(words[1:])
        return {"status": _status, "stop": _stop, "restart": _restart}[words[0]](options)
    return _run(_run_parser().parse_intermixed_args(words))


def _run(options) -> int:
    from horus_cli.launch.plan import LaunchFileError, format_plan, load_plan, parse_arguments
    try:
        arguments = parse_arguments(options.arguments)
    except ValueError as error:
        raise CommandFailed(str(error), EXIT_USAGE) from error
    try:
        plan = load_plan(options.file, arguments)
    except LaunchFileError as error:
        print(str(error), file=sys.stderr)
        return EXIT_USAGE
    if options.log_dir:
        plan = dataclasses.replace(plan, log_dir=os.path.abspath(options.log_dir))
    if options.dry_run:
        sys.stdout.write(format_plan(plan))
        return EXIT_OK
    if options.namespace:
        os.environ["HORUS_NAMESPACE"] = options.namespace
    from horus_cli.launch.runner import Launcher
    return Launcher(plan, namespace=options.namespace or "").run()


# ---- control from another terminal ---------------------------------------------------------------

def _launches() -> list[dict]:
    from horus_cli.launch import control
    try:
        return control.running_launches()
    except control.ControlError as error:
        raise CommandFailed(str(error)) from error


def _named(launches: list[dict], word: str) -> list[dict]:
    return [launch for launch in launches if word in (launch["name"], str(launch["pid"]))]


def _pick(word: str | None) -> dict:
    """The running launch `word` names (name or pid), or the only one when it is None."""
    launches = _launches()
    names = ", ".join(f"{launch['name']} (pid {launch['pid']})" for launch in launches)
    if word is None:
        if len(launches) == 1:
            return launches[0]
        if not launches:
            raise CommandFailed("no launch of yours runs")
        raise CommandFailed(f"{len(launches)} launches run: {names}; name one")
    found = _named(launches, word)
    if len(found) == 1:
        return found[0]
    if found:
        raise CommandFailed(f"several launches named '{word}' run: {names}; name one by its pid")
    raise CommandFailed(f"no launch '{word}' runs"
                        + (did_you_mean(word, [launch["name"] for launch in launches])
                           or (f" (running: {names})" if launches else "")))


def _ask(launch: dict, command: str, process: str | None = None) -> dict:
    from horus_cli.launch import control
    try:
        return control.ask(launch["socket"], command, process)
    except control.ControlError as error:
        raise CommandFailed(f"launch {launch['name']}: {error}") from error


def _uptime(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    whole = int(seconds)
    if whole < 60:
        return f"{seconds:.1f}s"
    if whole < 3600:
        return f"{whole // 60}m{whole % 60:02d}s"
    return f"{whole // 3600}h{whole % 3600 // 60:02d}m"


def _status(options) -> int:
    if len(options.words) > 1:
        raise CommandFailed("status takes at most one LAUNCH", EXIT_USAGE)
    if options.words:
        launches = [_pick(options.words[0])]
    else:
        launches = _launches()
    statuses = [_ask(launch, "status") for launch in launches]
    for status in statuses:
        del status["ok"]

    def render(rows):
        if not rows:
            print("no launch of yours runs")
        for index, row in enumerate(rows):
            if index:
                print()
            print(f"launch {row['name']} (pid {row['pid']}) {row['state']}, from {row['source']}, "
                  f"logs in {row['log_dir']}")
            table(["PROCESS", "PID", "STATE", "RESTARTS", "UPTIME", "LAST_END"],
                  [[p["name"], p["pid"] or "-", p["state"], p["restarts"], _uptime(p["uptime_s"]),
                    p["last_end"] or "-"] for p in row["processes"]])
    emit(statuses, options.json, render)
    return EXIT_OK


def _launch_and_process(words: list[str], action: str) -> tuple[dict, str | None]:
    """(launch, process) from `[LAUNCH] [PROCESS]`: one word names a launch if one runs by that
    name (or pid), else a process of the only launch."""
    if len(words) > 2:
        raise CommandFailed(f"{action} takes [LAUNCH] [PROCESS]", EXIT_USAGE)
    if len(words) == 2:
        return _pick(words[0]), words[1]
    if not words:
        return _pick(None), None
    if _named(_launches(), words[0]):
        return _pick(words[0]), None
    return _pick(None), words[0]


def _process_state(launch: dict, name: str) -> dict:
    processes = _ask(launch, "status")["processes"]
    for process in processes:
        if process["name"] == name:
            return process
    raise CommandFailed(f"launch {launch['name']} has no process '{name}'"
                        f"{did_you_mean(name, [p['name'] for p in processes])}")


def _wait(what: str, done, limit: float) -> None:
    deadline = time.monotonic() + limit
    while not done():
        if time.monotonic() > deadline:
            raise CommandFailed(f"{what} not done after {limit:g} s")
        time.sleep(0.05)


def _stop(options) -> int:
    launch, process = _launch_and_process(options.words, "stop")
    if process is None:
        status = _ask(launch, "status")
        limit = sum(p["stop_timeout"] for p in status["processes"]) + 5
        _ask(launch, "stop")
        from horus_cli.launch.groups import process_running
        _wait(f"the stop of launch {launch['name']}",
              lambda: not process_running(launch["pid"]), limit)
        print(f"stopped launch {launch['name']}")
        return EXIT_OK
    _ask(launch, "stop", process)
    state = _process_state(launch, process)
    _wait(f"the stop of {process}",
          lambda: _process_state(launch, process)["state"] not in ("running", "stopping"),
          state["stop_timeout"] + 5)
    print(f"stopped {process}")
    return EXIT_OK


def _restart(options) -> int:
    if not 1 <= len(options.words) <= 2:
        raise CommandFailed("restart takes [LAUNCH] PROCESS", EXIT_USAGE)
    launch = _pick(options.words[0] if len(options.words) == 2 else None)
    process = options.words[-1]
    before = _process_state(launch, process)
    _ask(launch, "restart", process)
    seen = {}

    def restarted() -> bool:
        seen.update(_process_state(launch, process))
        return seen["restarts"] > before["restarts"] and seen["state"] != "stopping" and (
            seen["state"] != "running" or seen["pid"] != before["pid"])
    _wait(f"the restart of {process}", restarted, before["stop_timeout"] + 5)
    if seen["state"] == "running":
        print(f"restarted {process} (pid {seen['pid']})")
    else:
        print(f"restarted {process}: now {seen['state']}")
    return EXIT_OK


def register(commands) -> None:
    parser = commands.command(
        "launch", help="start a whole robot from one file; status, stop, restart of a running one",
        description=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        parents=[commands.common, commands.listing])
    parser.add_argument("words", nargs=argparse.REMAINDER, metavar="FILE|ACTION ...",
                        help="a launch file and its NAME:=VALUE arguments, or an action")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the fully expanded plan and exit")
    parser.add_argument("--log-dir", help="the folder of the processes' output logs (default: "
                                          "~/.local/state/horus/launch/NAME/TIME)")
    parser.set_defaults(handler=launch, launch_parser=parser,
                        completion_words="status stop restart")
