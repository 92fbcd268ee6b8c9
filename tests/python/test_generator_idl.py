"""horus-gen --lang idl: the OMG IDL it writes, in ROS 2's naming. The mapping is checked on the
text of a schema with every kind of type; then the IDL of the standard library and of the test
schemas goes through Cyclone DDS's own compiler, `idlc` (Debian cyclonedds-tools), and the C it
writes through `cc` against Cyclone's headers (cyclonedds-dev): the type names are ROS 2's, and
where the layouts coincide (POD messages of numbers, bools, enums, arrays and such messages) the C
struct has the HORUS size and offsets. Without idlc these tests fail: scripts/install-deps
installs it."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from generator_testing import ROOT, SCHEMAS, TEST_SCHEMAS, run_horus_gen
from horus_gen.diagnostics import Reporter
from horus_gen.lang import idl
from horus_gen.loader import Options
from horus_gen.model import EnumRef, FixedArray, Message, MessageRef, Primitive
from horus_gen.resolve import Resolver

STANDARD = sorted(str(p) for p in (ROOT / "schemas" / "horus" / "msg").glob("*.hmsg"))
TESTS = TEST_SCHEMAS + [str(SCHEMAS / "summary_names" / "names.hmsg")]

OTHER = """package kw_other;

/// Another package's message.
Thing { id: u32, level: Level }

enum Level: i16 { Low = -1, Default = 0, Map = 5 }
"""

EVERYTHING = """package kw_msgs;
import "kw_other/thing.hmsg";

enum Kind: u32 { Any = 1, Octet = 2, Plain = 3 }

/// Every kind of type. A doc line ending in a backslash \\
Everything {
    const MAX: f64 = 1.5e300,
    const LABEL: string<12> = "plain text",
    const QUOTE: string<12> = "a\\"b",
    const KIND: Kind = Kind::Octet,
    const ON: bool = true,
    const MODULE: u8 = 3,
    flag: bool,
    small: i8,
    big: u64,
    ratio: f32,
    fixed_text: string<8>,
    text: String,
    blob: bytes,
    octets: Vec<u8>,
    values: Vec<f64>,
    grid: [[[u16; 2]; 3]; 4],
    maybe_grid: Option<[f32; 3]>,
    rows: Vec<[[i32; 2]; 2]>,
    nested: Vec<Vec<[u8; 2]>>,
    arrays_of_vecs: [Vec<[f32; 2]>; 3],
    deep: Option<[Vec<[f64; 2]>; 3]>,
    maybe: Option<i32>,
    matrices: Vec<Vec<f64>>,
    kinds: Vec<Kind>,
    kind: Kind,
    thing: kw_other::Thing,
    things: [kw_other::Thing; 2],
    module: u8,
    string: u8,
    sequence: u8,
    Octet: u8,
    map: u8,
    fixed: u8,
    uint8: u8,
    interface: u8,
    x: f32,
    X: f32,
    everything_: u8,
    _hidden: u8,
}

/// Its name is a keyword's, with a field named like it.
Octet { octet: u8 }

/// Plain old data whose C layout is the HORUS one.
Pod { a: u8, b: f64, c: u16, d: [u32; 3], e: i8, kind: Kind, thing: kw_other::Thing, flags: [bool; 3] }

Empty {}
"""

SERVICE = """package kw_msgs;
import "kw_msgs/all.hmsg";

