"""Parameters end to end, in real processes and both languages: a C++ and a Python node of
tests/schemas/test_nodes/param_node.hnode (param_node.cpp, py_param_node.py), each a process of
its own whose ticks read the generated accessors, and this test process as the third, through the
`horus` command and horus.Params. Writes while the nodes tick reach each node's callback once and
then its tick; refusals (out of range, vetoed by the node, read-only) say why and change nothing;
a YAML dump, edited and loaded, changes both nodes; YAML errors name file and line; a SIGKILLed
node leaves a store that its next start takes over."""
from __future__ import annotations

import json
import subprocess

import horus
import pytest
import yaml
from conftest import NAMES, run_horus
from processes import command_refused, command_succeeded

# What a node's tick prints before anything is written: the .hnode's defaults.
DEFAULT_LINE = {"max_speed": "1", "gain": "0.5", "offset": "0", "wheel_count": "4",
                "enabled": "true", "profile": "eco", "mode": "Run", "gains": "1,0.5,0",
                "mask": "true,false", "ticks": "0"}
# The same defaults as plain values (horus.Params, `horus param dump`).
DEFAULTS = {"max_speed": 1.0, "gain": 0.5, "offset": 0, "wheel_count": 4, "enabled": True,
            "profile": "eco", "mode": "Run", "gains": [1.0, 0.5, 0.0], "mask": [True, False],
            "ticks": 0}


def ok(*args: str) -> subprocess.CompletedProcess:
    return command_succeeded(run_horus(*args), args)


def refused(*args: str) -> str:
    return command_refused(run_horus(*args), args)


def values_of(line: str) -> dict:
    """`ready max_speed=1 gain=0.5 ...` as {"max_speed": "1", ...}."""
    return dict(item.split("=", 1) for item in line.split()[1:])


def lines_until(process, expected: str) -> list[str]:
    """The child's stdout lines up to and including the first that starts with `expected`."""
    seen = []
    while not seen or not seen[-1].startswith(expected):
        line = process.stdout.readline()
        assert line, f"the node ended after {seen}"
        seen.append(line.rstrip())
    return seen


def value_and_version(node: str, name: str) -> tuple:
    with horus.Params(node) as params:
        info = params.get(name)
        return info.value, info.version


def test_another_process_reads_each_nodes_declarations_and_values(nodes, language):
    node = nodes.start(language)
    name = NAMES[language]
    assert values_of(node.ready) == DEFAULT_LINE

    listed = json.loads(ok("param", "list", name, "--json").stdout)
    assert [p["name"] for p in listed] == list(DEFAULTS)
    assert {p["name"]: p["value"] for p in listed} == DEFAULTS
    assert {p["version"] for p in listed} == {1}
    assert all(p["owner_alive"] for p in listed)
    described = ok("param", "describe", name, "max_speed").stdout.splitlines()
    for line in ("type: f64", "range: [0, 2]", "unit: m/s",
                 "doc: Top speed the planner may command.", f"owner: pid {node.pid}"):
        assert line in described, described

    with horus.Params(name) as params:
        assert params.owner_alive and params.owner_pid == node.pid
        assert {info.name: info.value for info in params.list()} == DEFAULTS
        mode = params.get("mode")
        assert (mode.type, mode.choices, mode.enumerators) == ("test_msgs.Mode", ["Idle", "Run"],
                                                              ["Idle", "Run", "Fault"])
        assert params.get("wheel_count").read_only
    assert horus.param_nodes() == [name]


