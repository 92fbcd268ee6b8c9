"""horus-gen on a node's params block: the declarations `describe` lists (text and JSON), the
generated C++ compiled against the runtime's headers, the generated Python's declare_param() calls,
and the generated code of tests/schemas/test_nodes/param_node.hnode against tests/golden/params.
Its errors are golden diagnostics (tests/golden/diagnostics/node_params*.hnode).

Refresh the generated-code golden files after an intended change, then read the diff:
    HORUS_UPDATE_GOLDEN=1 /usr/bin/python3 -m pytest tests/python/test_generator_params.py
"""
from __future__ import annotations

import json
import os
import struct
import subprocess
from pathlib import Path

import pytest

from generator_testing import GOLDEN, ROOT, SCHEMAS, run_horus_gen

PARAM_NODE = str(SCHEMAS / "test_nodes" / "param_node.hnode")
CXX = os.environ.get("CXX", "g++")

# A package of its own: an enum, a topic's message and a node with topics and parameters, so that
# the constructor's member initializers hold both.
ROBOT_TYPES = """
enum ControlMode: u8 { Idle = 0, Velocity = 1, Position = 2 }
Speed { value: f64 }
"""
ROBOT_NODE = """
import "types.hmsg";
/// Drives the motor.
MotorController {
    name: "motor_controller",
    rate: 100 hz,
    pub { speed: Speed -> "motor.speed" }
    params {
        /// Top speed the planner may command.
        /// Lines of doc join with newlines.
        #[min = 0.0]
        #[max = 2.0]
        #[unit = "m/s"]
        max_speed: f64 = 1.0,
        #[choices = ["eco", "sport"]]
        profile: String = "eco",
        #[read_only]
        wheel_count: u8 = 4,
        #[choices = [Velocity, Position]]
        mode: ControlMode = ControlMode::Velocity,
        #[min = -1]
        #[max = 1]
        gains: [f64; 3] = [1.0, 0.5, 0.0],
        #[choices = [[1, 2], [3, 4]]]
        pair: [i16; 2] = [3, 4],
        mask: [bool; 2] = [true, false],
        big: i64 = -9223372036854775808,
        quoted: String = "say \\"hi\\"",
    }
}
"""


def robot_schemas(tmp_path: Path) -> list[str]:
    folder = tmp_path / "robot"
    folder.mkdir()
    (folder / "types.hmsg").write_text(ROBOT_TYPES)
    (folder / "motor.hnode").write_text(ROBOT_NODE)
    return [str(folder / "motor.hnode"), str(folder / "types.hmsg")]


def node_json(stdout: str, name: str) -> dict:
    return next(t for t in json.loads(stdout)["types"] if t["kind"] == "node" and t["name"] == name)


def test_describe_json_lists_each_parameter_as_the_runtime_declares_it():
    result = run_horus_gen("describe", "--json", "-I", str(SCHEMAS), PARAM_NODE)
    assert result.returncode == 0, result.stderr
    params = node_json(result.stdout, "param_node")["params"]
    assert [p["name"] for p in params] == ["max_speed", "gain", "offset", "wheel_count", "enabled", "profile",
                                           "mode", "gains", "mask", "ticks"]
    assert params[0] == {"name": "max_speed", "type": {"kind": "primitive", "name": "f64"}, "spelling": "f64",
                         "default": 1.0, "min": 0.0, "max": 2.0, "choices": [], "unit": "m/s",
                         "doc": "Top speed the planner may command.", "read_only": False}
    assert params[2]["min"] == -10 and params[2]["max"] == 10
    assert params[3]["read_only"] is True
    assert params[5]["choices"] == ["eco", "sport"] and params[5]["type"] == {"kind": "string"}
    # An enum's values by enumerator name, as the type description and YAML files spell them.
    assert params[6] == {"name": "mode", "type": {"kind": "enum", "name": "test_msgs.Mode"},
                         "spelling": "test_msgs.Mode", "default": "Run", "min": None, "max": None,
                         "choices": ["Idle", "Run"], "unit": "", "doc": "", "read_only": False}
    assert params[7]["type"] == {"kind": "array", "element": {"kind": "primitive", "name": "f64"}, "length": 3}
    assert params[7]["default"] == [1.0, 0.5, 0.0] and params[7]["spelling"] == "[f64; 3]"


