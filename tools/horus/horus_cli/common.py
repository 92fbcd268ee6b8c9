"""What every `horus` command uses: exit statuses, the one-line failure (CommandFailed), the
argparse types and parser, the namespace and --json options, listings as tables or JSON, and
did-you-mean suggestions. Imports no command module (commands/ import this).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

EXIT_OK, EXIT_NOT_FOUND, EXIT_USAGE = 0, 1, 2


class CommandFailed(Exception):
    """A failure reported as one line on stderr, with its exit status."""

    def __init__(self, message: str, status: int = EXIT_NOT_FOUND) -> None:
        super().__init__(message)
        self.status = status


def positive_float(text: str) -> float:
    """An argparse type: a number above 0 (a window, a rate, a timeout of 0 or less would
    busy-loop, divide by zero or never end)."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"needs a number above 0, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """An argparse type: a finite number of 0 or more (an offset into a recording)."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"needs a number of 0 or more, got {text!r}")
    return value


def refresh_interval(text: str) -> float:
    """An argparse type: seconds between screen refreshes, at least 0.1 (curses waits for keys in
    whole milliseconds; shorter would redraw without pause and take a CPU)."""
    value = positive_float(text)
    if value < 0.1:
        raise argparse.ArgumentTypeError(f"needs at least 0.1 seconds, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An argparse type: a whole number above 0 (a count of 0 would mean forever)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise argparse.ArgumentTypeError(f"needs a whole number above 0, got {text!r}")
    return value


def introspection():
    """horus.introspection, imported on first use: loading the extension is most of the start-up
    time, so `--help` and completion stay instant."""
    from horus import introspection as module
    return module


def _bytes_as_hex(value):
    """A listing as JSON values: the bytes it carries (a topic's type description) as hex digits
    under the key with `_hex` added (`description_hex`), so that no reader takes them for text."""
    if isinstance(value, dict):
        return {(f"{key}_hex" if isinstance(item, bytes) else key): _bytes_as_hex(item)
                for key, item in value.items()}
    if isinstance(value, list):
        return [_bytes_as_hex(item) for item in value]
    if isinstance(value, bytes):
        return value.hex()
    return value


def emit(rows, as_json: bool, render) -> None:
    if as_json:
        json.dump(_bytes_as_hex(rows), sys.stdout, indent=2, sort_keys=True)
        sys.stdout.write("\n")
    else:
        render(rows)


def table(header: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(str(row[i])) for row in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(str(cell).ljust(width) for cell, width in zip(row, widths)).rstrip())


def names_or_table(args, header: list[str], row):
    """The renderer of a listing: names alone, or with -v a table of `row(item)`."""
    def render(items):
        if args.verbose:
            table(header, [row(item) for item in items])
        else:
            for item in items:
                print(item["name"])
    return render


def namespace_name(args) -> str:
    return args.namespace or introspection().current_namespace()


def close_names(name: str, known) -> list[str]:
    """Those of `known` closest to a name that is not one of them, the closest first."""
    import difflib
    return difflib.get_close_matches(name, sorted(set(known)), n=3, cutoff=0.6)


def suggestion(close: list[str]) -> str:
    return "; did you mean " + " or ".join(f"'{name}'" for name in close) + "?" if close else ""


def did_you_mean(name: str, known) -> str:
    return suggestion(close_names(name, known))


def utc(seconds: float, digits: int = 0) -> str:
    """A wall-clock time as ISO 8601 UTC, with `digits` decimals of the second (rounded first,
    so that 12.999 with two decimals is 13.00, not 12.00)."""
    scale = 10 ** digits
    units = round(seconds * scale)
    text = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(units // scale))
    if digits:
        text += f".{units % scale:0{digits}d}"
    return text + "Z"


def started(started_wall_ns: int) -> str:
    """When a process started (to the kernel's clock tick: two decimals), or "?"."""
    return utc(started_wall_ns / 1e9, 2) if started_wall_ns else "?"


def format_rate(value) -> str:
    return "-" if value is None else f"{value:.1f}"


def format_bytes(value: float) -> str:
    for unit in ("B", "KB", "MB"):
        if value < 1000 or unit == "MB":
            return f"{value:.1f} {unit}" if unit != "B" else f"{value:.0f} B"
        value /= 1000
    return ""


class UsageParser(argparse.ArgumentParser):
    """argparse with the usage error on one line and exit status 2."""

    def error(self, message: str):
        self.exit(EXIT_USAGE, f"{self.prog}: {message}\n")


class Commands:
    """The `horus` parser, where each command module adds its own (register(commands)): the
    subparsers of the commands, with the options every command takes (--namespace) and every
    listing (--json)."""

    def __init__(self, prog: str, description: str) -> None:
        self.common = UsageParser(add_help=False)
        self.common.add_argument("--namespace", "-n", default=argparse.SUPPRESS,
                                 help="the namespace to look at (default: $HORUS_NAMESPACE, else "
                                      "'default')")
        self.listing = UsageParser(add_help=False)
        self.listing.add_argument("--json", action="store_true",
                                  help="print JSON instead of text")
        self.parser = UsageParser(prog=prog, parents=[self.common], description=description)
        self.subparsers = self.parser.add_subparsers(dest="command", metavar="COMMAND",
                                                     parser_class=UsageParser)

    def group(self, name: str, help_text: str):
        """A command with actions (`horus topic list`): the subparsers its actions go in."""
        sub = self.subparsers.add_parser(name, help=help_text, description=help_text,
                                         parents=[self.common])
        return sub.add_subparsers(dest="action", metavar="ACTION", parser_class=UsageParser)

    def action(self, group, name: str, help_text: str, handler, json_output: bool = True):
        """An action of a group, run by `handler(args)`; with --json unless json_output is False."""
        parents = [self.common, self.listing] if json_output else [self.common]
        sub = group.add_parser(name, help=help_text, description=help_text, parents=parents)
        sub.set_defaults(handler=handler)
        return sub

    def command(self, name: str, **options):
        """A command without actions (`horus log`), with argparse's add_parser options."""
        return self.subparsers.add_parser(name, **options)


def live_status_files(program: str, namespace: str) -> list[dict]:
    """What each live process of `program` (horus-remote, horus-view) serving `namespace` says in
    the status file it rewrites every second (<XDG_RUNTIME_DIR or /tmp/PROGRAM-UID>/PROGRAM/
    <namespace>.<pid>.json), by process id. The file of a process killed before it could remove
    it is removed here."""
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    folder = os.path.join(runtime, program) if runtime else f"/tmp/{program}-{os.getuid()}"
    found = []
    for name in sorted(os.listdir(folder)) if os.path.isdir(folder) else []:
        prefix, _, pid = name.removesuffix(".json").rpartition(".")
        if prefix != namespace or not name.endswith(".json") or not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            os.remove(os.path.join(folder, name))
            continue
        except PermissionError:
            pass
        try:
            with open(os.path.join(folder, name)) as file:
                found.append(json.load(file))
        except (OSError, ValueError):  # went away while read
            continue
    return sorted(found, key=lambda status: status["pid"])