def test_set_while_ticking_reaches_the_callback_once_then_the_tick(nodes, language):
    node = nodes.start(language)
    name = NAMES[language]

    assert ok("param", "set", name, "max_speed", "1.5").stdout == (
        f"{name}.max_speed = 1.5 (version 2)\n")
    assert lines_until(node, "tick ") == ["change max_speed 1.5 horus param",
                                          node.ready.replace("ready", "tick").replace(
                                              "max_speed=1 ", "max_speed=1.5 ")]
    # A second write, from horus.Params: the next lines are its own, so the first reached the
    # callback exactly once.
    with horus.Params(name) as params:
        result = params.set("offset", -3, source="e2e test")
        assert (result.accepted, result.reason, result.version) == (True, "", 2)
    assert lines_until(node, "tick ")[0] == "change offset -3 e2e test"

    ok("param", "set", name, "mode", "Idle")
    ok("param", "set", name, "gains", "[0.5, -0.5, 0.25]")
    ok("param", "set", name, "profile", "sport")
    changes = [line for line in lines_until(node, "change profile") if line.startswith("change")]
    assert changes == ["change mode Idle horus param", "change gains 0.5,-0.5,0.25 horus param",
                       "change profile sport horus param"]
    ticked = values_of(lines_until(node, "tick ")[-1])
    assert (ticked["max_speed"], ticked["offset"], ticked["mode"], ticked["gains"],
            ticked["profile"]) == ("1.5", "-3", "Idle", "0.5,-0.5,0.25", "sport")
    assert value_and_version(name, "max_speed") == (1.5, 2)
    assert value_and_version(name, "mode") == ("Idle", 2)
    assert value_and_version(name, "gain") == (0.5, 1)


def test_out_of_range_vetoed_and_read_only_writes_say_why_and_change_nothing(nodes, language):
    node = nodes.start(language)
    name = NAMES[language]

    assert "above the maximum 2" in refused("param", "set", name, "max_speed", "7")
    assert "a gain above 5 makes the speed loop oscillate" in refused("param", "set", name,
                                                                      "gain", "6")
    assert "read-only" in refused("param", "set", name, "wheel_count", "6")
    assert "not one of the allowed values" in refused("param", "set", name, "profile", "turbo")
    with horus.Params(name) as params:
        below = params.set("max_speed", -1.0)
        assert not below.accepted and "below the minimum 0" in below.reason
        assert below.version == 1
        vetoed = params.set("gain", 9.0, source="e2e test")
        assert not vetoed.accepted and "oscillate" in vetoed.reason and vetoed.version == 1
    for parameter in ("max_speed", "gain", "wheel_count", "profile"):
        assert value_and_version(name, parameter) == (DEFAULTS[parameter], 1)

    # The node was offered only what its declaration allows (the two gains it vetoed), and its
    # ticks never saw a value change: a write it accepts is the next thing it prints.
    ok("param", "set", name, "offset", "1")
    assert lines_until(node, "change offset") == ["change gain 6 horus param",
                                                  "change gain 9 e2e test",
                                                  "change offset 1 horus param"]
    assert values_of(lines_until(node, "tick ")[-1])["gain"] == "0.5"


def test_a_yaml_dump_edited_and_loaded_changes_both_nodes(nodes, tmp_path):
    cpp, python = nodes.start("cpp"), nodes.start("python")
    both = [NAMES["cpp"], NAMES["python"]]
    dumped = ok("param", "dump", *both).stdout
    assert dumped == horus.dump_params(both)
    values = yaml.safe_load(dumped)
    assert values == {NAMES["cpp"]: DEFAULTS, NAMES["python"]: DEFAULTS}

    # The read-only wheel_count stays in the file, unchanged: a dump loads back as it is.
    values[NAMES["cpp"]].update(max_speed=0.75, profile="sport", gains=[0.1, 0.2, 0.3])
    values[NAMES["python"]].update(offset=-4, mode="Idle", mask=[False, True])
    robot = tmp_path / "robot.yaml"
    robot.write_text(yaml.safe_dump(values, sort_keys=False))
    ok("param", "load", str(robot))

    for node, name, changed in (
            (cpp, NAMES["cpp"], {"max_speed": "0.75", "profile": "sport", "gains": "0.1,0.2,0.3"}),
            (python, NAMES["python"], {"offset": "-4", "mode": "Idle", "mask": "false,true"})):
        # Only the values the file changes are offered to the node, each once and from the
        # file; its ticks then read the new ones.
        offered = [line for line in lines_until(node, f"change {max(changed)}")
                   if line.startswith("change")]
        assert sorted(line.split()[1] for line in offered) == sorted(changed)
        assert all(line.endswith(f"yaml:{robot}") for line in offered)
        ticked = values_of(lines_until(node, "tick ")[-1])
        while any(ticked[key] != value for key, value in changed.items()):
            ticked = values_of(lines_until(node, "tick ")[-1])
    reloaded = yaml.safe_load(ok("param", "dump", *both).stdout)
    assert reloaded == {node: {key: values[node][key] for key in DEFAULTS} for node in both}
    assert value_and_version(NAMES["cpp"], "max_speed") == (0.75, 2)
    assert value_and_version(NAMES["python"], "max_speed") == (1.0, 1)  # unchanged: not written
    assert value_and_version(NAMES["python"], "wheel_count") == (4, 1)


