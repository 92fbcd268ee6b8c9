"""SchedulerConfig::network(): a C++ scheduler (network_peer.cpp) runs `horus bridge` as its
child process. Two namespaces that share no memory, DDS on loopback: a topic the C++ program
exports reaches a bridge's namespace in order, one a bridge exports reaches the C++ program;
the child ends with the scheduler, also when the scheduler is SIGKILLed; a bridge that fails
stops the scheduler; a missing bridge program and invalid Network fields are refused."""
from __future__ import annotations

import contextlib
import os
import pathlib
import signal

from processes import wait_line, wait_until
from test_bridge import COUNT, HORUS, PUBLISHER, SUBSCRIBER, assert_in_order, bridge, \
    python_env, sequences

NETWORK_PEER = os.environ.get("HORUS_DDS_NETWORK_PEER", "")


def peer_env(world, generated, program: str = HORUS) -> dict:
    return python_env(world, generated) | {"HORUS_BRIDGE_PROGRAM": program}


def children_of(pid: int) -> list[int]:
    """The live processes whose parent is `pid` (from /proc)."""
    found = []
    for stat in pathlib.Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # ended meanwhile
        if int(fields[1]) == pid and fields[0] != "Z":
            found.append(int(stat.parent.name))
    return found


@contextlib.contextmanager
def killed_at_the_end(pid: int):
    """Kills `pid` if it still runs when the test ends: a bridge left behind keeps the test's
    pipes open, and reading them to the end would hang instead of failing."""
    try:
        yield
    finally:
        if not ended(pid):
            os.kill(pid, signal.SIGKILL)


def ended(pid: int) -> bool:
    """Whether `pid` is gone or a zombie (whoever inherited it may not reap it at once)."""
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return True


def test_a_topic_a_cpp_scheduler_exports_crosses_in_order_and_its_bridge_ends_with_it(
        dds_domain, worlds, children, generated):
    source, target = worlds
    subscriber = children.python(SUBSCRIBER, python_env(target, generated), str(COUNT), "cmd_vel")
    wait_line(subscriber, "ready")
    bridge(children, target, generated, dds_domain, "--import", "cmd_vel")
    program = children.start([NETWORK_PEER, "export", str(dds_domain)],
                             peer_env(source, generated))
    wait_line(program, "exporting 'cmd_vel'")
    [bridge_pid] = children_of(program.pid)
    with killed_at_the_end(bridge_pid):
        # A group of its own: a terminal's Ctrl+C reaches the scheduler, which ends the bridge.
        assert os.getpgid(bridge_pid) == bridge_pid != os.getpgid(program.pid)
        assert_in_order("cmd_vel", sequences(subscriber)["cmd_vel"])
        program.send_signal(signal.SIGINT)
        _, errors = program.communicate(timeout=30)
        assert program.returncode == 0, errors
        assert ended(bridge_pid), f"the bridge (pid {bridge_pid}) outlived its scheduler"


def test_a_topic_a_bridge_exports_reaches_a_cpp_scheduler_that_imports_it_in_order(
        dds_domain, worlds, children, generated):
    source, target = worlds
    program = children.start([NETWORK_PEER, "import", str(dds_domain), str(COUNT)],
                             peer_env(target, generated))
    wait_line(program, "bridge on DDS domain")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    bridge(children, source, generated, dds_domain, "--export", "cmd_vel")

    out, errors = program.communicate(timeout=120)
    assert program.returncode == 0, errors
    assert "importing rt/cmd_vel" in out, out
    seen = [int(n) for n in out.splitlines()[-1].split()[1:]]
    assert_in_order("cmd_vel", seen)


def test_the_bridge_of_a_sigkilled_scheduler_ends_too(dds_domain, worlds, children, generated):
    # No HORUS_BRIDGE_PROGRAM: the scheduler finds the build tree's `horus` on its own.
    program = children.start([NETWORK_PEER, "export", str(dds_domain)],
                             peer_env(worlds[0], generated, program=""))
    wait_line(program, "bridge on DDS domain")
    [bridge_pid] = children_of(program.pid)
    with killed_at_the_end(bridge_pid):
        program.kill()
        program.wait()
        wait_until(lambda: ended(bridge_pid), f"the bridge (pid {bridge_pid}) to end")


def test_a_failing_bridge_stops_the_scheduler_which_returns_1(tmp_path, worlds, children):
    # Stands in for `horus bridge`: shows the command line it was given, then fails as the bridge
    # does on a bug of its own.
    failing = tmp_path / "failing-bridge"
    failing.write_text('#!/bin/sh\necho "argv: $*"\n'
                       'echo "horus bridge: stopping: topic \'cmd_vel\': a bug" >&2\nexit 3\n')
    failing.chmod(0o755)
    program = children.start([NETWORK_PEER, "options", "9"],
                             worlds[0].env(HORUS_BRIDGE_PROGRAM=str(failing)))
    out, errors = program.communicate(timeout=30)
    assert program.returncode == 1, (out, errors)
    assert out.splitlines()[0] == (
        f"argv: bridge --namespace={worlds[0].namespace} --domain=9 --depth=7 --best-effort "
        "--export=cmd_* --export=-odd --import=map --transient-local=map --export-service=get_* "
        "--import-service=plan --deadline=cmd_*=200 --deadline=map=2000 --service-timeout=2.5 "
        "--ros2-types=cmd_vel --accept-untyped-writers"), out
    assert "horus bridge: stopping: topic 'cmd_vel': a bug" in errors, errors
    assert "stopped: network: the bridge process (pid " in errors, errors
    assert ") exited with status 3" in errors, errors


def test_a_missing_or_unrunnable_bridge_program_is_a_clear_error(tmp_path, worlds, children):
    unrunnable = tmp_path / "not-a-program"
    unrunnable.write_bytes(b"\x00\x01 no interpreter, no ELF")
    unrunnable.chmod(0o755)
    for program, expected in (
            (tmp_path / "none", f"HORUS_BRIDGE_PROGRAM is '{tmp_path / 'none'}', which is no "
                                "executable"),
            ("no-such-horus", "HORUS_BRIDGE_PROGRAM is 'no-such-horus', which is no executable "
                              "on PATH"),
            (unrunnable, f"cannot run {unrunnable}: Exec format error")):
        peer = children.start([NETWORK_PEER, "export", "9"],
                              worlds[0].env(HORUS_BRIDGE_PROGRAM=str(program)))
        _, errors = peer.communicate(timeout=30)
        assert peer.returncode == 2, errors
        assert errors.strip() == f"error: horus::Scheduler 'network_peer': network: {expected}"


def test_invalid_network_fields_are_refused(children):
    peer = children.start([NETWORK_PEER, "invalid"])
    out, errors = peer.communicate(timeout=30)
    assert peer.returncode == 0, errors
    prefix = "refused: horus::Scheduler 'horus_dds_network_peer': network: "  # the program's name
    assert out.splitlines() == [prefix + line for line in (
        "a Network carries nothing: give export_ and/or import_ patterns (or export_services, "
        "import_services)",
        "domain must be a DDS domain id (0..232), got 233",
        "domain must be a DDS domain id (0..232), got -1",
        "depth must be at least 1, got 0",
        "the deadline of 'a' must be at least 1 ms, got 0 ms",
        "export_ has an empty pattern, which names nothing",
        "service_timeout must be a finite number of seconds above 0, got 0 s")], out
