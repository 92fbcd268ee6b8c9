"""horus-gen on malformed input (emitting C++, Python and IDL): every input ends in exit 0 with
output that imports in Python and compiles with g++, or exit 1 with `file:line:col: error:`
diagnostics and no output; never an internal error, never more than a few seconds of CPU. A
mutation fuzzer with a fixed seed over the project's own schemas (every distinct accepted output
imported, an evenly spread sample of them compiled with warnings as errors): its mutations also
rename names to ones C++ or Python give a meaning, insert doc text that comments and docstrings
must hold, and append long chains of declarations. Then one case per class of input that once
crashed or hung the generator, or was accepted with code that did not compile."""
from __future__ import annotations

import concurrent.futures
import contextlib
import hashlib
import io
import os
import random
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from generator_testing import HORUS_GEN, ROOT, SCHEMAS, run_horus_gen
from horus_gen.cli import main
from horus_gen.data import DataPaths
from horus_gen.lang import cpp

DATA = DataPaths.for_launcher(str(HORUS_GEN), str(ROOT / "templates"),
                              str(ROOT / "runtime" / "python" / "_horus_gen_support_v1.py"))
SEEDS = [p.read_text() for p in sorted((ROOT / "schemas" / "horus" / "msg").glob("*.hmsg"))
         + sorted(SCHEMAS.glob("*/*.h*"))]
NODE_SEEDS = [p.read_text() for p in sorted(SCHEMAS.glob("*/*.hnode"))
              + sorted((ROOT / "examples" / "warehouse_agv" / "nodes").glob("*.hnode"))]
# Fragments a careless or hostile edit could bring in: syntax, limits, reserved names, odd characters.
FRAGMENTS = ["[", "]", "<", ">", "{", "}", ";", ",", ":", "::", "=", "#[", "Vec<", "Option<", "[u8; 99999999999999]",
             "[[[[", "9" * 200, "1e999", "0x", "-", '"\\0"', "NULL", "errno", "assert", "self", "log_summary",
             "é", "ﬁ", "\0", "\r", "\u2028", "string<0>", "string<99999999999>", "f32", "u64", "1.5", "enum",
             "package", "import", "service", "\n", "///", "//", "_horus", "__x", "²",
             # node files
             "sub {", "pub {", "client {", "server {", "data {", "->", '-> "t"', "rate: 1 hz,", "budget: 1 us,",
             "on_miss: Stop,", "failure_policy: Restart { max_restarts: 1 },", "#[capacity = 3]", "node!", 'on: "x",',
             # params blocks
             "params {", "#[min = 1]", "#[max = -1.5]", '#[choices = ["a", 2]]', "#[read_only]", '#[unit = "\\\\"]',
             "[bool; 300]"]
# Doc text that C++ comments and Python docstrings must hold: comment and string ends, backslashes
# (one ending a line would continue a C++ `//` comment), trigraphs, non-ASCII.
DOCS = ["\n/// */ /* \"\"\" ''' \\n \\\n", "\n/// ends in a backslash \\\n", "\n/// ??/\n", "\n/// ?? ??/ x\n",
        "\n/// é — ü 中\n", "\n/// \"quoted\"\n", "\n/// \\\\\n", "\n///\t\x7e\n"]
FRAGMENTS += DOCS
# Names that C++ or Python give a meaning where the generated code puts them (members, types,
# enumerators, packages): keywords, macros, namespaces and types the code names, the generated
# code's own methods, locals and module names. A mutation renames every occurrence of one name of
# the input to one of these, so that many such mutants are accepted, and must then compile and import.
SPECIAL_NAMES = ["class", "None", "def", "std", "horus", "msgpack", "errno", "assert", "unix", "linux", "EOF",
                 "NULL", "INT_MAX", "st_atime", "stdin", "log_summary", "fingerprint", "schema", "visit", "type",
                 "size", "name", "value", "string", "vector", "array", "optional", "uint8_t", "size_t", "TypeInfo",
                 "FixedString", "Node", "Topic", "Request", "Response", "numpy", "math", "struct", "Sequence",
                 "ClassVar", "TYPE_CHECKING", "cls", "buf", "off", "v", "msg", "fn", "handler", "settings", "declared",
                 "fields", "kParts", "computed0", "horus_log_summary", "mro", "real", "to_bytes", "copy", "_s",
                 "_c_x", "self", "True", "print", "int", "float", "list", "object", "main", "operator", "p"]
