"""`horus frame list|tree|echo|hz`: the namespace's coordinate frames (horus.FrameTree), read
from its shared-memory tree. Looking never creates a tree: a namespace without one has no frames.
"""
from __future__ import annotations

import json
import math
import sys
import time

from horus_cli.common import (EXIT_OK, CommandFailed, did_you_mean, emit, format_rate,
                              namespace_name, positive_float, positive_int, table, utc)

# The rate of a frame in `list` comes from the stamps of its entries over this last stretch.
RATE_SPAN_S = 1.0


def _frames_module():
    import horus
    return horus


def _tree(args, required: bool):
    """The namespace's tree, or None when it has none (an error when `required`)."""
    horus = _frames_module()
    if not horus.frame_tree_exists(args.namespace or None):
        if required:
            raise CommandFailed(f"namespace '{namespace_name(args)}' has no frame tree: no "
                                "process has set a frame in it")
        return None
    return horus.FrameTree(args.namespace or None)


def _rate(tree, frame) -> float | None:
    """Entries per second over the newest RATE_SPAN_S of a dynamic frame's history."""
    stamps = [entry.stamp for entry in tree.history(frame.name)
              if entry.stamp >= frame.latest - int(RATE_SPAN_S * 1e9)]
    if len(stamps) < 2 or stamps[-1] == stamps[0]:
        return None
    return (len(stamps) - 1) / ((stamps[-1] - stamps[0]) / 1e9)


def _frame_rows(tree) -> list[dict]:
    now_ns = time.time_ns()
    rows = []
    for frame in tree.frames():
        has_entry = frame.latest != 0
        rows.append({
            "name": frame.name, "parent": frame.parent, "static": frame.is_static,
            "authority_pid": frame.authority_pid or None,
            "authority_program": frame.authority_program or None,
            "authority_alive": frame.authority_alive,
            "rate_hz": None if frame.is_static or not has_entry else _round(_rate(tree, frame)),
            "latest_ns": frame.latest if has_entry else None,
            "age_s": round((now_ns - frame.latest) / 1e9, 3) if has_entry else None,
            "updates": frame.updates})
    return rows


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 2)


def _authority(row: dict) -> str:
    if row["authority_pid"] is None:
        return "-"
    if not row["authority_alive"]:
        return f"{row['authority_pid']} (exited)"
    return f"{row['authority_pid']} {row['authority_program'] or '?'}"


def _kind(row: dict) -> str:
    if row["static"]:
        return "static"
    if row["parent"] is None:
        return "root"
    return f"{format_rate(row['rate_hz'])} Hz"


def frame_list(args) -> int:
    tree = _tree(args, required=False)
    rows = [] if tree is None else _frame_rows(tree)

    def render(rows):
        table(["FRAME", "PARENT", "AUTHORITY", "STATIC/RATE", "AGE"],
              [[r["name"], r["parent"] or "-", _authority(r),
                _kind(r),
                "-" if r["age_s"] is None or r["static"] else f"{r['age_s']:.3f} s"]
               for r in rows])
    emit(rows, args.json, render)
    return EXIT_OK


def _nested(rows: list[dict]) -> list[dict]:
    """The frames as trees: each root with its children, recursively."""
    children: dict[str | None, list[dict]] = {}
    for row in rows:
        children.setdefault(row["parent"], []).append(row)

    def node(row: dict) -> dict:
        return {"name": row["name"], "static": row["static"],
                "authority_pid": row["authority_pid"], "rate_hz": row["rate_hz"],
                "children": [node(child) for child in children.get(row["name"], [])]}
    return [node(root) for root in children.get(None, [])]


def frame_tree(args) -> int:
    tree = _tree(args, required=False)
    if args.dot:
        print(tree.as_dot() if tree is not None else "digraph frames {\n}", end="")
        return EXIT_OK
    if args.json:
        emit(_nested([] if tree is None else _frame_rows(tree)), True, None)
        return EXIT_OK
    text = "" if tree is None else tree.as_text()
    print(text if text else f"no frames in namespace '{namespace_name(args)}'", end="" if text
          else "\n")
    return EXIT_OK


def _rpy_degrees(rotation) -> tuple[float, float, float]:
    """Roll, pitch, yaw (x, y, z fixed axes) of a unit quaternion, in degrees, for people."""
    x, y, z, w = rotation
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return tuple(math.degrees(angle) for angle in (roll, pitch, yaw))


