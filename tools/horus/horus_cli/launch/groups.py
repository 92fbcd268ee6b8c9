"""Process groups as /proc shows them: whether one still has a live member, and waiting until it
has none. Every process `horus launch` starts leads a group of its own, which its children join
unless they leave it on purpose; a zombie (ended, not yet reaped) is no longer a member."""
from __future__ import annotations

import os
import time


def _live_processes():
    """(pid, ppid, pgrp) of every live (not zombie) process."""
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as stat:
                fields = stat.read().rpartition(b")")[2].split()
        except OSError:
            continue  # ended meanwhile
        # After the command's closing parenthesis: state, ppid, pgrp.
        if len(fields) >= 3 and fields[0] not in (b"Z", b"X"):
            yield int(name), int(fields[1]), int(fields[2])


def group_members(pgid: int) -> list[int]:
    """The live (not zombie) processes of a process group."""
    return [pid for pid, _, pgrp in _live_processes() if pgrp == pgid]


def _state(pid: int) -> bytes | None:
    """A process's state letter (R, S, Z...), or None when there is none by that pid."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rpartition(b")")[2].split()[0]
    except (OSError, IndexError):
        return None


def process_running(pid: int) -> bool:
    """Whether a process runs: a zombie (ended, not yet reaped by its parent) does not."""
    return _state(pid) not in (None, b"Z", b"X")


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return bool(group_members(pgid))


def wait_group_gone(pgid: int, limit: float) -> bool:
    """Whether the group is gone within `limit` seconds."""
    deadline = time.monotonic() + limit
    while group_alive(pgid):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.02)
    return True


def adopted_children() -> list[int]:
    """The live processes whose parent is this one: with PR_SET_CHILD_SUBREAPER, the orphans of
    the processes this one started (a daemon that left its group) as well as its own children."""
    me = os.getpid()
    return [pid for pid, ppid, _ in _live_processes() if ppid == me]
