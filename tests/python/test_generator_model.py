"""The resolver's model: names, tiers, layout, padding, identity, summaries."""
from __future__ import annotations

from pathlib import Path

import pytest

from generator_testing import SCHEMAS
from horus_gen.diagnostics import Reporter
from horus_gen.model import EnumValue, FixedArray, FixedString, Message, MessageRef, Padding
from horus_gen.loader import Options
from horus_gen.resolve import Resolver


def resolve(tmp_path: Path, text: str, name: str = "schema.hmsg", package: str | None = None, includes=()):
    path = tmp_path / name
    path.write_text(text)
    reporter = Reporter()
    model = Resolver(reporter, Options(list(includes), package)).run([str(path)])
    return model, reporter


def ok(tmp_path, text, **kw):
    model, reporter = resolve(tmp_path, text, **kw)
    assert not reporter.has_errors, reporter.render()
    return model


def test_layout_follows_cpp_rules(tmp_path):
    model = ok(tmp_path, "package p; M { a: u8, b: u64, c: u16, d: [u8; 3] }")
    m = model.message("p.M")
    assert [f.offset for f in m.fields] == [0, 8, 16, 18]
    assert (m.size, m.alignment) == (24, 8)
    assert m.padding == (Padding(1, 7), Padding(21, 3))


def test_empty_message_has_size_one_like_cpp_and_that_byte_is_padding(tmp_path):
    # No field writes the byte, so C++ holds whatever was in memory: encode must zero it.
    m = ok(tmp_path, "package p; E {}").message("p.E")
    assert (m.size, m.alignment, m.padding) == (1, 1, (Padding(0, 1),))


def test_padding_inside_nested_arrays_is_repeated(tmp_path):
    m = ok(tmp_path, "package p; In { a: u32, b: u8 } Out { items: [In; 3] }").message("p.Out")
    assert m.size == 24
    assert m.padding == (Padding(5, 3), Padding(13, 3), Padding(21, 3))


def test_string_n_is_inline_and_byte_aligned(tmp_path):
    m = ok(tmp_path, "package p; S { flag: u8, name: string<5>, x: f32 }").message("p.S")
    assert [f.offset for f in m.fields] == [0, 1, 8]
    assert isinstance(m.fields[1].type, FixedString)
    assert m.is_pod


def test_any_serialized_field_makes_the_message_serialized(tmp_path):
    model = ok(tmp_path, "package p; Inner { s: String } Outer { n: u32, inner: Inner } Pod { n: u32 }")
    assert not model.message("p.Inner").is_pod
    assert not model.message("p.Outer").is_pod
    assert model.message("p.Outer").size is None
    assert model.message("p.Pod").is_pod


def test_fingerprint_ignores_spelling_comments_defaults_and_attributes(tmp_path):
    a = ok(tmp_path, "package p; M { a: [u8;32], b: f32 }").message("p.M")
    b = ok(tmp_path, """package p;
        /// docs
        #[topic = "t"]
        M {
            // comment
            a: [ u8 ; 32 ],
            #[unit = "m"]
            b: f32 = 1.5,
            const K: u8 = 3,
        }""").message("p.M")
    assert a.fingerprint == b.fingerprint
    assert a.schema == b.schema


@pytest.mark.parametrize("changed", [
    "package p; M { a: [u8; 31], b: f32 }",
    "package p; M { a: [u8; 32], c: f32 }",
    "package p; M { a: [u8; 32], b: f64 }",
    "package p; M { b: f32, a: [u8; 32] }",
    "package q; M { a: [u8; 32], b: f32 }",
])
def test_fingerprint_changes_with_the_wire_contract(tmp_path, changed):
    base = ok(tmp_path, "package p; M { a: [u8; 32], b: f32 }").message("p.M")
    model = ok(tmp_path, changed)
    other = next(t for t in model.types.values() if isinstance(t, Message))
    assert other.fingerprint != base.fingerprint


def test_nested_change_changes_the_outer_fingerprint(tmp_path):
    one = ok(tmp_path, "package p; In { a: u32 } Out { i: In }").message("p.Out")
    two = ok(tmp_path, "package p; In { a: u64 } Out { i: In }").message("p.Out")
    assert one.fingerprint != two.fingerprint
    enum_one = ok(tmp_path, "package p; enum E: u8 { A = 0 } Out { e: E }").message("p.Out")
    enum_two = ok(tmp_path, "package p; enum E: u8 { A = 1 } Out { e: E }").message("p.Out")
    assert enum_one.fingerprint != enum_two.fingerprint


def test_schema_text_carries_every_nested_definition_once(tmp_path):
    m = ok(tmp_path, "package p; enum E: u8 { A = 0 } In { e: E } Out { a: In, b: [In; 2], e: E }").message("p.Out")
    assert m.schema.count("message p.In {") == 1
    assert m.schema.count("enum p.E: u8 {") == 1
    assert m.schema.startswith("message p.Out {\n  a: p.In,\n  b: [p.In; 2],\n  e: p.E,\n}\n")