def test_describe_graph_json_includes_the_parameters():
    result = run_horus_gen("describe", "--graph", "--json", "-I", str(SCHEMAS), PARAM_NODE)
    assert result.returncode == 0, result.stderr
    node = json.loads(result.stdout)["nodes"][0]
    assert [p["name"] for p in node["params"]][:3] == ["max_speed", "gain", "offset"]


def test_describe_text_lists_each_parameter_with_its_limits():
    result = run_horus_gen("describe", "-I", str(SCHEMAS), PARAM_NODE)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert "    param max_speed: f64 = 1.0  min 0.0  max 2.0  unit m/s" in lines
    assert "    param wheel_count: u8 = 4  read-only" in lines
    assert '    param profile: String = "eco"  choices ["eco", "sport"]' in lines
    assert "    param mode: test_msgs.Mode = Run  choices [Idle, Run]" in lines
    assert "    param gains: [f64; 3] = [1.0, 0.5, 0.0]  min -1.0  max 1.0" in lines


def test_generated_cpp_compiles_against_the_runtime_headers(tmp_path):
    out = tmp_path / "out"
    result = run_horus_gen("generate", "--lang", "cpp", "--out", str(out), *robot_schemas(tmp_path))
    assert result.returncode == 0, result.stderr
    cpp = out / "cpp"
    source = (cpp / "robot" / "_nodes.cpp").read_text()
    # Declared in the block's order, through the node, with the options the schema gives.
    assert source.index('"max_speed"') < source.index('"profile"') < source.index('"quoted"')
    assert '.choices = {::std::array<::std::int16_t, 2>{{1, 2}}, ::std::array<::std::int16_t, 2>{{3, 4}}}' in source
    assert '.doc = "Top speed the planner may command.\\nLines of doc join with newlines."' in source
    unit = tmp_path / "all.cc"
    unit.write_text('#include "robot/_nodes.cpp"\n'
                    "// What a derived node reads: the typed accessors of params().\n"
                    "struct Motor : robot::MotorControllerBase {\n"
                    "  void tick() override {\n"
                    "    double speed = params().max_speed();\n"
                    "    std::string profile = params().profile();\n"
                    "    robot::ControlMode mode = params().mode();\n"
                    "    std::array<double, 3> gains = params().gains();\n"
                    "    (void)speed; (void)profile; (void)mode; (void)gains;\n"
                    "  }\n"
                    "};\n"
                    "Motor motor;\n")
    compiled = subprocess.run([CXX, "-std=gnu++20", "-fsyntax-only", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                               f"-I{ROOT / 'runtime' / 'include'}", f"-I{cpp}", str(unit)],
                              capture_output=True, text=True)
    assert compiled.returncode == 0, compiled.stderr[:4000]


# Records what the generated __init__ declares, through a subclass: the calls are the generator's
# output, whatever horus.Node.declare_param then does with them.
RECORD_DECLARATIONS = """
import json, sys
sys.path.insert(0, sys.argv[1])
import robot

class Recorded(robot.MotorControllerBase):
    def declare_param(self, name, default, **options):
        if "type" in options and not isinstance(options["type"], str):
            options["type"] = "class " + options["type"].__name__
        declared.append([name, default if not hasattr(default, "name") else "enum " + default.name, options])

declared = []
Recorded()
print(json.dumps(declared))
"""


