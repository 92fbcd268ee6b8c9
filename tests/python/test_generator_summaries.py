"""The message forms of the Rust seeds: `#[derive(...)]` lists, and hand-written summaries that
compute (`{field:.2}`, `{self.used / self.total * 100:.1}%`), which C++ and Python print alike;
and names and doc text that the generated code holds safely."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

from generator_testing import ROOT, import_from, run_horus_gen

CXX = os.environ.get("CXX", "g++")
BUILD = Path(os.environ.get("HORUS_BUILD_DIR") or ROOT / "build")

SCHEMA = '''package seedforms;

/// Battery state, as the seed's hand-written LogSummary would print it.
/// Doc text C++ comments and Python docstrings must hold: */ """ \\ ??/
/// ends in a backslash \\
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, Deserialize, LogSummary)]
#[summary = "Battery({count} cells, {voltage:.2}, {self.used / self.total * 100:.1}% used, r={(count + 1) * -2.5}, q={used / zero}, {{ok}})"]
pub struct Battery {
    pub count: u32,
    #[unit = "V"]
    pub voltage: f32,
    pub used: f64,
    pub total: f64,
    pub zero: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Mode: u8 { Idle = 0, Run = 1 }
'''
VALUES = [(3, 12.3456, 1.0, 3.0, 0.0), (0, -0.005, 2.5, 0.0, 0.0), (4000000000, 1e30, -7.25, 1e-300, 0.0),
          (7, 0.125, 0.0, 0.0, 0.0)]


def generate(tmp_path: Path) -> Path:
    schema = tmp_path / "seedforms" / "battery.hmsg"
    schema.parent.mkdir()
    schema.write_text(SCHEMA, encoding="utf-8")
    result = run_horus_gen("generate", "--lang", "cpp,python", "--out", str(tmp_path / "out"), str(schema))
    assert result.returncode == 0, result.stderr
    return tmp_path / "out"


def test_derive_lists_and_computed_summaries_are_accepted_and_print_the_same_in_cpp_and_python(tmp_path):
    out = generate(tmp_path)
    (seedforms,) = import_from(out / "python", "seedforms")
    python = [seedforms.Battery(count=c, voltage=v, used=u, total=t, zero=z).log_summary() for c, v, u, t, z in VALUES]
    assert python[0] == "Battery(3 cells, 12.35 V, 33.3% used, r=-10, q=inf, {ok})"
    main = tmp_path / "main.cpp"
    main.write_text('#include "seedforms.cpp"\n#include <cstdio>\nint main() {\n' + "".join(
        f"  {{ seedforms::Battery b{{}}; b.count = {c}U; b.voltage = static_cast<float>({float(v).hex()});"
        f" b.used = {float(u).hex()}; b.total = {float(t).hex()}; b.zero = {float(z).hex()};"
        f' std::puts(b.log_summary().c_str()); }}\n' for c, v, u, t, z in VALUES) + "}\n")
    library = BUILD / "runtime" / "libhorus_summary.a"
    if not library.exists():
        raise FileNotFoundError(f"the C++ half needs {library}: build it with `cmake --build {BUILD} --target "
                                "horus_summary`, or name another build folder in HORUS_BUILD_DIR")
    binary = tmp_path / "main"
    compiled = subprocess.run([CXX, "-std=c++20", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                               f"-I{ROOT / 'runtime' / 'include'}", f"-I{out / 'cpp'}", str(main), str(library),
                               "-o", str(binary)],
                              capture_output=True, text=True)
    assert compiled.returncode == 0, compiled.stderr
    cpp = subprocess.run([str(binary)], capture_output=True, text=True, check=True).stdout.splitlines()
    assert cpp == python


def check(tmp_path: Path, text: str) -> str:
    schema = tmp_path / "p" / "case.hmsg"
    schema.parent.mkdir(exist_ok=True)
    schema.write_text(text, encoding="utf-8")
    result = run_horus_gen("check", str(schema))
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    return result.stderr


def test_an_unknown_derive_is_an_error_with_a_hint(tmp_path):
    stderr = check(tmp_path, "#[derive(Debug, Clonee)]\nA { x: u8 }\n")
    assert "case.hmsg:1:17: error: unknown derive 'Clonee' on message 'A'" in stderr
    assert "did you mean 'Clone'?" in stderr


def test_copy_of_a_serialized_message_is_an_error(tmp_path):
    stderr = check(tmp_path, "#[derive(Copy)]\nA { x: String }\n")
    assert "message 'A' derives Copy, but it is serialized" in stderr


def test_a_summary_format_needs_a_number_field(tmp_path):
    stderr = check(tmp_path, '#[summary = "{name:.2}"]\nA { name: String }\n')
    assert "case.hmsg:1:15: error: #[summary] computes with 'name', which is 'String', not a number" in stderr


def test_macros_of_the_headers_generated_code_includes_are_reserved():
    """cpp_macros.txt lists every macro a file including generated headers sees; refresh it with
    HORUS_UPDATE_GOLDEN=1 after the runtime's headers change."""
    headers = ["horus/message.hpp", "horus/summary_table.hpp", "horus/node.hpp", "horus/topic.hpp", "horus/run.hpp",
               "horus/scheduler.hpp", "horus/service_client.hpp", "horus/service_server.hpp",
               "horus/topic_metadata.hpp", "horus/fixed_string.hpp", "vector", "optional", "chrono", "cmath",
               "cstdio", "string", "memory"]
    source = "".join(f"#include <{h}>\n" for h in headers)
    result = subprocess.run([CXX, "-std=gnu++20", "-dM", "-E", f"-I{ROOT / 'runtime' / 'include'}", "-x", "c++", "-"],
                            input=source, capture_output=True, text=True, check=True)
    defined = {line.split()[1].split("(")[0] for line in result.stdout.splitlines() if line.startswith("#define ")}
    visible = {name for name in defined if not name.startswith("_")}
    listed_path = ROOT / "generator" / "horus_gen" / "lang" / "cpp_macros.txt"
    listed = set(listed_path.read_text().split())
    if os.environ.get("HORUS_UPDATE_GOLDEN"):
        listed_path.write_text("\n".join(sorted(listed | visible)) + "\n")
        listed |= visible
    assert not visible - listed, f"macros generated code would not avoid: {sorted(visible - listed)[:20]}"
