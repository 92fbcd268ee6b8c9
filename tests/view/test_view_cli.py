"""`horus view` (tools/horus/horus_cli/commands/view.py): serving with no action word and the
server's own options passed through, and `horus view status` showing a Foxglove client's
subscription with what it was sent, as a table and as JSON."""
from __future__ import annotations

import json
import os
import subprocess
import threading

import horus
import pytest
from conftest import run_node_client
from horus.msg import CmdVel
from processes import wait_line, wait_until

# Set by tests/view/CMakeLists.txt: the build tree's bin/horus.
CLI = os.environ.get("HORUS_CLI", "")


def horus_command(*argv: str) -> subprocess.CompletedProcess:
    assert CLI, "HORUS_CLI names build/bin/horus; run this suite through ctest (pytest_view_cli)"
    return subprocess.run([CLI, *argv], capture_output=True, text=True, timeout=60)


@pytest.fixture
def served(namespace, children) -> str:
    """`horus view --port 0` (serve, the action when none is named) in the test's namespace;
    the URL it prints once listening."""
    process = children.start([CLI, "view", "--port", "0"], dict(os.environ))
    return wait_line(process, "ready ws://").split(" ", 1)[1]


def publishing(stop: threading.Event) -> threading.Thread:
    cmd_vel = horus.Topic(CmdVel, "cmd_vel")

    def publish() -> None:
        count = 0
        while not stop.wait(0.02):
            count += 1
            cmd_vel.send(CmdVel(stamp_nanos=count, linear=0.5, angular=0.0))
    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    return thread


def test_serve_is_the_default_action_and_a_client_reads_through_it(served):
    stop = threading.Event()
    thread = publishing(stop)
    try:
        result = run_node_client(served, {"topics": ["cmd_vel"], "subscribe": {"cmd_vel": 2}})
    finally:
        stop.set()
        thread.join()
    (run,) = result["runs"].values()
    assert "error" not in run, run
    assert [m["linear"] for m in run["messages"]["cmd_vel"]["decoded"]] == [0.5, 0.5]


def test_status_shows_a_clients_subscription_and_what_it_was_sent(served, namespace):
    stop = threading.Event()
    thread = publishing(stop)
    client = subprocess.Popen(
        ["node", os.path.join(os.environ["HORUS_VIEW_NODE_CLIENT"], "client_check.mjs"), served,
         json.dumps({"topics": ["cmd_vel"],
                     "measure": {"topics": ["cmd_vel"], "warmup_s": 0, "seconds": 8}})],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        def subscribed_and_sent():
            done = horus_command("view", "status", "--json")
            assert done.returncode == 0, done.stderr
            servers = json.loads(done.stdout)
            subscriptions = [s for server in servers for c in server["clients"]
                             for s in c["subscriptions"]]
            return servers if any(s["topic"] == "cmd_vel" and s["sent"] > 0
                                  for s in subscriptions) else None
        servers = wait_until(subscribed_and_sent, "a cmd_vel subscription with messages sent "
                             "in `horus view status --json`")
        (server,) = servers
        assert server["namespace"] == namespace
        assert server["listen"] == served
        assert len(server["clients"]) == 1

        text = horus_command("view", "status")
        assert text.returncode == 0, text.stderr
        lines = text.stdout.splitlines()
        assert lines[0].startswith(f"horus-view {server['pid']} on {served}: 1 client,"), lines
        assert lines[1].split() == ["PID", "CLIENT", "ADDRESS", "TOPIC", "SENT", "DROPPED",
                                    "MAX", "HZ"], lines
        row = lines[2].split()
        assert row[0] == str(server["pid"]) and row[3] == "cmd_vel" and int(row[4]) > 0, lines
    finally:
        client.kill()
        client.communicate()
        stop.set()
        thread.join()


def test_status_of_a_namespace_nobody_serves(namespace):
    done = horus_command("view", "status")
    assert (done.returncode, done.stdout.strip()) == (
        0, f"no horus view serves namespace '{namespace}'")
    assert json.loads(horus_command("view", "status", "--json").stdout) == []


def test_the_servers_options_pass_through_and_its_refusals_reach_the_user(namespace):
    # An option of horus-view's own, refused by it with its usage (exit status 2).
    done = horus_command("view", "serve", "--port", "70000")
    assert done.returncode == 2, done
    assert "--port needs a port number from 0 to 65535, not '70000'" in done.stderr
    done = horus_command("view", "--no-such-option")
    assert done.returncode == 2 and "unknown argument --no-such-option" in done.stderr, done
    # Its help, through `horus view serve --help`.
    done = horus_command("view", "serve", "--help")
    assert done.returncode == 0 and "horus-view serve" in done.stdout, done


def test_a_missing_server_program_is_named(namespace):
    environment = dict(os.environ, HORUS_VIEW_PROGRAM="/nonexistent/horus-view")
    done = subprocess.run([CLI, "view"], capture_output=True, text=True, timeout=60,
                          env=environment)
    assert done.returncode == 1
    assert done.stderr.startswith("horus: cannot run /nonexistent/horus-view: it is not there"), \
        done.stderr


def test_completion_offers_the_actions():
    script = horus_command("completion").stdout
    assert 'view) words="serve status" ;;' in script
    assert "view" in script.split('words="', 1)[1].split('"', 1)[0].split()
