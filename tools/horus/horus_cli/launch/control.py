"""Control of a running launch from another terminal: the per-user folder of the launches' sockets,
the socket a launcher serves, and the requests `horus launch status|stop|restart` send it.

Each running launcher listens on `<folder>/<NAME>.<PID>.sock`, the folder being
`$XDG_RUNTIME_DIR/horus-launch` or else `/tmp/horus-launch-<UID>`. As every shared object of
HORUS, the folder is judged on an open descriptor (O_NOFOLLOW): it must be a folder of this user
that no other user can enter (mode 0700 when created; no group or other bits accepted), so no
other user can plant, read or connect to a socket in it. The launcher also checks each peer's
credentials (SO_PEERCRED): only this user (or root) is answered.

A request is one JSON line ({"command": "status" | "stop" | "restart", "process": NAME or null});
the answer is one JSON line ({"ok": true, ...} or {"ok": false, "error": TEXT}).
"""
from __future__ import annotations

import contextlib
import json
import os
import socket
import stat
import struct

# Longer requests are refused: the control socket is no channel for data.
MAX_REQUEST_BYTES = 64 * 1024


class ControlError(Exception):
    """A refusal of the control folder or socket, or a launch that does not answer."""


def control_folder() -> str:
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime:
        return os.path.join(runtime, "horus-launch")
    return f"/tmp/horus-launch-{os.geteuid()}"


def checked_folder(create: bool) -> str | None:
    """The control folder after its check (created 0700 when missing and `create`), or None when
    it does not exist and is not to be created. Raises ControlError naming the path, its owner
    and mode and the way out when another user could use it."""
    path = control_folder()
    if create:
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            pass
        except OSError as error:
            raise ControlError(f"cannot create the launch control folder {path}: "
                               f"{error.strerror}") from error
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    except FileNotFoundError:
        return None
    except OSError as error:
        raise ControlError(f"the launch control folder {path} cannot be opened ({error.strerror}"
                           "): it must be a folder of yours, not a symbolic link (remove it, or "
                           "set XDG_RUNTIME_DIR to a folder of your own)") from error
    try:
        status = os.fstat(fd)
    finally:
        os.close(fd)
    if status.st_uid != os.geteuid():
        raise ControlError(f"the launch control folder {path} belongs to uid {status.st_uid}, not "
                           f"to you (uid {os.geteuid()}): another user could control your "
                           "launches (set XDG_RUNTIME_DIR to a folder of your own)")
    if status.st_mode & 0o077:
        raise ControlError(f"the launch control folder {path} has mode "
                           f"{stat.S_IMODE(status.st_mode):04o}: other users could reach your "
                           f"launches (chmod 700 {path})")
    return path


def socket_path(folder: str, name: str, pid: int) -> str:
    return os.path.join(folder, f"{name}.{pid}.sock")


@contextlib.contextmanager
def _short_path(path: str):
    """`path` as the socket calls take it: through the folder's open descriptor
    (/proc/self/fd/N/NAME), so that a long folder (a deep XDG_RUNTIME_DIR) never meets sun_path's
    108 bytes, and the folder bound or connected in is the one opened without following a link."""
    fd = os.open(os.path.dirname(path), os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    try:
        yield f"/proc/self/fd/{fd}/{os.path.basename(path)}"
    finally:
        os.close(fd)


def listen(name: str) -> tuple[socket.socket, str]:
    """The launcher's control socket (non-blocking), bound in the checked folder."""
    folder = checked_folder(create=True)
    path = socket_path(folder, name, os.getpid())
    if len(os.path.basename(path).encode()) >= 90:  # sun_path, less "/proc/self/fd/N/"
        raise ControlError(f"the control socket name {os.path.basename(path)} is too long for a "
                           "Unix socket (give the launch a shorter name: `name:` in the file)")
    try:
        os.unlink(path)  # a socket of a dead launcher that had this pid
    except FileNotFoundError:
        pass
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old_mask = os.umask(0o177)
    try:
        with _short_path(path) as short:
            server.bind(short)
    finally:
        os.umask(old_mask)
    server.listen(8)
    server.setblocking(False)
    return server, path


def peer_allowed(connection: socket.socket) -> bool:
    """Whether the other end runs as this user (or root)."""
    credentials = connection.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED,
                                        struct.calcsize("3i"))
    _, uid, _ = struct.unpack("3i", credentials)
    return uid in (os.geteuid(), 0)


def read_request(connection: socket.socket) -> dict:
    """One request line; ValueError when it is none."""
    data = b""
    while not data.endswith(b"\n"):
        chunk = connection.recv(4096)
        if not chunk:
            break
        data += chunk
        if len(data) > MAX_REQUEST_BYTES:
            raise ValueError("request too long")
    request = json.loads(data)
    if not isinstance(request, dict) or not isinstance(request.get("command"), str):
        raise ValueError("not a request")
    return request


def running_launches() -> list[dict]:
    """The launches of this user that run: name, pid and socket path, by name then pid. Sockets of
    launchers that died without removing them are removed here."""
    folder = checked_folder(create=False)
    if folder is None:
        return []
    found = []
    for entry in sorted(os.listdir(folder)):
        stem, dot, pid = entry.removesuffix(".sock").rpartition(".")
        if not entry.endswith(".sock") or not dot or not pid.isdigit():
            continue
        path = os.path.join(folder, entry)
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            try:
                os.unlink(path)
            except OSError:
                pass
            continue
        except PermissionError:
            pass
        found.append({"name": stem, "pid": int(pid), "socket": path})
    return sorted(found, key=lambda launch: (launch["name"], launch["pid"]))


def ask(path: str, command: str, process: str | None = None, timeout: float = 5.0) -> dict:
    """Sends one request to the launch serving `path`; its answer. Raises ControlError when it
    does not answer or refuses."""
    client = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    client.settimeout(timeout)
    try:
        with _short_path(path) as short:
            client.connect(short)
        client.sendall((json.dumps({"command": command, "process": process}) + "\n").encode())
        data = b""
        while not data.endswith(b"\n"):
            chunk = client.recv(65536)
            if not chunk:
                break
            data += chunk
    except OSError as error:
        raise ControlError(f"the launch at {path} does not answer ({error})") from error
    finally:
        client.close()
    try:
        answer = json.loads(data)
    except ValueError as error:
        raise ControlError(f"the launch at {path} answered no JSON: {data[:200]!r}") from error
    if not answer.get("ok"):
        raise ControlError(answer.get("error", "refused"))
    return answer
