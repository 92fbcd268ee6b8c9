"""SchedulerConfig::network(): a C++ scheduler (network_peer.cpp, linked with horus::dds) runs the
DDS bridge on threads of its own process. Two namespaces that share no memory, DDS on loopback: a
topic the C++ program exports reaches a bridge's namespace in order, one a bridge exports reaches
the C++ program; no child process; a SIGKILLed scheduler leaves nothing `horus shm clean` does not
remove, and DDS peers see its writer go; a bridge that fails stops the scheduler (run() returns
1); services cross between two C++ schedulers' bridges as they cross `horus bridge`; every
option is carried, ROS 2 twins too; a program not linked with horus::dds and invalid Network
fields are refused."""
from __future__ import annotations

import os
import pathlib
import signal
import subprocess

from processes import wait_line, wait_until
from test_bridge import COUNT, HORUS, PUBLISHER, SUBSCRIBER, assert_in_order, bridge, \
    python_env, sequences
from test_bridge_service import CPP_CLIENT as SERVICE_PEER, run_client

NETWORK_PEER = os.environ.get("HORUS_DDS_NETWORK_PEER", "")
UNLINKED_PEER = os.environ.get("HORUS_DDS_NETWORK_PEER_UNLINKED", "")


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


def dds_writers(participant, topic: str) -> list[str]:
    """The GUIDs of the writers of DDS topic `topic` that `participant` knows to be alive."""
    return [p["writer"] for p in participant.publications() if p["topic"] == topic]


def test_a_topic_a_cpp_scheduler_exports_crosses_in_order_from_its_own_process(
        dds_domain, worlds, children, generated):
    source, target = worlds
    subscriber = children.python(SUBSCRIBER, python_env(target, generated), str(COUNT), "cmd_vel")
    wait_line(subscriber, "ready")
    bridge(children, target, generated, dds_domain, "--import", "cmd_vel")
    program = children.start([NETWORK_PEER, "export", str(dds_domain)],
                             python_env(source, generated))
    wait_line(program, "exporting 'cmd_vel' (horus.msg.CmdVel) as rt/cmd_vel "
                       "(horus::msg::dds_::CmdVel_)")
    assert children_of(program.pid) == [], "the bridge runs in the scheduler's process"
    assert_in_order("cmd_vel", sequences(subscriber)["cmd_vel"])
    program.send_signal(signal.SIGINT)
    _, errors = program.communicate(timeout=30)
    assert program.returncode == 0, errors


def test_a_topic_a_bridge_exports_reaches_a_cpp_scheduler_that_imports_it_in_order(
        dds_domain, worlds, children, generated):
    source, target = worlds
    program = children.start([NETWORK_PEER, "import", str(dds_domain), str(COUNT)],
                             python_env(target, generated))
    wait_line(program, "bridge on DDS domain")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    bridge(children, source, generated, dds_domain, "--export", "cmd_vel")

    out, errors = program.communicate(timeout=120)
    assert program.returncode == 0, errors
    assert "importing rt/cmd_vel (horus::msg::dds_::CmdVel_) as 'cmd_vel' (horus.msg.CmdVel)" \
        in out, out
    seen = [int(n) for n in out.splitlines()[-1].split()[1:]]
    assert_in_order("cmd_vel", seen)


def test_a_sigkilled_scheduler_leaves_nothing_behind_and_peers_see_its_writer_go(
        dds_domain, worlds, children, generated):
    world = worlds[0]
    program = children.start([NETWORK_PEER, "export", str(dds_domain)],
                             python_env(world, generated))
    wait_line(program, "exporting 'cmd_vel'")
    from horus._core import dds
    peer = dds.Participant(dds_domain)  # one peer throughout: it must see the writer go
    wait_until(lambda: dds_writers(peer, "rt/cmd_vel"), "the scheduler's writer on DDS")
    program.kill()
    program.wait()
    # DDS drops a participant that stopped renewing its lease (Cyclone: 10 s by default).
    wait_until(lambda: not dds_writers(peer, "rt/cmd_vel"),
               "DDS peers to see the killed scheduler's writer go", limit=60)
    cleaned = subprocess.run([HORUS, "shm", "clean"], env=world.env(), capture_output=True,
                             text=True, timeout=60)
    assert cleaned.returncode == 0, cleaned.stderr
    listed = subprocess.run([HORUS, "topic", "list"], env=world.env(), capture_output=True,
                            text=True, timeout=60)
    assert "cmd_vel" not in listed.stdout, listed.stdout


def test_a_failing_bridge_stops_the_scheduler_which_returns_1(dds_domain, worlds, children,
                                                               generated):
    program = children.start([NETWORK_PEER, "export", str(dds_domain)],
                             python_env(worlds[0], generated) | {"HORUS_BRIDGE_FAULT": "cmd_vel"})
    out, errors = program.communicate(timeout=60)
    assert program.returncode == 1, (out, errors)
    assert "horus bridge: stopping: topic 'cmd_vel': a fault injected by HORUS_BRIDGE_FAULT" \
        in errors, errors
    assert "stopped: network: the bridge stopped: topic 'cmd_vel': a fault injected" in errors, \
        errors


def test_a_program_without_the_dds_bridge_is_a_clear_error(worlds, children):
    peer = children.start([UNLINKED_PEER, "export", "9"], worlds[0].env())
    _, errors = peer.communicate(timeout=30)
    assert peer.returncode == 2, errors
    assert errors.strip() == (
        "error: horus::Scheduler 'network_peer': network: this program has no DDS bridge: link "
        "it with horus::dds (target_link_libraries(... horus::dds), built where Cyclone DDS is "
        "installed)")