NODE_FUZZ_INPUTS = 300
FUZZ_INPUTS = 2000
# How many of the distinct accepted outputs g++ checks (every one is imported).
CPP_COMPILES = 10
CXX = os.environ.get("CXX", "g++")
# CPU seconds, far above any input's: this catches hangs, it measures nothing (the slowest input's
# CPU time is printed, and recorded in BENCHMARKS.md). CPU time, not wall time, so that a machine
# loaded by other work never passes for a hang.
SECONDS_PER_INPUT = 5


class Hang(Exception):
    pass


_NAME = re.compile(r"\b[A-Za-z_]\w*\b")


def chain(rng: random.Random) -> str:
    """Many declarations, each using the next: deep nesting of messages, or a long run of enums."""
    count = rng.choice([20, 64, 1100])
    if rng.random() < 0.5:
        return "".join(f"\nC{i} {{ x: C{i + 1}, y: [u8; 2] }}" for i in range(count)) + f"\nC{count} {{ z: u8 }}\n"
    return "".join(f"\nenum E{i}: u8 {{ A = {i % 250}, B }}" for i in range(count)) + "\n"


def mutate(rng: random.Random, text: str) -> str:
    for _ in range(rng.randint(1, 4)):
        at = rng.randrange(len(text) + 1)
        choice = rng.random()
        if choice < 0.15:
            names = sorted(set(_NAME.findall(text)))
            if names:
                text = re.sub(rf"\b{rng.choice(names)}\b", rng.choice(SPECIAL_NAMES), text)
            continue
        if choice < 0.2:
            line_start = text.rfind("\n", 0, at) + 1
            text = text + chain(rng) if rng.random() < 0.5 else text[:line_start] + rng.choice(DOCS) + text[line_start:]
            continue
        if choice < 0.3:
            text = text[:at] + rng.choice(FRAGMENTS) + text[at:]
        elif choice < 0.5:
            text = text[:at] + text[at + rng.randint(1, 20):]
        elif choice < 0.7:
            end = at + rng.randint(1, 40)
            text = text[:at] + text[at:end] * rng.randint(2, 50) + text[end:]
        elif choice < 0.85:
            other = rng.choice(SEEDS)
            start = rng.randrange(len(other) + 1)
            text = text[:at] + other[start:start + rng.randint(1, 80)] + text[at:]
        else:
            text = text[:at] + rng.choice(FRAGMENTS) * rng.randint(50, 3000) + text[at:]
    return text


def generate_in_process(schema: Path, out: Path, includes: tuple[Path, ...] = (ROOT / "schemas",)) -> tuple[int, str]:
    """horus-gen generate of one file in this process (a subprocess each would take minutes)."""
    def hang(*_):
        raise Hang()

    previous = signal.signal(signal.SIGPROF, hang)
    stderr = io.StringIO()
    signal.setitimer(signal.ITIMER_PROF, SECONDS_PER_INPUT)
    try:
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
            status = main(DATA, ["generate", "--lang", "cpp,python,idl", "--out", str(out),
                                 *(arg for folder in includes for arg in ("-I", str(folder))), str(schema)])
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, previous)
    return status, stderr.getvalue()


