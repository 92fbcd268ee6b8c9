"""`horus shm`: the namespace's shared-memory objects and who uses them; the clean-up of what
dead processes left."""
from __future__ import annotations

import json
import os

from horus_cli.common import EXIT_OK, emit, introspection, table


def _program(pid: int) -> str:
    """A process's program name as the kernel tells it, or "?" (gone, or not ours to read)."""
    try:
        with open(f"/proc/{pid}/comm", encoding="utf-8", errors="replace") as comm:
            return comm.read().strip() or "?"
    except OSError:
        return "?"


def _flock_holders(path: str) -> list[int]:
    """The pids holding a flock on `path` (those waiting for one left out), from /proc/locks."""
    try:
        status = os.stat(path)
        with open("/proc/locks", encoding="ascii", errors="replace") as locks:
            lines = locks.read().splitlines()
    except OSError:
        return []
    holders = set()
    for line in lines:
        fields = line.split()  # "1: FLOCK ADVISORY READ <pid> <major>:<minor>:<inode> 0 EOF"
        if len(fields) < 6 or fields[1] != "FLOCK":
            continue  # a POSIX lock, or a waiter ("1: -> FLOCK ...")
        major, minor, inode = fields[5].split(":")
        if (int(major, 16), int(minor, 16), int(inode)) == \
                (os.major(status.st_dev), os.minor(status.st_dev), status.st_ino):
            holders.add(int(fields[4]))
    return sorted(holders)


def shm_list(args) -> int:
    core = introspection()
    folder = core.namespace_directory(args.namespace)
    rows = []
    for topic in core.list_topics(args.namespace):
        path = os.path.join(folder, topic["name"])
        try:
            size = os.stat(path).st_size
        except OSError:
            size = None
        rows.append({"name": topic["name"], "path": path, "size": size,
                     "pids": topic["user_pids"], "in_use": bool(topic["user_pids"]),
                     "error": topic["error"]})
    # The log ring, the presence folder, the parameter stores (one a node, named after it) and
    # the frame tree: their users hold a lock on them (the tree's an OFD lock, which /proc/locks
    # shows without a pid: "(in use)").
    rows += [{"name": o["kind"] + ("/" + os.path.basename(o["path"]) if o["kind"] == "@params"
                                   else ""),
              "path": o["path"], "size": o["size"],
              "pids": _flock_holders(o["path"]), "in_use": o["in_use"], "error": ""}
             for o in core.list_namespace_objects(args.namespace)]
    for row in rows:
        row["users"] = [{"pid": pid, "program": _program(pid)} for pid in row.pop("pids")]

    def users_text(row) -> str:
        if row["users"]:
            return ",".join(f"{u['pid']}({u['program']})" for u in row["users"])
        # A lock held by a process this one cannot see (another pid namespace).
        return "(in use)" if row["in_use"] else "-"

    def render(items):
        table(["SEGMENT", "BYTES", "USERS", "PATH"],
              [[r["name"], "-" if r["size"] is None else r["size"], users_text(r), r["path"]]
               for r in items])
    emit(rows, args.json, render)
    return EXIT_OK


def shm_clean(args) -> int:
    core = introspection()
    removed = core.clean_namespace(args.namespace)
    announcements = core.clean_presence(args.namespace)
    pools = core.clean_pools(args.namespace)
    if args.json:
        print(json.dumps({"removed": removed, "announcements": announcements, "pools": pools}))
    else:
        print(f"removed {removed} segment{'s' if removed != 1 else ''}, {announcements} "
              f"announcement{'s' if announcements != 1 else ''} and {pools} "
              f"tensor pool{'s' if pools != 1 else ''} left by dead processes")
    return EXIT_OK


def register(commands) -> None:
    shm = commands.group("shm", "shared-memory segments: list, clean")
    commands.action(shm, "list", "the namespace's segments, log ring, presence folder, parameter "
                    "stores and frame tree, and who uses them", shm_list)
    commands.action(shm, "clean", "remove the segments, log ring, presence folder, parameter "
                    "stores, frame tree and tensor pools whose every user died (never a live "
                    "one's)", shm_clean)