def test_every_option_is_carried_in_process_a_ros2_twin_too(dds_domain, worlds, children):
    """Every Network field set (network_peer's options): the scheduler runs, and cmd_vel, which
    ros2_types names, leaves as its ROS 2 twin."""
    peer = children.start([NETWORK_PEER, "options", str(dds_domain)], worlds[0].env())
    wait_line(peer, "exporting 'cmd_vel' (horus.msg.CmdVel) as rt/cmd_vel "
                    "(geometry_msgs::msg::dds_::Twist_)")
    peer.send_signal(signal.SIGINT)
    _, errors = peer.communicate(timeout=30)
    assert peer.returncode == 0, errors


def test_a_service_crosses_between_two_cpp_schedulers_bridges(
        dds_domain, worlds, children, generated):
    """A C++ server in A (service_peer.cpp), exported by a C++ scheduler's bridge there, is
    called from B through another's import, by a C++ and a Python client; a handler's failure
    reaches the caller as ServiceFailed; when the server goes, B's callers get NoServer. The
    exporting bridge learns the response type from a reply topic, so a local call in A comes
    first (a C++ program has no Python path to find the type on)."""
    source, target = worlds
    server = children.start([SERVICE_PEER, "serve"], source.env())
    wait_line(server, "ready")
    assert run_client(children, source, generated, "call", "c++") == ["answer 7.5 3 times 2.5"]
    exporting = children.start([NETWORK_PEER, "relay", str(dds_domain), "export-service", "Sc*"],
                               source.env())
    wait_line(exporting, "exporting service 'Scale' as rq/ScaleRequest "
                         "(dds_test::dds_::Scale_Request_) and rr/ScaleReply "
                         "(dds_test::dds_::Scale_Response_)")
    importing = children.start([NETWORK_PEER, "relay", str(dds_domain), "import-service", "*"],
                               target.env())
    wait_line(importing, "importing service 'Scale' from rr/ScaleReply "
                         "(dds_test::dds_::Scale_Response_)")
    assert run_client(children, target, generated, "call", "c++") == ["answer 7.5 3 times 2.5"]
    lines = run_client(children, target, generated, "call")
    assert lines == ["server True"] + [f"answer {2.5 * i} {i:g} times 2.5" for i in range(5)] + [
        "error ServiceFailed on the server's host: a factor of 0"], lines

    server.send_signal(signal.SIGTERM)
    server.communicate(timeout=30)
    wait_line(exporting, "no longer exporting service 'Scale' (its server stopped)")
    wait_line(importing, "no longer importing service 'Scale' (no server on DDS)")
    assert run_client(children, target, generated, "until-no-server") == [
        "error NoServerError no_server"]
    for program in (exporting, importing):
        program.send_signal(signal.SIGTERM)
        _, errors = program.communicate(timeout=30)
        assert program.returncode == 0, errors


def test_invalid_network_fields_are_refused(children):
    peer = children.start([NETWORK_PEER, "invalid"])
    out, errors = peer.communicate(timeout=30)
    assert peer.returncode == 0, errors
    prefix = "refused: horus::Scheduler 'horus_dds_network_peer': network: "  # the program's name
    assert out.splitlines() == [prefix + line for line in (
        "a Network carries nothing: give export_ and/or import_ patterns (or export_services, "
        "import_services, export_frames, import_frames, export_actions, import_actions)",
        "domain must be a DDS domain id (0..232), got 233",
        "domain must be a DDS domain id (0..232), got -1",
        "depth must be at least 1, got 0",
        "the deadline of 'a' must be at least 1 ms, got 0 ms",
        "export_ has an empty pattern, which names nothing",
        "service_timeout must be a finite number of seconds above 0, got 0 s")], out


def test_a_cpp_scheduler_carries_pod_and_serialized_types_it_was_not_compiled_with(
        dds_domain, worlds, children, generated):
    # A Python publisher's pods (every kind of POD field) and kinds (serialized: every kind of
    # field) go out through a C++ scheduler's bridge in A, and in through another's in B, which
    # creates the local topics from the identity the exporting writer carries.
    source, target = worlds
    subscriber = children.python(SUBSCRIBER, python_env(target, generated), str(COUNT), "pods",
                                 "kinds")
    wait_line(subscriber, "ready")
    importing = children.start([NETWORK_PEER, "relay", str(dds_domain), "import", "*"],
                               python_env(target, generated))
    wait_line(importing, "bridge on DDS domain")
    publisher = children.python(PUBLISHER, python_env(source, generated))
    wait_line(publisher, "ready")
    exporting = children.start([NETWORK_PEER, "relay", str(dds_domain), "export", "[kp]*"],
                               python_env(source, generated))
    got = sequences(subscriber)
    for name in ("pods", "kinds"):
        assert_in_order(name, got[name])
    said = {}
    for role, program in (("exporting", exporting), ("importing", importing)):
        program.send_signal(signal.SIGINT)
        said[role], errors = program.communicate(timeout=30)
        assert program.returncode == 0, errors
    assert "exporting 'kinds' (dds_test.Kinds) as rt/kinds (dds_test::dds_::Kinds_)" \
        in said["exporting"], said["exporting"]
    assert "exporting 'pods' (dds_test.Pods) as rt/pods (dds_test::dds_::Pods_)" \
        in said["exporting"], said["exporting"]
    assert "importing rt/kinds (dds_test::dds_::Kinds_) as 'kinds' (dds_test.Kinds)" \
        in said["importing"], said["importing"]
