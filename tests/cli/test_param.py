"""`horus param` against a live Python node process that declares parameters: list, get, set,
describe, watch, dump and load, as text and --json; refusals (out of range, vetoed by the node,
read-only) are exit status 1 with the reason; --namespace; did-you-mean; the parameter service
left out of `service list`."""
from __future__ import annotations

import json
import os
import subprocess

import pytest
import yaml
from conftest import HORUS, run_horus
from peer_scripts import param_motor
from processes import command_refused, command_succeeded, wait_line, wait_until

# The node: one parameter of each kind (peer_scripts.param_motor, and a read-only count).
MOTOR = param_motor('self.declare_param("wheels", 4, type="u8", read_only=True)')


@pytest.fixture
def motor(children):
    process = children.python(MOTOR)
    wait_line(process, "ready")
    return process


def ok(*args: str) -> subprocess.CompletedProcess:
    return command_succeeded(run_horus(*args), args)


def refused(*args: str) -> str:
    reason = command_refused(run_horus(*args), args)
    assert "\n" not in reason.strip(), reason
    return reason


def test_help_of_every_action_exits_zero():
    for action in ("", "list", "get", "set", "describe", "watch", "dump", "load"):
        result = run_horus("param", *([action] if action else []), "--help")
        assert result.returncode == 0, (action, result.stderr)
        assert result.stdout.startswith(f"usage: horus param {action}".rstrip())


def test_no_node_with_parameters_is_an_empty_listing():
    assert ok("param", "list").stdout.splitlines()[1:] == []
    assert json.loads(ok("param", "list", "--json").stdout) == []
    assert "no node 'motor' with parameters" in refused("param", "get", "motor", "max_speed")


def test_list_shows_every_parameter_with_its_value_and_owner(motor):
    text = ok("param", "list").stdout
    header, *rows = text.splitlines()
    assert header.split() == ["NODE", "NAME", "TYPE", "VALUE", "UNIT", "VERSION", "OWNER"]
    assert rows[0].split() == ["motor", "max_speed", "f64", "1.0", "m/s", "1", "pid",
                               str(motor.pid)]
    assert rows[2].split()[:4] == ["motor", "gains", "[f64;", "3]"]
    listed = json.loads(ok("param", "list", "motor", "--json").stdout)
    assert [p["name"] for p in listed] == ["max_speed", "profile", "gains", "wheels"]
    assert listed[0]["value"] == 1.0 and listed[0]["owner_alive"] is True
    assert listed[3]["read_only"] is True
    assert ok("param", "list", "--names").stdout.split() == ["motor"]
    assert ok("param", "list", "motor", "--names").stdout.split() == [
        "max_speed", "profile", "gains", "wheels"]


def test_get_and_describe(motor):
    assert ok("param", "get", "motor", "max_speed").stdout == "1.0\n"
    assert ok("param", "get", "motor", "gains").stdout == "[1.0, 0.5, 0.0]\n"
    got = json.loads(ok("param", "get", "motor", "profile", "--json").stdout)
    assert (got["value"], got["version"], got["choices"]) == ("eco", 1, ["eco", "sport", "track"])
    described = ok("param", "describe", "motor", "max_speed").stdout
    for line in ("parameter: motor.max_speed", "type: f64", "value: 1.0 (version 1)",
                 "range: [0, 2]", "unit: m/s", "doc: Top speed the planner may command.",
                 f"owner: pid {motor.pid}"):
        assert line in described.splitlines(), described
    assert json.loads(ok("param", "describe", "motor", "wheels", "--json").stdout)["read_only"]


def test_set_changes_the_value_once_through_the_node(motor):
    result = ok("param", "set", "motor", "max_speed", "1.5")
    assert result.stdout == "motor.max_speed = 1.5 (version 2)\n"
    assert wait_line(motor, "change") == "change max_speed 1.5 horus param"
    assert ok("param", "get", "motor", "max_speed").stdout == "1.5\n"
    answer = json.loads(ok("param", "set", "motor", "gains", "[2, 0.25, 0]", "--json").stdout)
    assert answer["accepted"] and answer["value"] == [2.0, 0.25, 0.0] and answer["version"] == 2
    assert wait_line(motor, "change") == "change gains [2.0, 0.25, 0.0] horus param"


def test_refused_writes_exit_1_with_the_reason_and_change_nothing(motor):
    assert "above the maximum 2" in refused("param", "set", "motor", "max_speed", "7")
    answer = run_horus("param", "set", "motor", "max_speed", "7", "--json")
    assert answer.returncode == 1
    assert json.loads(answer.stdout)["accepted"] is False
    assert "track mode needs the cage closed" in refused("param", "set", "motor", "profile",
                                                         "track")
    assert "read-only" in refused("param", "set", "motor", "wheels", "6")
    for name, value in (("max_speed", 1.0), ("profile", "eco"), ("wheels", 4)):
        got = json.loads(ok("param", "get", "motor", name, "--json").stdout)
        assert (got["value"], got["version"]) == (value, 1)