/// A service.
Lookup {
    request { name: String, kind: Kind }
    response { found: bool, where_: Option<[f64; 3]> }
}
"""


def cyclone() -> str:
    """idlc's path; fails (never skips) when Cyclone DDS's compiler or headers are missing."""
    idlc = shutil.which("idlc")
    missing = [what for what, there in (("idlc (Debian cyclonedds-tools)", idlc),
                                        ("/usr/include/dds/dds.h (Debian cyclonedds-dev)",
                                         os.path.exists("/usr/include/dds/dds.h")),
                                        ("cc", shutil.which("cc"))) if not there]
    if missing:
        pytest.fail(f"horus-gen --lang idl is checked with Cyclone DDS's compiler: missing {', '.join(missing)}; "
                    "run scripts/install-deps (it installs cyclonedds-dev and cyclonedds-tools)")
    return idlc


def write_schemas(root: Path) -> list[str]:
    files = {"kw_other/thing.hmsg": OTHER, "kw_msgs/all.hmsg": EVERYTHING, "kw_msgs/lookup.hsrv": SERVICE}
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return [str(root / name) for name in files]


def generate(out: Path, includes: list[str], files: list[str]) -> Path:
    result = run_horus_gen("generate", "--lang", "idl", "--out", str(out),
                           *(arg for folder in includes for arg in ("-I", folder)), *files)
    assert result.returncode == 0, result.stderr
    return out / "idl"


def model_of(includes: list[str], files: list[str]):
    reporter = Reporter()
    model = Resolver(reporter, Options(includes, None)).run(files)
    assert not reporter.has_errors, reporter.render()
    return model


def compile_with_cyclone(root: Path, c_out: Path) -> list[Path]:
    """idlc on every IDL file under `root` (-I root), then cc -c on every C file it wrote; returns the
    C files, after asserting that every step succeeded."""
    idlc = cyclone()
    failures = []
    idl_files = sorted(root.rglob("*.idl"))
    assert idl_files, f"no IDL under {root}"
    for path in idl_files:
        result = subprocess.run([idlc, "-I", str(root), "-b", str(root), "-o", str(c_out), str(path)],
                                capture_output=True, text=True)
        if result.returncode != 0:
            failures.append(f"idlc {path.relative_to(root)}: {result.stderr}")
    c_files = sorted(c_out.rglob("*.c"))
    assert len(c_files) == len(idl_files), (failures, c_files)
    for path in c_files:
        result = subprocess.run(["cc", "-c", "-Wall", "-Werror", "-I", str(c_out), "-I/usr/include", str(path),
                                 "-o", str(path.with_suffix(".o"))], capture_output=True, text=True)
        if result.returncode != 0:
            failures.append(f"cc {path.relative_to(c_out)}: {result.stderr}")
    assert not failures, "\n".join(failures[:5])
    return c_files


@pytest.fixture(scope="module")
def everything(tmp_path_factory) -> tuple[Path, list[str], list[str]]:
    schemas = tmp_path_factory.mktemp("kw_schemas")
    files = write_schemas(schemas)
    return generate(tmp_path_factory.mktemp("kw_out"), [str(schemas)], files), [str(schemas)], files


def body(text: str, struct: str) -> str:
    found = re.search(r"struct " + re.escape(struct) + r" \{\n(.*?)\n\};", text, re.S)
    assert found, f"struct {struct} in:\n{text}"
    return found.group(1)


def test_one_file_per_message_enum_and_service_under_the_package_path(everything):
    root, _, _ = everything
    assert sorted(str(p.relative_to(root)) for p in root.rglob("*.idl")) == [
        "kw_msgs/Empty.idl", "kw_msgs/Everything.idl", "kw_msgs/Kind.idl", "kw_msgs/Lookup.idl",
        "kw_msgs/Octet.idl", "kw_msgs/Pod.idl", "kw_other/Level.idl", "kw_other/Thing.idl"]


def test_every_type_kind_maps_to_its_idl_type(everything):
    root, _, _ = everything
    text = (root / "kw_msgs" / "Everything.idl").read_text()
    members = [line.strip() for line in body(text, "Everything_").splitlines() if not line.strip().startswith("//")]
    assert members == [
        "boolean flag;", "int8 small;", "uint64 big;", "float ratio;", "string<8> fixed_text;", "string text;",
        "sequence<uint8> blob;", "sequence<uint8> octets;", "sequence<double> values;",
        "uint16 grid[4][3][2];",
        "sequence<Everything__maybe_grid, 1> maybe_grid;",
        "sequence<Everything__rows> rows;",
        "sequence<sequence<Everything__nested> > nested;",
        "sequence<Everything__arrays_of_vecs> arrays_of_vecs[3];",
        "sequence<Everything__deep_3, 1> deep;",
        "sequence<int32, 1> maybe;",
        "sequence<sequence<double> > matrices;",
        "sequence<::kw_msgs::dds_::Kind_> kinds;", "::kw_msgs::dds_::Kind_ kind;",
        "::kw_other::dds_::Thing_ thing;", "::kw_other::dds_::Thing_ things[2];",
        # IDL keywords (compared without case) get rosidl's trailing underscore...
        "uint8 module_;", "uint8 string_;", "uint8 sequence_;", "uint8 Octet_;", "uint8 map_;", "uint8 fixed_;",
        "uint8 uint8_;", "uint8 interface_;",
        # ...names IDL would read as one (case, the struct's own name) one more; `_x` is escaped.
        "float x;", "float X_;", "uint8 everything__;", "uint8 __hidden;"]
    # Anonymous arrays cannot be sequence<> elements: typedefs, declared before the struct.
    for typedef in ["typedef float Everything__maybe_grid[3];", "typedef int32 Everything__rows[2][2];",
                    "typedef uint8 Everything__nested[2];", "typedef float Everything__arrays_of_vecs[2];",
                    "typedef double Everything__deep[2];",
                    "typedef sequence<Everything__deep> Everything__deep_2;",
                    "typedef Everything__deep_2 Everything__deep_3[3];"]:
        assert typedef in text and text.index(typedef) < text.index("struct Everything_ {"), typedef


def test_files_have_a_banner_a_guard_includes_and_the_horus_identity(everything):
    root, includes, files = everything
    model = model_of(includes, files)
    text = (root / "kw_msgs" / "Everything.idl").read_text()
    assert text.startswith("// Generated by horus-gen from all.hmsg. Do not edit: edit the schema and regenerate.\n"
                           "#ifndef HORUS_IDL_KW_MSGS_EVERYTHING_IDL_\n#define HORUS_IDL_KW_MSGS_EVERYTHING_IDL_\n")
    assert text.rstrip().endswith("#endif  // HORUS_IDL_KW_MSGS_EVERYTHING_IDL_")
    assert re.findall(r'#include "(.*)"', text) == ["kw_msgs/Kind.idl", "kw_other/Thing.idl"]
    assert "module kw_msgs {\nmodule dds_ {\n" in text
    fingerprint = model.types["kw_msgs.Everything"].fingerprint
    assert f"// HORUS type kw_msgs.Everything, fingerprint 0x{fingerprint:016x}." in text
    constants = text[text.index("module Everything_Constants {"):text.index("};", text.index("Everything_Constants"))]
    assert [line.strip() for line in constants.splitlines()[1:]] == [
        f"const uint64 HORUS_FINGERPRINT = 0x{fingerprint:016x};",
        'const string HORUS_TYPE_NAME = "kw_msgs.Everything";',
        "const double MAX = 1.5e+300;",
        'const string<12> LABEL = "plain text";',
        "const uint32 KIND = 2;  // Kind::Octet",
        "const boolean ON = TRUE;",
        "const uint8 MODULE_ = 3;",
        "// QUOTE: left out, its value has no IDL literal that idlc's C keeps."]
    # The doc line's trailing backslash would continue the // comment over the next line.
    assert "// Every kind of type. A doc line ending in a backslash\n@final\nstruct Everything_ {" in text
    assert (root / "kw_msgs" / "Octet.idl").read_text().count("uint8 octet__;") == 1


def test_an_enum_is_a_typedef_of_its_integer_and_a_constant_per_variant(everything):
    root, _, _ = everything
    text = (root / "kw_other" / "Level.idl").read_text()
    assert "typedef int16 Level_;" in text
    assert "const int16 Low = -1;" in text and "const int16 Default_ = 0;" in text and "const int16 Map_ = 5;" in text
    assert "#include" not in text


def test_a_service_is_its_request_and_response_structs_in_one_file(everything):
    root, includes, files = everything
    service = model_of(includes, files).services["kw_msgs.Lookup"]
    text = (root / "kw_msgs" / "Lookup.idl").read_text()
    assert f"const uint64 HORUS_FINGERPRINT = 0x{service.fingerprint:016x};" in text.split("module Lookup_Constants")[1]
    assert body(text, "Lookup_Request_").split() == ["string", "name;", "::kw_msgs::dds_::Kind_", "kind;"]
    assert body(text, "Lookup_Response_").split() == ["boolean", "found;", "sequence<Lookup_Response__where_,", "1>",
                                                      "where_;"]
    assert 'HORUS_TYPE_NAME = "kw_msgs.LookupRequest"' in text and "typedef double Lookup_Response__where_[3];" in text
    assert re.findall(r'#include "(.*)"', text) == ["kw_msgs/Kind.idl"]


def test_an_empty_message_gets_ros2s_placeholder_member(everything):
    root, _, _ = everything
    assert body((root / "kw_msgs" / "Empty.idl").read_text(), "Empty_").strip().endswith(
        "uint8 structure_needs_at_least_one_member;")


def test_a_pool_block_crosses_dds_as_the_data_it_holds(tmp_path):
    # The descriptors of pool-backed types: the DDS bridge sends the block's bytes in its place.
    root = generate(tmp_path, [str(ROOT / "schemas")], [str(ROOT / "schemas/horus/msg/vision.hmsg")])
    members = [line.strip() for line in body((root / "horus/msg/ImageDescriptor.idl").read_text(),
                                             "ImageDescriptor_").splitlines()
               if not line.strip().startswith("//")]
    assert members == ["uint32 width;", "uint32 height;", "::horus::msg::dds_::ImageEncoding_ encoding;",
                       "uint8 channels;", "uint32 step;", "uint64 data_size;", "sequence<uint8> data;",
                       "string<32> frame_id;", "uint64 timestamp_ns;"]


def test_idl_refuses_no_name_it_renames_instead():
    assert idl.KEYWORDS == frozenset()
    assert [idl.identifier(n) for n in ("module", "Module", "MAP", "x", "_x", "dds_")] == [
        "module_", "Module_", "MAP_", "x", "__x", "dds_"]


def test_output_is_deterministic(everything, tmp_path):
    root, includes, files = everything
    again = generate(tmp_path, includes, files)
    for path in root.rglob("*.idl"):
        assert (again / path.relative_to(root)).read_text() == path.read_text(), path


def c_name(model, qualified: str) -> str:
    found = model.types[qualified]
    return "_".join(idl.modules(found.package)) + "_" + idl.identifier(idl.declared_name(model, qualified) + "_")


def same_layout_in_c(model, qualified: str) -> bool:
    """A POD message whose C struct from idlc has the HORUS layout: numbers, bools, enums, fixed
    arrays of them and such messages (IDL strings are pointers in C, and HORUS's are inline; a
    PoolBlock is a sequence of the block's data)."""
    found = model.types[qualified]
    if not isinstance(found, Message) or not found.is_pod:
        return False

    def plain(t) -> bool:
        if isinstance(t, FixedArray):
            return plain(t.element)
        if isinstance(t, MessageRef):
            return t.qualified != idl.POOL_BLOCK and same_layout_in_c(model, t.qualified)
        return isinstance(t, (Primitive, EnumRef))
    return all(plain(f.type) for f in found.fields)


def layout_asserts(model) -> list[str]:
    lines = []
    for qualified in model.generated:
        if qualified in model.types and same_layout_in_c(model, qualified):
            message = model.message(qualified)
            struct = idl.struct_of(model, message)
            name = c_name(model, qualified)
            lines.append(f'_Static_assert(sizeof({name}) == {message.size}, "{qualified}: size {message.size}");')
            for f, member in zip(message.fields, struct.members):
                c_member = member.name[1:] if member.name.startswith("_") else member.name
                lines.append(f'_Static_assert(offsetof({name}, {c_member}) == {f.offset}, '
                             f'"{qualified}.{f.name}: offset {f.offset}");')
    return lines


@pytest.mark.parametrize("which", ["standard", "tests", "mapping"])
def test_idlc_compiles_the_idl_and_cc_the_c_it_writes_with_the_horus_layout(everything, tmp_path, which):
    if which == "mapping":
        root, includes, files = everything
    else:
        includes, files = ([str(ROOT / "schemas")], STANDARD) if which == "standard" else ([str(SCHEMAS)], TESTS)
        root = generate(tmp_path / "out", includes, files)
    c_files = compile_with_cyclone(root, tmp_path / "c")
    model = model_of(includes, files)

    # The DDS type name is ROS 2's: what a ROS 2 node (rmw_cyclonedds) or a plain Cyclone program names.
    typenames = {m for path in c_files for m in re.findall(r'\.m_typename = "([^"]+)"', path.read_text())}
    expected = {"::".join(idl.modules(t.package)) + "::" + idl.identifier(idl.declared_name(model, q) + "_")
                for q, t in model.types.items() if isinstance(t, Message) and q in model.generated}
    assert typenames == expected
    samples = {"standard": ["horus.msg.CmdVel", "horus.msg.Imu"],
               "tests": ["test_msgs.ImuLike", "test_msgs.Primitives", "test_msgs.Empty"],
               "mapping": ["kw_msgs.Pod", "kw_msgs.Empty"]}[which]
    assert "horus::msg::dds_::CmdVel_" in typenames or which != "standard"

    # Where the layouts coincide the C struct idlc writes is the HORUS message, byte for byte.
    asserts = layout_asserts(model)
    for qualified in samples:
        assert f"sizeof({c_name(model, qualified)}) == {model.message(qualified).size}," in "\n".join(asserts), qualified
    headers = sorted({str(p.relative_to(tmp_path / "c").with_suffix(".h")) for p in c_files})
    check = tmp_path / "layout.c"
    check.write_text("#include <stddef.h>\n" + "".join(f'#include "{h}"\n' for h in headers) + "\n".join(asserts) + "\n")
    result = subprocess.run(["cc", "-c", "-I", str(tmp_path / "c"), "-I/usr/include", str(check),
                             "-o", str(tmp_path / "layout.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
