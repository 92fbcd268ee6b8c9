"""Launch files read into plans (tools/horus/horus_cli/launch/plan.py): substitutions, includes,
arguments, the --dry-run text and the errors, against the sample files in files/ and the goldens
in golden/; and a process started as a plan says gets its parameter file through
HORUS_PARAMS_FILE. Refresh the goldens (then read the diff):

    HORUS_UPDATE_GOLDEN=1 PYTHONPATH=tools/horus:tests/support \
        /usr/bin/python3 -m pytest tests/launch/test_launch_file.py -k golden
"""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest
from processes import Children, private_namespace, wait_line
from horus_cli.launch.plan import (Backoff, Dependency, LaunchFileError, format_plan,
                                   horus_command, load_plan, parse_arguments)

HERE = pathlib.Path(__file__).resolve().parent
FILES = HERE / "files"
GOLDEN = HERE / "golden"


@pytest.fixture(autouse=True)
def in_files_folder(monkeypatch):
    """Messages name files relative to the current folder: the samples' own, as a user running
    `horus launch` beside them sees; and no variable of the samples leaks in from outside."""
    monkeypatch.chdir(FILES)
    for name in ("LAUNCH_TEST_ROBOT", "LAUNCH_TEST_OPERATOR", "LAUNCH_TEST_UNSET"):
        monkeypatch.delenv(name, raising=False)


def normalized(text: str) -> str:
    """`text` without what differs between machines: the checkout's folder, the interpreter and
    the way this process runs `horus`."""
    return (text.replace(" ".join(horus_command()), "<horus>")
            .replace(sys.executable, "<python>").replace(str(FILES), "<files>"))


def matches_golden(name: str, text: str) -> None:
    golden = GOLDEN / name
    if os.environ.get("HORUS_UPDATE_GOLDEN"):
        golden.write_text(text)
    expected = golden.read_text()
    assert text == expected, f"{name} differs; expected:\n{expected}\ngot:\n{text}"


def errors_of(path: str, arguments: dict[str, str] | None = None) -> list[str]:
    with pytest.raises(LaunchFileError) as raised:
        load_plan(path, arguments or {})
    assert str(raised.value) == "\n".join(raised.value.errors)
    return raised.value.errors


def test_the_dry_run_of_a_launch_with_an_include_matches_its_golden(monkeypatch):
    monkeypatch.setenv("LAUNCH_TEST_OPERATOR", "ana")
    plan = load_plan("robot.yaml", {"sim": "true"})
    matches_golden("robot_dry_run.txt", normalized(format_plan(plan)))
    assert format_plan(load_plan("robot.yaml", {"sim": "true"})) == format_plan(plan)


