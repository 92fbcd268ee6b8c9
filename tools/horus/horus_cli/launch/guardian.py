"""The guardian: a process of its own that ends what `horus launch` started when the launcher
itself ends without doing so (SIGKILL, the OOM killer, a crash).

The launcher forks it before it starts anything, keeping the write end of a pipe whose read end
only the guardian holds. Each process the launcher starts writes one line into that pipe between
its fork and its exec (so even a launcher killed in that instant is covered): its process group,
stop timeout and shared-memory namespace. The launcher adds a line when a group is gone and one
when it ended cleanly. The kernel closes the pipe when the launcher dies for whatever reason; the
guardian, reading end-of-file without that last line, does what the launcher's shutdown would:
SIGINT to each group still there in reverse start order, SIGKILL after its stop timeout, then the
clean-up of `horus shm clean` (segments, announcements and pools whose every user died) in each
namespace used.

The guardian runs in a session of its own, so Ctrl+C on the terminal never reaches it, and keeps no
descriptor of the launcher's but the pipe and the launch log.
"""
from __future__ import annotations

import json
import os
import signal
import time

from horus_cli.launch.groups import group_alive, wait_group_gone


def start_guardian(log_path: str) -> tuple[int, int]:
    """Forks the guardian; returns (its pid, the pipe's write end, close-on-exec). Call it before
    the process has threads (the fork copies only the calling one) or descriptors it must not
    share."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.close(write_end)
            _detach(read_end)
            _guard(read_end, log_path)
        finally:
            os._exit(0)
    os.close(read_end)
    return pid, write_end


def start_line(pgid: int, stop_timeout: float, shm_dir: str, namespace: str) -> bytes:
    """What a started process writes into the pipe (one write, below PIPE_BUF, so atomic)."""
    return (json.dumps({"start": pgid, "stop_timeout": stop_timeout, "shm_dir": shm_dir,
                        "namespace": namespace}) + "\n").encode()


def end_line(pgid: int) -> bytes:
    return (json.dumps({"end": pgid}) + "\n").encode()


EXIT_LINE = b'{"exit": true}\n'


def _detach(keep: int) -> None:
    os.setsid()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    null = os.open(os.devnull, os.O_RDWR)
    for fd in (0, 1, 2):
        os.dup2(null, fd)
    for fd in _open_descriptors():
        if fd > 2 and fd != keep:
            try:
                os.close(fd)
            except OSError:
                pass


def _open_descriptors() -> list[int]:
    try:
        return [int(name) for name in os.listdir("/proc/self/fd")]
    except OSError:
        return list(range(3, 1024))


def _guard(read_end: int, log_path: str) -> None:
    groups: dict[int, dict] = {}  # by pgid, in start order
    clean_exit = False
    pending = b""
    while True:
        try:
            chunk = os.read(read_end, 4096)
        except InterruptedError:
            continue
        if not chunk:
            break
        pending += chunk
        *lines, pending = pending.split(b"\n")
        for line in lines:
            try:
                message = json.loads(line)
            except ValueError:
                continue
            if "start" in message:
                groups.pop(message["start"], None)
                groups[message["start"]] = message
            elif "end" in message:
                groups.pop(message["end"], None)
            elif message.get("exit"):
                clean_exit = True
    if not clean_exit:
        _sweep(list(groups.values()), log_path)


def _log(log_path: str, text: str) -> None:
    try:
        with open(log_path, "a", encoding="utf-8") as log:
            log.write(f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} guardian: {text}\n")
    except OSError:
        pass


def _sweep(groups: list[dict], log_path: str) -> None:
    """Ends the groups still there in reverse start order, then cleans their namespaces."""
    live = [group for group in groups if group_alive(group["start"])]
    if live:
        _log(log_path, f"the launcher ended without stopping its processes: stopping "
                       f"{len(live)} process group(s)")
    for group in reversed(live):
        pgid = group["start"]
        try:
            os.killpg(pgid, signal.SIGINT)
        except OSError:
            continue
        if not wait_group_gone(pgid, group["stop_timeout"]):
            _log(log_path, f"process group {pgid} still there after {group['stop_timeout']} s: "
                           "SIGKILL")
            try:
                os.killpg(pgid, signal.SIGKILL)
            except OSError:
                pass
            wait_group_gone(pgid, 2.0)
    _clean_namespaces(groups, log_path)


def _clean_namespaces(groups: list[dict], log_path: str) -> None:
    places = {(group["shm_dir"], group["namespace"]) for group in groups}
    if not places:
        return
    try:
        from horus import introspection
    except Exception as error:  # noqa: BLE001 (the guardian has nobody to raise to)
        _log(log_path, f"cannot clean shared memory: {error}")
        return
    for shm_dir, namespace in sorted(places):
        if shm_dir:
            os.environ["HORUS_SHM_DIR"] = shm_dir
        else:
            os.environ.pop("HORUS_SHM_DIR", None)
        try:
            removed = introspection.clean_namespace(namespace)
            introspection.clean_presence(namespace)
            introspection.clean_pools(namespace)
            _log(log_path, f"namespace '{namespace}': removed {removed} segment(s) left by "
                           "dead processes")
        except Exception as error:  # noqa: BLE001
            _log(log_path, f"namespace '{namespace}': cannot clean: {error}")
