"""horus-gen on malformed input (emitting C++, Python and IDL): every input ends in exit 0 with
output that Python compiles, or exit 1 with `file:line:col: error:` diagnostics and no output;
never an internal error. A mutation fuzzer with a fixed seed over the project's own schemas, then
one case per class of input that once crashed or hung the generator."""
from __future__ import annotations

import contextlib
import io
import random
import signal
from pathlib import Path

import pytest

from generator_testing import HORUS_GEN, ROOT, SCHEMAS, run_horus_gen
from horus_gen.cli import main
from horus_gen.data import DataPaths

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
             "on_miss: Stop,", "failure_policy: Restart { max_restarts: 1 },", "#[capacity = 3]", "node!", 'on: "x",']
NODE_FUZZ_INPUTS = 300
FUZZ_INPUTS = 2000
# CPU seconds, far above any input's: this catches hangs, it measures nothing. CPU time, not wall
# time, so that a machine loaded by other work never passes for a hang.
SECONDS_PER_INPUT = 5


class Hang(Exception):
    pass


def mutate(rng: random.Random, text: str) -> str:
    for _ in range(rng.randint(1, 4)):
        at = rng.randrange(len(text) + 1)
        choice = rng.random()
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


@pytest.mark.parametrize("suffix, seeds, count", [(".hmsg", SEEDS, FUZZ_INPUTS), (".hnode", NODE_SEEDS, NODE_FUZZ_INPUTS)],
                         ids=["messages", "nodes"])
def test_mutated_schemas_end_in_output_or_diagnostics(tmp_path, suffix, seeds, count):
    rng = random.Random(23)
    schema = tmp_path / "fuzzed" / f"fuzzed{suffix}"
    schema.parent.mkdir()
    failures = []
    for index in range(count):
        text = mutate(rng, rng.choice(seeds))
        schema.write_text(text, encoding="utf-8")
        out = tmp_path / f"out{index}"
        try:
            status, stderr = generate_in_process(schema, out, (ROOT / "schemas", SCHEMAS))
        except Hang:
            failures.append((index, "hung", text))
            continue
        if "internal error" in stderr or status not in (0, 1):
            failures.append((index, stderr or f"exit {status}", text))
        elif status == 1:
            written = [p for p in out.rglob("*") if p.is_file()] if out.exists() else []
            if written or ": error: " not in stderr:
                failures.append((index, f"exit 1 with output {written[:3]} or no diagnostic: {stderr}", text))
        else:
            for module in (out / "python").rglob("*.py"):
                try:
                    compile(module.read_text(), str(module), "exec")
                except SyntaxError as error:
                    failures.append((index, f"{module.name} does not compile: {error}", text))
    assert not failures, "\n\n".join(f"input {i}: {why}\n--- input ---\n{text[:2000]}" for i, why, text in failures[:3])


def check(tmp_path, text: str) -> str:
    """Runs `horus-gen check` on `text` as the one schema of package p; returns its stderr after
    asserting exit 1 with diagnostics."""
    schema = tmp_path / "p" / "case.hmsg"
    schema.parent.mkdir(exist_ok=True)
    schema.write_text(text, encoding="utf-8")
    result = run_horus_gen("check", str(schema))
    assert result.returncode == 1, result.stderr
    assert "internal error" not in result.stderr and "case.hmsg:" in result.stderr, result.stderr
    return result.stderr


@pytest.mark.parametrize("text, error", [
    pytest.param("A { x: " + "[" * 500 + "f32" + "; 2]" * 500 + " }\n",
                 "types nest more than 16 deep", id="nested_arrays"),
    pytest.param("A { x: " + "Vec<" * 500 + "f32" + ">" * 500 + " }\n",
                 "types nest more than 16 deep", id="nested_generics"),
    pytest.param("A { x: [f32; 2] = " + "[" * 500 + "1" + "]" * 500 + " }\n",
                 "values nest more than 16 deep", id="nested_lists"),
    pytest.param("A { x: u64 = " + "9" * 5000 + " }\n",
                 "number of 5000 characters is longer than 100", id="long_integer"),
    pytest.param("A { x: u64 = 0x" + "f" * 5000 + " }\n",
                 "number of 5002 characters is longer than 100", id="long_hex"),
    pytest.param("A { x: [u8; ²] }\n", "unexpected character '²'", id="unicode_digit"),
    pytest.param("A { x: [u8; 1099511627776] }\n",
                 "array length 1099511627776 is more than 1073741824", id="huge_array"),
    pytest.param("A { x: string<1099511627776> }\n",
                 "string capacity 1099511627776 is more than 1073741824", id="huge_string"),
    pytest.param("B { a: u8, b: u32 }\nA { x: [B; 100000] }\n",
                 "message 'A' is too large: 100000 elements with 1 padding", id="many_padding_ranges"),
    pytest.param("A { x: [[u8; 1073741824]; 2] }\n", "message 'A' is too large", id="huge_message"),
    pytest.param("A { é: u8 }\n", "name 'é' is not ASCII", id="unicode_name"),
    pytest.param("A { ﬁeld: u8 }\n", "is not ASCII", id="nfkc_name"),
    pytest.param("A" * 101 + " { x: u8 }\n", "name of 101 characters is longer than 100", id="long_name"),
    pytest.param("/// a\0b\nA { x: u8 }\n", "character U+0000 is not allowed", id="nul_in_doc"),
    pytest.param("/// a\u2028b\nA { x: u8 }\n", "character U+2028 is not allowed", id="line_separator_in_doc"),
    pytest.param('A { x: string<4> = "a\\0" }\n', "holds a NUL character", id="nul_in_fixed_string"),
])
def test_each_class_of_bad_input_is_an_error_with_its_place(tmp_path, text, error):
    assert error in check(tmp_path, text)


@pytest.mark.parametrize("name", ["NULL", "errno", "assert", "stdin", "EOF", "INT32_MAX", "linux", "self",
                                  "log_summary", "to_bytes"])
def test_names_the_generated_code_cannot_use_are_refused(tmp_path, name):
    stderr = check(tmp_path, f"A {{ {name}: u8 }}\n")
    assert f"member name '{name}' is" in stderr


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