def output_digest(out: Path) -> str:
    """What the generator wrote, as one digest: mutants that differ only in what the generator
    ignores (comments, spacing) are compiled and imported once."""
    digest = hashlib.sha256()
    for path in sorted(p for p in out.rglob("*") if p.is_file() and p.name != ".horus-gen-outputs"):
        digest.update(str(path.relative_to(out)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


@pytest.fixture(scope="module")
def libraries(tmp_path_factory) -> Path:
    """The packages mutants import (horus.msg, the test schemas' packages), generated once: a
    mutant's own output holds only the fuzzed file's types."""
    out = tmp_path_factory.mktemp("libraries")
    for files in (sorted((ROOT / "schemas" / "horus" / "msg").glob("*.hmsg")),
                  *(sorted((SCHEMAS / package).glob("*.h[ms]*")) for package in ("test_msgs", "other_pkg", "crosslang"))):
        result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(out), "-I", str(ROOT / "schemas"),
                               "-I", str(SCHEMAS), *map(str, files))
        assert result.returncode == 0, result.stderr
        (out / ".horus-gen-outputs").unlink()  # each run lists only its own outputs
    return out


# Imports every generated module of each output folder named on the command line, each folder in
# a fresh set of modules (mutants share package names), over a copy of the libraries' modules so
# that a package split between the two stays whole; prints one line per failure. The support
# module is the copy of runtime/python's that horus-gen writes beside the packages. Generated
# nodes subclass horus.Node: the built runtime package (given, or "" for none) is imported first,
# and each folder's horus/ joins its path as `horus/__init__.py`'s extend_path would.
IMPORT_SCRIPT = """
import importlib, shutil, sys, tempfile, traceback
from pathlib import Path
libraries, runtime, outputs = Path(sys.argv[1]), sys.argv[2], sys.argv[3:]
if runtime:
    sys.path.insert(0, runtime)
    import horus
for out in outputs:
    with tempfile.TemporaryDirectory() as merged:
        shutil.copytree(libraries, merged, dirs_exist_ok=True)
        shutil.copytree(Path(out) / "python", merged, dirs_exist_ok=True)
        before = set(sys.modules)
        sys.path.insert(0, merged)
        if runtime:
            horus.__path__.append(merged + "/horus")
        for module in sorted((Path(out) / "python").rglob("*.py")):
            name = ".".join(module.relative_to(Path(out) / "python").with_suffix("").parts)
            name = name.removesuffix(".__init__")
            try:
                importlib.import_module(name)
            except BaseException:
                print(f"{out}: {name} does not import: " + traceback.format_exc().replace(chr(10), " | "))
        sys.path.remove(merged)
        if runtime:
            horus.__path__.remove(merged + "/horus")
        for name in set(sys.modules) - before:
            del sys.modules[name]
"""


def python_runtime() -> str:
    """The built `horus` package's folder (HORUS_BUILD_DIR/python, default build/python)."""
    folder = Path(os.environ.get("HORUS_BUILD_DIR") or ROOT / "build") / "python"
    if not any((folder / "horus").glob("_core*.so")):
        raise FileNotFoundError(f"generated nodes import the horus runtime, not built in {folder}: build it with "
                                f"`cmake --build {folder.parent} --target horus_python` (HORUS_BUILD_PYTHON=ON), "
                                "or name another build folder in HORUS_BUILD_DIR")
    return str(folder)


def import_failures(outputs: list[Path], libraries: Path, runtime: str) -> list[str]:
    """One Python process imports every output's modules (a process each would take minutes)."""
    if not outputs:
        return []
    result = subprocess.run(["/usr/bin/python3", "-c", IMPORT_SCRIPT, str(libraries / "python"), runtime,
                             *map(str, outputs)],
                            capture_output=True, text=True, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    return result.stdout.splitlines() + ([f"the import process failed: {result.stderr}"] if result.returncode else [])


def compile_failure(out: Path, libraries: Path) -> str | None:
    """The output's C++ as one translation unit (its .cpp files, which include the package's
    headers, and every header), checked by g++ -fsyntax-only; the compiler's errors, or None."""
    cpp = out / "cpp"
    unit = out / "all.cc"
    unit.write_text("".join(f'#include "{p.relative_to(cpp)}"\n'
                            for p in sorted(cpp.rglob("*")) if p.suffix in (".cpp", ".hpp")))
    result = subprocess.run([CXX, "-std=c++20", "-fsyntax-only", "-Wall", "-Wextra", "-Wpedantic", "-Werror", f"-I{ROOT / 'runtime' / 'include'}", f"-I{cpp}",
                             f"-I{libraries / 'cpp'}", str(unit)], capture_output=True, text=True)
    return f"{cpp} does not compile:\n{result.stderr[:3000]}" if result.returncode else None


@pytest.mark.parametrize("suffix, seeds, count", [(".hmsg", SEEDS, FUZZ_INPUTS), (".hnode", NODE_SEEDS, NODE_FUZZ_INPUTS)],
                         ids=["messages", "nodes"])
def test_mutated_schemas_end_in_output_or_diagnostics(tmp_path, capsys, libraries, suffix, seeds, count):
    rng = random.Random(23)
    schema = tmp_path / "fuzzed" / f"fuzzed{suffix}"
    schema.parent.mkdir()
    failures = []
    accepted: dict[str, tuple[int, str, Path]] = {}  # output digest -> the first input that wrote it
    slowest = (0.0, -1, 0)  # CPU seconds, input, its size in bytes
    started, started_cpu = time.monotonic(), time.process_time()
    for index in range(count):
        text = mutate(rng, rng.choice(seeds))
        schema.write_text(text, encoding="utf-8")
        out = tmp_path / f"out{index}"
        cpu = time.process_time()
        try:
            status, stderr = generate_in_process(schema, out, (ROOT / "schemas", SCHEMAS))
        except Hang:
            failures.append((index, f"took more than {SECONDS_PER_INPUT} s of CPU", text))
            continue
        slowest = max(slowest, (time.process_time() - cpu, index, len(text.encode())))
        if "internal error" in stderr or status not in (0, 1):
            failures.append((index, stderr or f"exit {status}", text))
        elif status == 1:
            written = [p for p in out.rglob("*") if p.is_file()] if out.exists() else []
            if written or ": error: " not in stderr:
                failures.append((index, f"exit 1 with output {written[:3]} or no diagnostic: {stderr}", text))
        else:
            accepted.setdefault(output_digest(out), (index, text, out))
    generated, generated_cpu = time.monotonic() - started, time.process_time() - started_cpu

    by_out = {str(out): (index, text) for index, text, out in accepted.values()}
    runtime = python_runtime() if suffix == ".hnode" else ""
    for line in import_failures([out for _, _, out in accepted.values()], libraries, runtime):
        index, text = by_out.get(line.split(":", 1)[0], (-1, ""))
        failures.append((index, line, text))
    # Every accepted output is imported; a bounded, evenly spread sample is compiled (a compiler
    # run takes a second or more), two at a time.
    outputs = list(accepted.values())
    sample = outputs[::max(1, -(-len(outputs) // CPP_COMPILES))]
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        for (index, text, _), failure in zip(sample, pool.map(lambda entry: compile_failure(entry[2], libraries), sample)):
            if failure:
                failures.append((index, failure, text))
    with capsys.disabled():
        print(f"\n{count} {suffix} inputs generated in {generated:.1f} s ({generated_cpu:.1f} s of CPU); slowest input {slowest[1]} "
              f"({slowest[2]} bytes): {slowest[0] * 1000:.0f} ms of CPU; {len(accepted)} distinct outputs imported, {len(sample)} compiled; "
              f"{time.monotonic() - started:.1f} s in all")
    assert not failures, "\n\n".join(f"input {i}: {why}\n--- input ---\n{text[:2000]}" for i, why, text in failures[:3])


def check(tmp_path, text: str, folder: str = "p", suffix: str = ".hmsg") -> str:
    """Runs `horus-gen check` on `text` as the one schema in `folder` (package p unless it says
    otherwise); returns its stderr after asserting exit 1 with diagnostics."""
    schema = tmp_path / folder / ("case" + suffix)
    schema.parent.mkdir(exist_ok=True)
    schema.write_text(text, encoding="utf-8")
    result = run_horus_gen("check", str(schema))
    assert result.returncode == 1, result.stderr
    assert "internal error" not in result.stderr and schema.name + ":" in result.stderr, result.stderr
    return result.stderr


def case(text: str, error: str, id: str, folder: str = "p"):
    return pytest.param(text, error, folder, id=id)


@pytest.mark.parametrize("text, error, folder", [
    case("A { x: " + "[" * 500 + "f32" + "; 2]" * 500 + " }\n",
          "types nest more than 16 deep", id="nested_arrays"),
    case("A { x: " + "Vec<" * 500 + "f32" + ">" * 500 + " }\n",
          "types nest more than 16 deep", id="nested_generics"),
    case("A { x: [f32; 2] = " + "[" * 500 + "1" + "]" * 500 + " }\n",
          "values nest more than 16 deep", id="nested_lists"),
    case("A { x: u64 = " + "9" * 5000 + " }\n",
          "number of 5000 characters is longer than 100", id="long_integer"),
    case("A { x: u64 = 0x" + "f" * 5000 + " }\n",
          "number of 5002 characters is longer than 100", id="long_hex"),
    case("A { x: [u8; ²] }\n", "unexpected character '²'", id="unicode_digit"),
    case("A { x: [u8; 1099511627776] }\n",
          "array length 1099511627776 is more than 1073741824", id="huge_array"),
    case("A { x: string<1099511627776> }\n",
          "string capacity 1099511627776 is more than 1073741824", id="huge_string"),
    case("B { a: u8, b: u32 }\nA { x: [B; 100000] }\n",
          "message 'A' is too large: 100000 elements with 1 padding", id="many_padding_ranges"),
    case("A { x: [[u8; 1073741824]; 2] }\n", "message 'A' is too large", id="huge_message"),
    # The same limit where no POD layout is computed: this one was accepted, and its C++ did not compile.
    case("B { v: Vec<[[[u8; 1073741824]; 1073741824]; 1073741824]> }\n",
         "case.hmsg:1:5: error: field 'v' of 'B' is too large: [1073741824 elements of 1073741824 bytes]",
         id="huge_array_in_vec"),
    case("B { v: Option<[[u8; 1073741824]; 2]> }\n", "field 'v' of 'B' is too large", id="huge_array_in_option"),
    case("B { s: String, v: [[u16; 1073741824]; 1] }\n", "field 'v' of 'B' is too large", id="huge_array_in_serialized"),
    case("".join(f"C{i} {{ x: C{i + 1} }}\n" for i in range(1100)) + "C1100 { z: u8 }\n",
         "case.hmsg:1037:9: error: message 'C1036' holds messages more than 64 levels deep (through 'x')",
         id="deep_chain_of_messages"),
    case("A { é: u8 }\n", "name 'é' is not ASCII", id="unicode_name"),
    case("A { ﬁeld: u8 }\n", "is not ASCII", id="nfkc_name"),
    case("A" * 101 + " { x: u8 }\n", "name of 101 characters is longer than 100", id="long_name"),
    case("/// a\0b\nA { x: u8 }\n", "character U+0000 is not allowed", id="nul_in_doc"),
    case("/// a\u2028b\nA { x: u8 }\n", "character U+2028 is not allowed", id="line_separator_in_doc"),
    case('A { x: string<4> = "a\\0" }\n', "holds a NUL character", id="nul_in_fixed_string"),
    # C++ initialised std::string from "a\0b" as "a"; Python kept 'a\x00b'.
    case('C { s: String = "a\\0b" }\n', "value of field 's' holds a NUL character, which String values",
         id="nul_in_string"),
    case('C { const S: String = "a\\0b", x: u8 }\n', "value of constant 'S' holds a NUL character",
         id="nul_in_string_constant"),
    # ValueError building an enum: a value outside the underlying type, two enumerators on one
    # value, a value too long to spell (Python refuses int-to-text beyond 4300 digits).
    case("enum E: u8 { A = 300 }\nA { e: E }\n", "value 300 of 'E::A' is out of range for u8", id="enum_value_out_of_range"),
    case("enum E: u8 { A = 1, B = 1 }\nA { e: E }\n", "duplicate enum value 1: 'B' and 'A' of 'E'", id="enum_duplicate_value"),
    case("enum E: u64 { A = 0x" + "f" * 5000 + " }\n", "number of 5002 characters is longer than 100", id="enum_huge_value"),
    # identity.py spells array lengths into the type's identity text: one past int-to-text's limit.
    case("A { x: [u8; 0x" + "f" * 4000 + "] }\n", "number of 4002 characters is longer than 100", id="spelled_array_length"),
    # An integer as a float default: float() raised OverflowError past 1.8e308.
    case("A { x: f64 = 0x" + "f" * 300 + " }\n", "number of 302 characters is longer than 100", id="float_default_overflow"),
    case("A { x: f32 = 0x" + "f" * 98 + " }\n", "is out of range for f32", id="float_default_out_of_f32"),
    # Names from the schema's folder (no `package` line) become file names too: characters a
    # path or an identifier cannot hold, or too many of them, are refused like declared names.
    case("A { x: u8 }\n", "package name 'bad-pkg' cannot be", folder="bad-pkg", id="folder_name_with_dash"),
    case("A { x: u8 }\n", "'é' is not ASCII", folder="é", id="folder_name_not_ascii"),
    case("A { x: u8 }\n", "is longer than 100 characters", folder="p" * 200, id="folder_name_too_long"),
])


def test_each_class_of_bad_input_is_an_error_with_its_place(tmp_path, text, error, folder):
    stderr = check(tmp_path, text, folder)
    assert error in stderr and "Traceback" not in stderr


@pytest.mark.parametrize("text, suffix, error", [
    ("S { request { a: Vec<[[u8; 1073741824]; 4]> } response { b: u8 } }\n", ".hsrv",
     "case.hsrv:1:15: error: field 'a' of 'SRequest' is too large"),
    ("node! { N { data { x: Vec<[[u8; 1073741824]; 4]> } } }\n", ".hnode",
     "case.hnode:1:20: error: data field 'x' is too large"),
], ids=["service", "node_data"])
def test_a_fixed_size_array_is_bounded_in_services_and_node_data(tmp_path, text, suffix, error):
    stderr = check(tmp_path, text, suffix=suffix)
    assert error in stderr and "a fixed-size array holds at most 1073741824 bytes" in stderr


@pytest.mark.parametrize("name", ["NULL", "errno", "assert", "stdin", "EOF", "INT32_MAX", "INT_MAX", "linux", "self",
                                  "log_summary", "to_bytes", "st_atime", "TYPE_CHECKING", "_c_x", "_s"])
def test_names_the_generated_code_cannot_use_are_refused(tmp_path, name):
    stderr = check(tmp_path, f"A {{ {name}: u8 }}\n")
    assert f"member name '{name}' is" in stderr


# Names C++ or Python give a meaning where generated code puts them, which it holds safely, and doc
# text its comments and docstrings must hold: before, `B: B` and a type `std` did not compile,
# the trailing backslash commented out the next line of C++, and `B()` met the parameter B.
SPECIAL_SCHEMA = '''package odd.std;
/// doc */ /* """ \\ ends in a backslash \\
/// ??/
B { x: u8 }
/// é ??/
A { B: B, string: u8, uint8_t: u16, type: f32, size: u8, buf: B, cls: u8, v: [B; 2] }
enum E: u8 { std = 0, None_ = 1, value = 2, name = 3 }
/// a type named like the namespace generated code uses
std { x: u8, e: E, a: A }
buf { off: B }
S { s: String, b: B, numpy: Vec<B> }
'''


def test_special_names_and_doc_text_compile_import_and_round_trip(tmp_path):
    schema = tmp_path / "odd" / "std" / "odd.hmsg"
    schema.parent.mkdir(parents=True)
    schema.write_text(SPECIAL_SCHEMA, encoding="utf-8")
    out = tmp_path / "out"
    result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(out), str(schema))
    assert result.returncode == 0, result.stderr
    assert compile_failure(out, tmp_path) is None
    script = ("import sys; sys.path.insert(0, sys.argv[1]); from odd.std import A, S, std, buf, B\n"
              "a = A(); a.B.x = 3; assert A.from_bytes(a.to_bytes()) == a, a\n"
              "assert buf.from_bytes(buf(off=B(x=1)).to_bytes()).off.x == 1\n"
              "s = S(numpy=[B(x=2)]); assert S.from_bytes(s.to_bytes()) == s\n"
              "print(std().log_summary())\n")
    ran = subprocess.run(["/usr/bin/python3", "-c", script, str(out / "python")], capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.startswith("std{x: 0, e: std, a: A{B: B{x: 0}")


def test_the_runtimes_namespaces_are_not_packages():
    """Every namespace the runtime's headers open (`horus::detail`, or `namespace log {` inside
    horus) is refused as a package, and so is horus itself."""
    text = "\n".join(p.read_text() for p in (ROOT / "runtime" / "include").rglob("*.hpp"))
    nested = set(re.findall(r"^(?:inline )?namespace (\w+) \{", text, re.M)) - {"horus", "msgpack", "adaptor"}
    opened = {"horus"} | {m.replace("::", ".") for m in re.findall(r"namespace (horus(?:::\w+)+)", text)}
    opened |= {"horus." + name for name in nested}
    assert [p for p in sorted(opened) if not cpp.reserved_package(p)] == []


def test_thousands_of_errors_are_counted_and_the_first_hundred_shown(tmp_path):
    stderr = check(tmp_path, "A {\n" + "".join(f"    f{i}: Unknown{i},\n" for i in range(3000)) + "}\n")
    assert stderr.count(": error: ") == 100
    assert "(2900 more errors not shown)\n3000 errors generated." in stderr


def test_an_output_folder_that_cannot_be_written_is_an_error_not_a_crash(tmp_path):
    blocked = tmp_path / "file"
    blocked.write_text("")
    result = run_horus_gen("generate", "--out", str(blocked / "out"), str(SCHEMAS / "other_pkg" / "stamp.hmsg"))
    assert result.returncode == 1
    assert "horus-gen: error: cannot write the output to" in result.stderr and "Traceback" not in result.stderr