def test_defaults_and_constants_are_typed_values(tmp_path):
    model = ok(tmp_path, """package p;
        enum Mode: u8 { Idle = 0, Run = 5 }
        M { const K: i64 = -9223372036854775808, mode: Mode = Mode::Run, g: [f64; 2] = [1, -0.5], s: string<3> = "abc" }""")
    m = model.message("p.M")
    assert m.constants[0].value == -(1 << 63)
    assert m.fields[0].default == EnumValue("p.Mode", "Run", 5)
    assert m.fields[1].default == (1.0, -0.5)
    assert m.fields[2].default == "abc"


def test_default_summary_names_every_field_with_units(tmp_path):
    m = ok(tmp_path, 'package p; M { #[unit = "m"] x: f32, r: [f32; 9] }').message("p.M")
    texts = [(p.text, p.field, p.label, p.unit) for p in m.summary]
    assert texts == [("M{x: ", None, "", ""), ("", "x", "", "m"), (", r: ", None, "", ""),
                     ("", "r", "f32", ""), ("}", None, "", "")]


def test_custom_summary_template(tmp_path):
    m = ok(tmp_path, 'package p; #[summary = "id {a} {{raw}}"] M { a: u8 }').message("p.M")
    assert [(p.text, p.field) for p in m.summary] == [("id ", None), ("", "a"), (" {raw}", None)]


def test_upstream_macro_files_compile_unchanged(tmp_path):
    model = ok(tmp_path, """
        message! {
            /// Feedback.
            pub struct MotorFeedback {
                pub motor_id: u32,
                pub velocity: f32,
            }
        }
        message! { MotorFeedback2 { timestamp_ns: u64, motor_id: u32, } }
        """, package="upstream")
    assert [f.name for f in model.message("upstream.MotorFeedback").fields] == ["motor_id", "velocity"]
    assert model.message("upstream.MotorFeedback").docs == ("Feedback.",)
    assert "upstream.MotorFeedback2" in model.types


def test_package_defaults_to_folder_name_then_option(tmp_path):
    folder = tmp_path / "robot_msgs"
    folder.mkdir()
    assert "robot_msgs.M" in ok(folder, "M { a: u8 }").types
    assert "given.pkg.M" in ok(folder, "M { a: u8 }", package="given.pkg").types


def test_qualified_names_resolve_through_include_dirs_without_import(tmp_path):
    model = ok(tmp_path, "package q; Uses { s: other_pkg::Stamp }", includes=[str(SCHEMAS)])
    uses = model.message("q.Uses")
    assert uses.fields[0].type == MessageRef("other_pkg.Stamp")
    assert model.generated == ["q.Uses"]


def test_services_yield_request_response_and_service(tmp_path):
    model = ok(tmp_path, "package p; S { request { a: u8 } response { b: String } }", name="s.hsrv")
    assert model.generated == ["p.SRequest", "p.SResponse", "p.S"]
    service = model.services["p.S"]
    assert service.request_topic == "S.request" and service.response_topic == "S.response"
    assert service.request.is_pod and not service.response.is_pod
    assert service.request.service == "p.S"


def test_nested_arrays(tmp_path):
    f = ok(tmp_path, "package p; M { g: [[u8; 4]; 3] }").message("p.M").fields[0]
    assert f.type == FixedArray(FixedArray(f.type.element.element, 4), 3)
    assert f.spelling == "[[u8; 4]; 3]" and f.size == 12


def test_all_errors_are_reported_in_one_run(tmp_path):
    _, reporter = resolve(tmp_path, "package p; A { x: f63 } B { y: [u8; 0] } C { z: string<0> }")
    assert len(reporter.diagnostics) == 3


def test_same_package_types_in_sibling_files_resolve_without_import(tmp_path):
    (tmp_path / "point.hmsg").write_text("package p; Point { x: f64 }")
    model = ok(tmp_path, "package p; Path { points: [Point; 4] }")
    assert model.message("p.Path").size == 32
    assert model.generated == ["p.Path"], "a sibling used by name is a dependency, not an output"


def test_errors_in_a_package_found_through_include_dirs_are_reported(tmp_path):
    lib = tmp_path / "inc" / "lib"
    lib.mkdir(parents=True)
    (lib / "things.hmsg").write_text("package lib;\nThing { b: f63 }\n")
    _, reporter = resolve(tmp_path, "package app; Uses { t: lib::Thing }", includes=[str(tmp_path / "inc")])
    assert [d.message for d in reporter.diagnostics] == ["unknown type 'f63'"]
    assert reporter.diagnostics[0].span.source.path.endswith("things.hmsg")


def test_package_option_applies_only_to_the_files_being_compiled(tmp_path):
    lib = tmp_path / "inc" / "lib"
    lib.mkdir(parents=True)
    (lib / "things.hmsg").write_text("Thing { a: u8 }\n")
    model = ok(tmp_path, "Uses { t: lib::Thing }", package="app", includes=[str(tmp_path / "inc")])
    assert "lib.Thing" in model.types and "app.Uses" in model.types