def test_generated_python_imports_and_declares_each_parameter(tmp_path):
    out = tmp_path / "out"
    result = run_horus_gen("generate", "--lang", "python", "--out", str(out), *robot_schemas(tmp_path))
    assert result.returncode == 0, result.stderr
    runtime = Path(os.environ.get("HORUS_BUILD_DIR") or ROOT / "build") / "python"
    ran = subprocess.run(["/usr/bin/python3", "-c", RECORD_DECLARATIONS, str(out / "python")],
                         capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(runtime), "PYTHONDONTWRITEBYTECODE": "1"})
    assert ran.returncode == 0, ran.stderr
    declared = json.loads(ran.stdout)
    assert declared == [
        ["max_speed", 1.0, {"type": "f64", "min": 0.0, "max": 2.0, "unit": "m/s",
                            "doc": "Top speed the planner may command.\nLines of doc join with newlines."}],
        ["profile", "eco", {"type": "String", "choices": ["eco", "sport"]}],
        ["wheel_count", 4, {"type": "u8", "read_only": True}],
        ["mode", "enum Velocity", {"type": "class ControlMode", "choices": [1, 2]}],
        ["gains", [1.0, 0.5, 0.0], {"type": "[f64; 3]", "min": -1, "max": 1}],
        ["pair", [3, 4], {"type": "[i16; 2]", "choices": [[1, 2], [3, 4]]}],
        ["mask", [True, False], {"type": "[bool; 2]"}],
        ["big", -9223372036854775808, {"type": "i64"}],
        ["quoted", 'say "hi"', {"type": "String"}],
    ]


GENERATED_GOLDEN = GOLDEN / "params"
GENERATED_FILES = ["cpp/test_nodes/param_node.hpp", "cpp/test_nodes/_nodes.cpp", "python/test_nodes/_param_node.py"]


@pytest.mark.parametrize("relative", GENERATED_FILES)
def test_generated_code_matches_golden(tmp_path, relative):
    result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(tmp_path), "-I", str(SCHEMAS), PARAM_NODE)
    assert result.returncode == 0, result.stderr
    produced = (tmp_path / relative).read_text()
    # Named .golden: the linters would otherwise format-check them as the project's own sources.
    expected = GENERATED_GOLDEN / (relative.replace("/", "__") + ".golden")
    if os.environ.get("HORUS_UPDATE_GOLDEN"):
        expected.parent.mkdir(exist_ok=True)
        expected.write_text(produced)
    assert produced == expected.read_text(), f"{relative} differs from {expected.name}"


def test_f32_bounds_are_the_f32_values_the_parameter_holds(tmp_path):
    # 0.1 is not an f32: the bound is 0.1f, as the default is, so the default equals it in every
    # language (a double 0.1 would be below the default 0.1f, and the node refused at start).
    node = tmp_path / "n.hnode"
    node.write_text("N { params {\n  #[min = 0.1]\n  #[max = 0.1]\n  x: f32 = 0.1,\n"
                    "  #[max = 0.1]\n  #[choices = [0.1, 0.2]]\n  y: f32 = 0.1,\n} }\n")
    result = run_horus_gen("describe", "--json", str(node))
    assert "n.hnode:6:21: error: choice 0.2 of parameter 'y' is outside its #[min]/#[max]" in result.stderr
    node.write_text("N { params {\n  #[min = 0.1]\n  #[max = 0.1]\n  x: f32 = 0.1,\n} }\n")
    result = run_horus_gen("describe", "--json", str(node))
    assert result.returncode == 0, result.stderr
    param = node_json(result.stdout, "N")["params"][0]
    assert param["min"] == param["max"] == struct.unpack("<f", struct.pack("<f", 0.1))[0]


def test_every_language_generates_a_run_holding_nodes(tmp_path):
    # IDL and JSON Schema describe values: a node has none, and is left out (not an internal error).
    result = run_horus_gen("generate", "--lang", "cpp,python,idl,jsonschema", "--out", str(tmp_path), "-I",
                           str(SCHEMAS), PARAM_NODE)
    assert result.returncode == 0, result.stderr
    assert not list((tmp_path / "jsonschema").rglob("*ParamNode*")) and not list((tmp_path / "idl").rglob("*ParamNode*"))
    assert (tmp_path / "cpp" / "test_nodes" / "param_node.hpp").is_file()