def _show_transform(stamped, as_json: bool) -> None:
    translation, rotation = stamped.transform
    if as_json:
        print(json.dumps({"target": stamped.parent, "source": stamped.child,
                          "stamp_ns": stamped.stamp, "translation": list(translation),
                          "rotation": list(rotation),
                          "rpy_deg": [round(a, 6) for a in _rpy_degrees(rotation)]},
                         sort_keys=True), flush=True)
        return
    def numbers(values, digits: int) -> str:
        return "[" + ", ".join(f"{v:.{digits}f}" for v in values) + "]"
    print(f"at {utc(stamped.stamp / 1e9, 3)} ({stamped.stamp} ns): {stamped.parent} <- "
          f"{stamped.child}\n"
          f"  translation: {numbers(translation, 6)}\n"
          f"  rotation (x, y, z, w): {numbers(rotation, 6)}\n"
          f"  rotation (roll, pitch, yaw deg): {numbers(_rpy_degrees(rotation), 3)}", flush=True)


def _check_frames(tree, args, names: list[str]) -> None:
    known = [frame.name for frame in tree.frames()]
    for name in names:
        if name not in known:
            raise CommandFailed(f"no frame '{name}' in namespace '{namespace_name(args)}'"
                                f"{did_you_mean(name, known)}")


def frame_echo(args) -> int:
    horus = _frames_module()
    tree = _tree(args, required=True)
    _check_frames(tree, args, [args.target, args.source])
    period = 1.0 / args.rate
    shown, last_reason = 0, None
    next_at = time.monotonic()
    while True:
        try:
            stamped = tree.lookup_stamped(args.target, args.source)
        except horus.FrameError as error:
            if str(error) != last_reason:  # said once until it changes, not every period
                print(f"horus: {error}", file=sys.stderr, flush=True)
                last_reason = str(error)
        else:
            last_reason = None
            _show_transform(stamped, args.json)
            shown += 1
            if args.once or (args.count and shown >= args.count):
                return EXIT_OK
        next_at += period
        time.sleep(max(0.0, next_at - time.monotonic()))


def frame_hz(args) -> int:
    tree = _tree(args, required=True)
    if args.frame is not None:
        _check_frames(tree, args, [args.frame])
        frame = next(frame for frame in tree.frames() if frame.name == args.frame)
        if frame.is_static or frame.parent is None:
            raise CommandFailed(f"frame '{args.frame}' is "
                                f"{'static' if frame.is_static else 'a root'}: it has no rate")

    def counts() -> dict[str, int]:
        return {frame.name: frame.updates for frame in tree.frames()
                if not frame.is_static and frame.parent is not None
                and (args.frame is None or frame.name == args.frame)}

    before, start = counts(), time.monotonic()
    while True:
        time.sleep(args.window)
        after, end = counts(), time.monotonic()
        elapsed = end - start
        window = {name: {"updates": count - before.get(name, 0),
                         "rate_hz": round((count - before.get(name, 0)) / elapsed, 2)}
                  for name, count in after.items()}
        if args.json:
            print(json.dumps({"window_s": round(elapsed, 3), "frames": window}, sort_keys=True),
                  flush=True)
        else:
            if not window:
                print(f"no dynamic frames ({elapsed:.2f} s)", flush=True)
            for name, figures in window.items():
                print(f"{name}: {figures['rate_hz']:.2f} Hz ({figures['updates']} updates in "
                      f"{elapsed:.2f} s)", flush=True)
        if args.once:
            return EXIT_OK
        before, start = after, end


def register(commands) -> None:
    frame = commands.group("frame", "the namespace's coordinate frames (its transform tree)")
    commands.action(frame, "list", "every frame: parent, authority, static or rate, age of the "
                    "newest transform", frame_list)
    sub = commands.action(frame, "tree", "the frames as an indented tree (--json: nested)",
                          frame_tree)
    sub.add_argument("--dot", action="store_true", help="print a Graphviz digraph instead")
    sub = commands.action(frame, "echo", "print the transform TARGET <- SOURCE at the latest "
                          "common time, at a rate", frame_echo)
    sub.add_argument("target", help="the frame the answer is expressed in (e.g. map)")
    sub.add_argument("source", help="the frame whose coordinates it maps (e.g. lidar)")
    sub.add_argument("--rate", type=positive_float, default=1.0, metavar="HZ",
                     help="lookups per second (default 1)")
    sub.add_argument("--once", action="store_true", help="print one transform and exit")
    sub.add_argument("--count", type=positive_int, metavar="N", help="print N transforms and exit")
    sub = commands.action(frame, "hz", "transforms written per second, of one frame or every "
                          "dynamic one", frame_hz)
    sub.add_argument("frame", nargs="?", help="the frame (default: every dynamic frame)")
    sub.add_argument("--window", type=positive_float, default=1.0, metavar="SECONDS",
                     help="seconds per measurement (default 1)")
    sub.add_argument("--once", action="store_true", help="print one window and exit")