def test_horus_launch_dry_run_prints_the_golden_plan_and_starts_nothing(monkeypatch):
    horus = os.environ.get("HORUS_CLI")
    assert horus, "HORUS_CLI names bin/horus: run through ctest (pytest_launch_file)"
    monkeypatch.setenv("LAUNCH_TEST_OPERATOR", "ana")
    result = subprocess.run([horus, "launch", "robot.yaml", "sim:=true", "--dry-run"],
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    # The child runs `horus` as bin/horus, and Python scripts with bin/horus's interpreter.
    text = result.stdout.replace(horus, "<horus>").replace("/usr/bin/python3", "<python>")
    assert normalized(text) == (GOLDEN / "robot_dry_run.txt").read_text()
    refused = subprocess.run([horus, "launch", "errors/many.yaml", "sm:=1"],
                             capture_output=True, text=True, timeout=30)
    assert refused.returncode != 0 and refused.stdout == ""
    assert normalized(refused.stderr).endswith((GOLDEN / "errors_many.txt").read_text())


def test_the_plan_holds_every_process_expanded_in_dependency_order(monkeypatch):
    monkeypatch.setenv("LAUNCH_TEST_OPERATOR", "ana")
    plan = load_plan(str(FILES / "robot.yaml"), {"scan_hz": "25"})
    assert plan.name == "agv_demo" and plan.source == str(FILES / "robot.yaml")
    assert plan.log_dir == ""
    assert plan.args == {"robot": "agv1", "sim": "false", "scan_hz": "25"}
    by_name = {process.name: process for process in plan.processes}
    # Included processes come first (read where the include is), each after what it waits for.
    assert [process.name for process in plan.processes] == ["lidar", "imu", "perception",
                                                           "recorder"]
    lidar = by_name["lidar"]
    assert lidar.argv == (str(FILES / "bin/fake_driver"), "--device", "lidar", "--rate", "25")
    assert lidar.namespace == "agv1" and lidar.params == str(FILES / "config/lidar.yaml")
    assert lidar.env == {"HORUS_NAMESPACE": "agv1",
                         "HORUS_PARAMS_FILE": str(FILES / "config/lidar.yaml")}
    assert lidar.restart == "always" and lidar.backoff == Backoff()
    assert lidar.where == "sensors.yaml:6"
    assert by_name["imu"].cwd == str(FILES / "config")
    perception = by_name["perception"]
    assert perception.argv[:2] == (sys.executable, str(FILES / "perception.py"))
    assert perception.env == {"HORUS_NAMESPACE": "agv1", "OPERATOR": "ana",
                              "PERCEPTION_THREADS": "2"}
    assert perception.cwd == str(FILES) and perception.required
    assert perception.depends_on == (
        Dependency("process", "lidar", 10.0, "robot.yaml:26"),
        Dependency("topic", "scan", 5.0, "robot.yaml:27"),
        Dependency("service", "lidar_calibration", 2.5, "robot.yaml:29"))
    assert perception.backoff == Backoff(initial=1.0, maximum=8.0, limit=3)
    recorder = by_name["recorder"]
    assert recorder.argv[:len(horus_command()) + 1] == (*horus_command(), "record")
    assert recorder.stop_timeout == 2.0 and not recorder.required and recorder.restart == "never"


def test_arguments_come_from_the_command_line_else_their_defaults_else_the_environment(
        monkeypatch):
    plan = load_plan("robot.yaml", {})
    assert plan.processes[0].namespace == "agv1"
    assert plan.processes[2].env["OPERATOR"] == "nobody"
    assert load_plan("robot.yaml", {"robot": "agv9"}).processes[0].namespace == "agv9"
    monkeypatch.setenv("LAUNCH_TEST_ROBOT", "agv7")
    assert load_plan("robot.yaml", {}).processes[0].namespace == "agv7"
    assert load_plan("robot.yaml", {"robot": "agv9"}).processes[0].namespace == "agv9"


def test_an_argument_with_choices_takes_only_those():
    assert errors_of("robot.yaml", {"sim": "ture"}) == [
        "robot.yaml:7: args.sim: 'ture' (given on the command line) is not one of true, false "
        "(did you mean 'true'?)"]


def test_command_line_arguments_parse_as_name_colon_equals_value():
    assert parse_arguments(["sim:=true", "robot:=agv 2", "empty:="]) == {
        "sim": "true", "robot": "agv 2", "empty": ""}
    for word in ("sim=true", ":=true", "2fast:=1"):
        with pytest.raises(ValueError, match="NAME:=VALUE"):
            parse_arguments([word])


def test_every_mistake_of_a_file_is_reported_with_file_line_key_and_hint_as_the_golden():
    errors = errors_of("errors/many.yaml", {"sm": "1"})
    matches_golden("errors_many.txt", normalized("\n".join(errors) + "\n"))
    for error in errors:
        assert error.startswith("errors/many.yaml:") or error.startswith("sensors.yaml:"), error


@pytest.mark.parametrize("name", ["cycle", "not_yaml", "includes_itself"])
def test_cycles_and_malformed_files_are_reported_as_their_goldens(name):
    matches_golden(f"errors_{name}.txt",
                   normalized("\n".join(errors_of(f"errors/{name}.yaml")) + "\n"))


def test_an_argument_without_default_must_be_given(tmp_path):
    (tmp_path / "needs.yaml").write_text(
        "args:\n  robot: {doc: which robot}\nprocesses:\n  driver:\n"
        "    command: $(env LAUNCH_TEST_UNSET " + str(FILES / "bin/fake_driver") + ")\n"
        "    args: [$(arg robot)]\n")
    assert errors_of(str(tmp_path / "needs.yaml")) == [
        f"{tmp_path}/needs.yaml:2: args.robot: has no default and was not given "
        "(give it on the command line: robot:=VALUE)"]
    plan = load_plan(str(tmp_path / "needs.yaml"), {"robot": "agv3"})
    assert plan.processes[0].argv == (str(FILES / "bin/fake_driver"), "agv3")
    assert plan.name == "needs"


def test_a_file_that_is_missing_or_starts_nothing_says_so(tmp_path):
    assert errors_of(str(tmp_path / "absent.yaml")) == [
        f"{tmp_path}/absent.yaml:1: launch file: cannot read it (No such file or directory)"]
    (tmp_path / "empty.yaml").write_text("args: {a: 1}\n")
    assert errors_of(str(tmp_path / "empty.yaml")) == [
        f"{tmp_path}/empty.yaml:1: processes: the launch starts no process "
        "(list them under processes:)"]


@pytest.fixture
def namespace(monkeypatch, tmp_path):
    yield from private_namespace(monkeypatch, tmp_path, "launch")


def test_a_process_started_as_the_plan_says_gets_its_parameter_file(tmp_path, namespace):
    """The runtime reads HORUS_PARAMS_FILE when the program names no parameter file itself."""
    assert os.environ.get("HORUS_PARAM_E2E_NODE"), (
        "HORUS_PARAM_E2E_NODE names tests/params_e2e's node program: run through ctest "
        "(pytest_launch_file)")
    (tmp_path / "start.yaml").write_text("cpp_params:\n  max_speed: 0.5\n  profile: sport\n")
    (tmp_path / "other.yaml").write_text("cpp_params:\n  max_speed: 1.5\n")
    (tmp_path / "robot.yaml").write_text(
        "processes:\n  node:\n    command: $(env HORUS_PARAM_E2E_NODE)\n"
        "    args: [cpp_params]\n    params: start.yaml\n")
    spec = load_plan(str(tmp_path / "robot.yaml"), {}).processes[0]
    assert spec.env == {"HORUS_PARAMS_FILE": str(tmp_path / "start.yaml")}
    with Children() as children:
        started = children.start(list(spec.argv), {**os.environ, **spec.env})
        ready = wait_line(started, "ready ")
        assert "max_speed=0.5 " in ready and "profile=sport " in ready, ready
        started.terminate()
        started.communicate(timeout=20)
        # A file the program names itself wins over the variable.
        named = children.start([*spec.argv, str(tmp_path / "other.yaml")],
                               {**os.environ, **spec.env})
        ready = wait_line(named, "ready ")
        assert "max_speed=1.5 " in ready and "profile=sport " not in ready, ready
        named.terminate()
        named.communicate(timeout=20)
        # And a wrong file in the variable stops the start naming that file and line.
        (tmp_path / "wrong.yaml").write_text("cpp_params:\n  max_speed: 9\n")
        wrong = children.start(list(spec.argv),
                               {**os.environ, "HORUS_PARAMS_FILE": str(tmp_path / "wrong.yaml")})
        out, err = wrong.communicate(timeout=30)
        assert wrong.returncode != 0 and "ready" not in out
        assert f"{tmp_path / 'wrong.yaml'}:2:" in err, err


def test_a_name_repeated_in_one_file_and_keys_for_the_top_file_only_are_reported(tmp_path):
    driver = FILES / "bin/fake_driver"
    (tmp_path / "part.yaml").write_text(
        f"name: part\nlog_dir: logs\nprocesses:\n  cam:\n    command: {driver}\n")
    (tmp_path / "top.yaml").write_text(
        f"include: part.yaml\nprocesses:\n  cam:\n    command: {driver}\n"
        f"  arm:\n    command: {driver}\n  arm:\n    command: {driver}\n"
        "  wheel:\n    command: $(arg\n")
    top, part = tmp_path / "top.yaml", tmp_path / "part.yaml"
    assert errors_of(str(top)) == [
        f"{part}:1: name: only the top launch file sets it (this file is included from {top}:1)",
        f"{part}:2: log_dir: only the top launch file sets it (this file is included from "
        f"{top}:1)",
        f"{top}:3: processes.cam: a process named 'cam' is already defined at {part}:4 "
        "(process names are unique in the whole launch, included files too)",
        f"{top}:7: processes.arm: a process named 'arm' is already defined at {top}:5 "
        "(process names are unique in the whole launch, included files too)",
        f"{top}:10: processes.wheel.command: '$(' without its closing ')' "
        "(write $(env NAME), $(arg NAME) or $(dir))"]


def test_the_top_file_names_the_launch_and_its_log_folder(tmp_path):
    (tmp_path / "robot.yaml").write_text(
        "name: agv_one\nlog_dir: $(env LAUNCH_TEST_UNSET logs)\nprocesses:\n"
        "  a:\n    command: $(env LAUNCH_TEST_UNSET \"" + str(FILES / "bin/fake_driver") +
        "\") --say \"two words\"\n")
    plan = load_plan(str(tmp_path / "robot.yaml"), {})
    assert plan.name == "agv_one" and plan.log_dir == str(tmp_path / "logs")
    assert plan.processes[0].argv == (str(FILES / "bin/fake_driver"), "--say", "two words")