def test_unknown_nodes_and_parameters_name_the_closest(motor):
    assert "did you mean 'motor'?" in refused("param", "get", "motr", "max_speed")
    assert "did you mean 'max_speed'?" in refused("param", "get", "motor", "max_sped")
    assert "did you mean 'profile'?" in refused("param", "set", "motor", "profil", "eco")


def test_watch_prints_each_change(motor, children):
    watcher = children.start([HORUS, "param", "watch", "motor", "profile", "--count", "1",
                              "--json"])
    # The watcher is ready once it has the store open; a change before that is not its to see.
    wait_until(lambda: _reads_store(watcher.pid), "the watcher to open the store")
    ok("param", "set", "motor", "max_speed", "0.5")  # another parameter: not printed
    ok("param", "set", "motor", "profile", "sport")
    out, err = watcher.communicate(timeout=20)
    assert watcher.returncode == 0, err
    assert json.loads(out) == {"node": "motor", "name": "profile", "value": "sport",
                               "version": 2}


def _reads_store(pid: int) -> bool:
    """Whether the process has a parameter store mapped."""
    try:
        with open(f"/proc/{pid}/maps") as maps:
            return "/@params/" in maps.read()
    except OSError:
        return False


def test_dump_then_load_round_trips(motor, tmp_path):
    values = {"motor": {"max_speed": 1.0, "profile": "eco", "gains": [1.0, 0.5, 0.0],
                        "wheels": 4}}
    assert yaml.safe_load(ok("param", "dump").stdout) == values
    assert json.loads(ok("param", "dump", "motor", "--json").stdout) == values
    values["motor"].update(profile="sport", max_speed=1.25)  # read-only "wheels" unchanged
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(values))
    assert "set" in ok("param", "load", str(path)).stdout
    assert ok("param", "get", "motor", "profile").stdout == "sport\n"
    assert ok("param", "get", "motor", "max_speed").stdout == "1.25\n"
    bad = tmp_path / "bad.yaml"
    bad.write_text("motor:\n  max_speed: 9\n")
    assert "bad.yaml:2" in refused("param", "load", str(bad))
    assert ok("param", "get", "motor", "max_speed").stdout == "1.25\n"


def test_namespace_option_reaches_another_namespace(children, namespace):
    other = f"{namespace}_other"
    process = children.python(MOTOR, {**os.environ, "HORUS_NAMESPACE": other})
    wait_line(process, "ready")
    assert ok("param", "list", "--names").stdout == ""
    assert ok("param", "list", "--names", "--namespace", other).stdout.split() == ["motor"]
    assert ok("param", "set", "motor", "max_speed", "0.75", "-n", other).returncode == 0
    assert ok("param", "get", "motor", "max_speed", "-n", other).stdout == "0.75\n"


def test_service_list_leaves_out_the_parameter_service(motor):
    assert ok("service", "list").stdout == ""
    hidden = ok("service", "list", "--include-hidden").stdout.split()
    assert len(hidden) == 1 and "motor" in hidden[0]
    assert all("motor" not in line for line in ok("topic", "list").stdout.splitlines())


def test_completion_offers_nodes_and_parameters(motor):
    script = ok("completion").stdout
    environment = dict(os.environ, PATH=f"{os.path.dirname(HORUS)}:{os.environ['PATH']}")

    def complete(*words: str) -> list[str]:
        line = " ".join(f"'{word}'" for word in ("horus", *words))
        completed = subprocess.run(
            ["bash", "-c", f'{script}\nCOMP_WORDS=({line}); COMP_CWORD={len(words)}; _horus; '
                           'printf "%s\\n" "${COMPREPLY[@]}"'],
            capture_output=True, text=True, env=environment, timeout=30)
        assert completed.returncode == 0, completed.stderr
        return sorted(completed.stdout.split())

    assert complete("param", "g") == ["get"]
    assert complete("param", "get", "") == ["motor"]
    assert complete("param", "set", "mo") == ["motor"]
    assert complete("param", "describe", "motor", "max") == ["max_speed"]
    assert complete("param", "dump", "motor", "") == ["motor"]


@pytest.mark.parametrize("stop", ["terminate", "kill"])
def test_a_stopped_node_is_shown_and_written_only_for_its_next_start(children, stop):
    first = children.python(MOTOR)
    wait_line(first, "ready")
    getattr(first, stop)()  # SIGTERM: it shuts down; SIGKILL: it leaves its store as it was
    first.communicate(timeout=20)
    row = ok("param", "list").stdout.splitlines()[1].split()
    assert row[:4] == ["motor", "max_speed", "f64", "1.0"] and row[-2:] == ["not", "running"]
    assert "not running" in refused("param", "set", "motor", "max_speed", "1.5")
    assert ok("param", "set", "motor", "max_speed", "1.5", "--persist").returncode == 0
    second = children.python(MOTOR)
    wait_line(second, "ready")
    got = json.loads(ok("param", "get", "motor", "max_speed", "--json").stdout)
    assert (got["value"], got["owner_pid"]) == (1.5, second.pid)