def test_yaml_errors_name_file_and_line_and_change_nothing(nodes, tmp_path):
    for language in NAMES:
        nodes.start(language)
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"{NAMES['cpp']}:\n  max_speed: 0.5\n{NAMES['python']}:\n  offset: 3\n"
                   "  profile: turbo\n")
    assert f"{bad}:5:" in refused("param", "load", str(bad))
    with pytest.raises(horus.ParamError, match=f"{bad}:5:"):
        horus.load_params(bad)
    malformed = tmp_path / "malformed.yaml"
    malformed.write_text(f"{NAMES['cpp']}:\n  max_speed: 0.5\n  gains: [1.0, 0.5\n")
    assert f"{malformed}:" in refused("param", "load", str(malformed))
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text(f"{NAMES['cpp']}:\n  max_speed: 0.5\n  max_sped: 0.5\n")
    assert f"{unknown}:3:" in refused("param", "load", str(unknown))
    assert value_and_version(NAMES["cpp"], "max_speed") == (1.0, 1)
    assert value_and_version(NAMES["python"], "offset") == (0, 1)


def test_a_start_with_a_bad_parameter_file_stops_naming_file_and_line(nodes, language,
                                                                      tmp_path):
    name = NAMES[language]
    start = tmp_path / "start.yaml"
    start.write_text(f"# {language}\n{name}:\n  profile: sport\n  max_speed: 9\n")
    child = nodes.launch(language, str(start))
    out, err = child.communicate(timeout=30)
    assert child.returncode != 0 and "ready" not in out
    assert f"{start}:4:" in err and "above the maximum 2" in err, err


def test_a_sigkilled_node_leaves_a_store_its_next_start_uses(nodes, language, tmp_path):
    name = NAMES[language]
    start = tmp_path / "start.yaml"
    start.write_text(f"{name}:\n  max_speed: 0.5\n  profile: sport\n")
    first = nodes.start(language, str(start))
    assert values_of(first.ready)["max_speed"] == "0.5"
    ok("param", "set", name, "offset", "3")
    lines_until(first, "tick ")
    first.kill()
    first.communicate(timeout=20)

    # The store stays, readable, its owner shown as gone; a write is refused unless persisted.
    with horus.Params(name) as params:
        assert not params.owner_alive
        assert (params.get("offset").value, params.get("offset").version) == (3, 2)
        assert params.get("max_speed").value == 0.5
    assert "not running" in refused("param", "set", name, "gain", "2.5")
    assert ok("param", "set", name, "gain", "2.5", "--persist").returncode == 0
    assert "above the maximum 2" in refused("param", "set", name, "max_speed", "3", "--persist")

    # The next start takes the store over: defaults, then the file, then the persisted value;
    # what the killed run was set to while it ran (offset 3) is not kept.
    second = nodes.start(language, str(start))
    assert values_of(second.ready) == dict(DEFAULT_LINE, max_speed="0.5", profile="sport",
                                           gain="2.5")
    with horus.Params(name) as params:
        assert params.owner_alive and params.owner_pid == second.pid
        assert {info.version for info in params.list()} == {1}
    ok("param", "set", name, "max_speed", "1.25")
    assert lines_until(second, "tick ") == [
        "change max_speed 1.25 horus param",
        second.ready.replace("ready", "tick").replace("max_speed=0.5", "max_speed=1.25")]
