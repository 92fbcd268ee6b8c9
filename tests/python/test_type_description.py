"""The type description (docs/type-description.md) against the generator's own output, for every
standard type and every test schema type: describe --json, the bytes generated Python and C++ carry,
the generated classes' layouts and encodings, and horus.typedesc decoding and encoding the same
bytes (type_description_check.py, one process per schema set). Also the in-process API
(horus_gen.describe_files, describe_schema_text), typedesc.load_type and the version rule."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import msgpack
import pytest

import horus_gen
from generator_testing import ROOT, SCHEMAS, TEST_SCHEMAS, run_horus_gen
from horus_gen import description
from horus_gen.lang.cpp import header_path

TYPEDESC = ROOT / "runtime" / "python" / "horus" / "typedesc.py"
CHECK = Path(__file__).with_name("type_description_check.py")
STANDARD = ROOT / "schemas"


def schema_files(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.iterdir() if p.suffix in (".hmsg", ".hsrv"))


# Every set of schema files the repository compiles: (files, include folders).
SCHEMA_SETS = {
    "standard": (schema_files(STANDARD / "horus" / "msg"), [STANDARD]),
    "test_schemas": (TEST_SCHEMAS, [SCHEMAS, STANDARD]),
    "summary_names": (schema_files(SCHEMAS / "summary_names"), [SCHEMAS, STANDARD]),
    "cli": (schema_files(ROOT / "tests" / "cli" / "schemas" / "cli_user"),
            [ROOT / "tests" / "cli" / "schemas", STANDARD]),
    "dds": (schema_files(ROOT / "tests" / "dds" / "schemas" / "dds_test"),
            [ROOT / "tests" / "dds" / "schemas", STANDARD]),
    "remote": (schema_files(ROOT / "tests" / "remote" / "schemas" / "remote_test"),
               [ROOT / "tests" / "remote" / "schemas", STANDARD]),
}


def includes(folders) -> list[str]:
    return [arg for folder in folders for arg in ("-I", str(folder))]


@pytest.fixture(scope="module")
def standard_output(tmp_path_factory) -> Path:
    """The standard types generated for C++ and Python: the other sets use them."""
    out = tmp_path_factory.mktemp("standard_types")
    files, folders = SCHEMA_SETS["standard"]
    result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(out), *includes(folders), *files)
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture(scope="module", params=sorted(SCHEMA_SETS))
def compiled(request, tmp_path_factory, standard_output):
    """One schema set generated for C++ and Python, with its describe --json tree, and the output
    roots its code needs (its own, then the standard types')."""
    files, folders = SCHEMA_SETS[request.param]
    out = tmp_path_factory.mktemp(request.param)
    result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(out), *includes(folders), *files)
    assert result.returncode == 0, result.stderr
    result = run_horus_gen("describe", "--json", *includes(folders), *files)
    assert result.returncode == 0, result.stderr
    # What the carried bytes are checked against: the set's types and the standard ones they use.
    standard = [f for f in SCHEMA_SETS["standard"][0] if f not in files]
    everything = run_horus_gen("describe", "--json", *includes(folders), *files, *standard)
    assert everything.returncode == 0, everything.stderr
    (out / "described.json").write_text(everything.stdout)
    return out, json.loads(result.stdout), [out, standard_output]


def python_path(roots: list[Path]) -> str:
    return os.pathsep.join(str(root / "python") for root in roots)


def described_types(tree: dict) -> list[dict]:
    return [e for e in tree["types"] if e["kind"] in ("message", "enum")]


def test_every_type_agrees_with_the_generated_python_and_typedesc(compiled):
    out, tree, roots = compiled
    packages = sorted({e["package"] for e in described_types(tree)})
    result = subprocess.run([sys.executable, str(CHECK), str(TYPEDESC), str(out / "described.json"), *packages],
                            capture_output=True, text=True,
                            env={**os.environ, "PYTHONPATH": python_path(roots), "PYTHONDONTWRITEBYTECODE": "1"})
    assert result.returncode == 0, result.stderr
    assert result.stdout == "", result.stdout


CPP_PROGRAM = """#include <cstddef>
#include <cstdio>
#include <string_view>
{includes}

namespace {{
void print(std::string_view name, std::string_view description, std::size_t size, std::size_t alignment) {{
  std::printf("%.*s %zu %zu ", static_cast<int>(name.size()), name.data(), size, alignment);
  for (unsigned char byte : description) std::printf("%02x", byte);
  std::printf("\\n");
}}
}}  // namespace

{asserts}
int main() {{
{prints}
}}
"""


def cpp_program(tree: dict) -> str:
    """Prints each type's carried bytes, sizeof and alignof; static_asserts each POD field's offset."""
    includes, asserts, prints = [], [], []
    for entry in described_types(tree):
        cpp = "::" + entry["name"].replace(".", "::")
        includes.append(f'#include "{header_path(entry["name"])}"')
        size = f"sizeof({cpp})" if entry["kind"] == "message" else "0"
        alignment = f"alignof({cpp})" if entry["kind"] == "message" else "0"
        prints.append(f'  print("{entry["name"]}", ::horus::TypeInfo<{cpp}>::description, {size}, {alignment});')
        if entry["kind"] == "message" and entry["tier"] == "pod":
            asserts += [f"static_assert(offsetof({cpp}, {f['name']}) == {f['offset']});" for f in entry["fields"]]
    return CPP_PROGRAM.format(includes="\n".join(includes), asserts="\n".join(asserts), prints="\n".join(prints))


def test_cpp_carries_the_python_bytes_with_the_described_layout(compiled):
    out, tree, roots = compiled
    program = out / "print_descriptions.cpp"
    program.write_text(cpp_program(tree))
    binary = out / "print_descriptions"
    build = subprocess.run(["g++", "-std=c++20", "-w", "-I", str(ROOT / "runtime" / "include"),
                            *[arg for root in roots for arg in ("-I", str(root / "cpp"))],
                            str(program), "-o", str(binary)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr[-4000:]
    printed = subprocess.run([str(binary)], capture_output=True, text=True, check=True).stdout.splitlines()
    by_name = {e["name"]: e for e in described_types(tree)}
    python = python_descriptions(roots, sorted(by_name))
    for line in printed:
        name, size, alignment, carried = line.split(" ")
        entry = by_name[name]
        assert bytes.fromhex(carried) == python[name], name
        if entry["kind"] == "message":
            assert (int(size), int(alignment)) == (entry["size"], entry["alignment"]) or entry["tier"] != "pod", name
    assert len(printed) == len(by_name)


def python_descriptions(roots: list[Path], names: list[str]) -> dict[str, bytes]:
    """The bytes the generated Python classes carry, read in a process of their own (another set's
    package of the same name may be imported in this one)."""
    script = ("import importlib, json, sys\n"
              "found = {}\n"
              "for name in sys.argv[1:]:\n"
              "    package, short = name.rsplit('.', 1)\n"
              "    found[name] = getattr(importlib.import_module(package), short).__horus__['description'].hex()\n"
              "print(json.dumps(found))\n")
    result = subprocess.run([sys.executable, "-c", script, *names], capture_output=True, text=True,
                            env={**os.environ, "PYTHONPATH": python_path(roots), "PYTHONDONTWRITEBYTECODE": "1"})
    assert result.returncode == 0, result.stderr
    return {name: bytes.fromhex(text) for name, text in json.loads(result.stdout).items()}


def test_the_describe_tree_is_versioned_and_complete(compiled):
    _out, tree, _roots = compiled
    assert (tree["format"], tree["version"]) == ("horus.typedesc", 1)
    for entry in tree["types"]:
        if entry["kind"] == "message":
            assert {"fields", "constants", "padding", "summary", "topic", "schema", "tier", "size", "alignment",
                    "fingerprint"} <= set(entry)
            for f in entry["fields"]:
                assert {"name", "type", "offset", "size", "default", "unit"} <= set(f)


def test_the_carried_bytes_are_what_msgpack_writes_for_the_tree():
    tree = horus_gen.describe_files(TEST_SCHEMAS, [str(SCHEMAS), str(STANDARD)])
    carried = description.pack(tree)
    assert carried == msgpack.packb(tree, use_bin_type=True)
    assert msgpack.unpackb(carried, raw=False) == tree
    for value in (0, 127, 128, -32, -33, 255, 65535, 65536, -(1 << 63), (1 << 64) - 1, 1.5, "x" * 40, "y" * 300,
                  list(range(20)), {str(i): i for i in range(20)}, None, True):
        assert description.pack(value) == msgpack.packb(value, use_bin_type=True), value


def test_describe_files_and_schema_text_in_process():
    tree = horus_gen.describe_files(TEST_SCHEMAS, [str(SCHEMAS), str(STANDARD)])
    printed = run_horus_gen("describe", "--json", *includes([SCHEMAS, STANDARD]), *TEST_SCHEMAS)
    assert printed.returncode == 0, printed.stderr
    command = json.loads(printed.stdout)
    for entry in command["types"]:
        entry.pop("dds_type", None)
    assert command == tree  # what the command prints beside the tree: DDS names (and nodes, none here)
    pose = next(e for e in tree["types"] if e["name"] == "test_msgs.Pose2")
    carried = horus_gen.describe_schema_text("test_msgs.Pose2", pose["schema"])
    assert carried["root"] == "test_msgs.Pose2"
    assert carried["types"][-1]["fingerprint"] == pose["fingerprint"]
    assert [e["name"] for e in carried["types"]][-1] == "test_msgs.Pose2"


def test_schema_text_errors_carry_the_diagnostics():
    with pytest.raises(horus_gen.SchemaCompileError) as error:
        horus_gen.describe_schema_text("demo.Bad", "message demo.Bad {\n  x: f65,\n}\n")
    assert "unknown type 'f65'" in str(error.value)
    assert len(error.value.diagnostics) == 1 and "did you mean 'f64'?" in error.value.diagnostics[0]
    with pytest.raises(horus_gen.SchemaCompileError, match="expected 'message pkg.Name"):
        horus_gen.describe_schema_text("demo.Bad", "struct demo.Bad {}\n")
    with pytest.raises(horus_gen.SchemaCompileError, match="declares no type demo.Other"):
        horus_gen.describe_schema_text("demo.Other", "message demo.Bad {\n  x: f64,\n}\n")


@pytest.fixture
def typedesc(monkeypatch):
    """horus.typedesc as in the repository, finding the support module through the checkout's
    horus-gen as an installed one finds it through the installed launcher."""
    import importlib.util
    monkeypatch.setenv("HORUS_GEN_PROGRAM", str(ROOT / "generator" / "horus-gen"))
    spec = importlib.util.spec_from_file_location("typedesc_under_test", TYPEDESC)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_load_type_compiles_schema_text_in_process_and_checks_the_fingerprint(typedesc):
    text = "message demo.Pose {\n  x: f32,\n  mode: demo.Mode,\n}\nenum demo.Mode: u8 {\n  Idle = 0,\n  Run = 2,\n}\n"
    fingerprint = int(horus_gen.describe_schema_text("demo.Pose", text)["types"][-1]["fingerprint"], 16)
    cls = typedesc.load_type("demo.Pose", text, fingerprint)
    message = typedesc.from_plain(cls, {"x": 0.1, "mode": "Run"})
    assert typedesc.to_plain(cls.from_bytes(message.to_bytes())) == {"x": 0.1, "mode": "Run"}
    assert message.to_bytes() == bytes.fromhex("cdcccc3d02000000")
    with pytest.raises(typedesc.SchemaError, match="gives fingerprint"):
        typedesc.load_type("demo.Pose", text, fingerprint ^ 1)
    with pytest.raises(typedesc.SchemaError, match="does not compile"):
        typedesc.load_type("demo.Bad", "message demo.Bad {\n  x: f65,\n}\n", None)
    with pytest.raises(ValueError, match="no field 'y'"):
        typedesc.from_plain(cls, {"y": 1})


def test_load_type_reads_the_identities_the_runtime_spells(typedesc):
    cls = typedesc.load_type("[f32; 3]", "value [f32; 3]", typedesc.runtime_fingerprint("value [f32; 3]"))
    assert typedesc.decode(cls, cls(value=[1.0, 2.0, 0.5]).to_bytes()) == {"value": [1.0, 2.0, 0.5]}


def test_readers_refuse_a_newer_version_and_other_data(typedesc):
    with pytest.raises(typedesc.SchemaError, match="version 2 is newer than this reader's 1"):
        typedesc.parse({"format": "horus.typedesc", "version": 2, "types": []})
    with pytest.raises(typedesc.SchemaError, match="not a type description"):
        typedesc.parse({"format": "other", "version": 1, "types": []})
    with pytest.raises(typedesc.SchemaError, match="not valid MessagePack"):
        typedesc.parse(b"\xc1")
    # Added keys are compatible: a reader ignores what it does not know.
    tree = horus_gen.describe_schema_text("demo.P", "message demo.P {\n  x: u8,\n}\n")
    tree["future_key"] = 1
    tree["types"][0]["future_key"] = {"nested": True}
    assert typedesc.decode(typedesc.message_class(tree), b"\x07") == {"x": 7}
