"""Plain values across languages: a Python float, int, bool, str, bytes, numpy array or list on
the topic a C++ Topic<double>, Topic<std::int64_t>, Topic<bool>, Topic<std::string>,
Topic<std::vector<std::uint8_t>>, Topic<std::array<float, 3>> or Topic<std::vector<float>> uses:
the same identity, the same bytes, the same log summaries, both ways, between real processes."""
from __future__ import annotations

import math
import os
import subprocess

import numpy
import pytest

import horus

VALUE_PEER = os.environ.get("HORUS_PY_VALUE_PEER", "")

# kind (value_peer.cpp) -> (how Python declares it, the name both sides give it, the samples
# value_peer.cpp sends: the same lists)
CASES = {
    "f64": (float, "f64", [0.0, -1.5, 3.141592653589793, 1e300, -0.0]),
    "i64": (int, "i64", [0, -1, 2**63 - 1, -2**63]),
    "bool": (bool, "bool", [True, False]),
    "string": (str, "String", ["", "hello", "grüß dich", "x" * 40]),
    "bytes": (bytes, "Vec<u8>", [b"", b"\x00\xff\x10", b"\xab" * 300]),
    "f32x3": (numpy.dtype((numpy.float32, 3)), "[f32; 3]",
              [numpy.array([1.0, 2.5, -3.25], numpy.float32), numpy.zeros(3, numpy.float32)]),
    "vec_f32": ("Vec<f32>", "Vec<f32>",
                [[], [1.0, 2.5], [0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5]]),
}


@pytest.fixture
def value_peer():
    """Runs tests/python/runtime/value_peer.cpp, built beside this suite."""
    assert VALUE_PEER, "HORUS_PY_VALUE_PEER names the C++ peer; run this suite through ctest"

    def start(*args: str) -> subprocess.Popen:
        return subprocess.Popen([VALUE_PEER, *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    return start


def _finished(proc: subprocess.Popen) -> list[tuple[str, str]]:
    """(hex of the bytes, log summary) of each value the peer printed, once it exited with 0."""
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    return [tuple(line.split("\t", 1)) for line in out.splitlines()]


def _same(kind: str, got, expected) -> bool:
    if kind == "f32x3":
        return len(got) == len(expected) and all(
            isinstance(g, numpy.ndarray) and g.dtype == numpy.float32 and numpy.array_equal(g, e)
            for g, e in zip(got, expected))
    if kind == "f64":
        return [(g, math.copysign(1.0, g)) for g in got] == [(e, math.copysign(1.0, e)) for e in expected]
    return got == expected and [type(g) for g in got] == [type(e) for e in expected]


@pytest.mark.parametrize("kind", CASES)
def test_both_languages_give_a_plain_value_the_same_identity(value_peer, kind):
    spec, name, _ = CASES[kind]
    value_type = horus.plain_value(spec)
    out, err = value_peer("identity", kind).communicate(timeout=30)
    assert out.split("\n", 2) == [name, f"{value_type.fingerprint:016x}", f"value {name}\n"], err
    assert (value_type.name, value_type.schema) == (name, f"value {name}\n")


@pytest.mark.parametrize("kind", CASES)
def test_cpp_publishes_and_python_reads_equal_values_and_bytes(value_peer, kind):
    spec, name, expected = CASES[kind]
    sub = horus.Topic(spec, "values")
    wire = horus.Topic(spec, "values")  # a second handle, read raw: the bytes C++ put on the topic
    printed = _finished(value_peer("pub", kind, "values"))
    got = [sub.recv(timeout=10.0) for _ in expected]
    assert _same(kind, got, expected), f"sent {expected}, read {got}"
    sent_bytes = [wire._core.try_recv().hex() for _ in expected]
    assert sent_bytes == [hex_bytes for hex_bytes, _ in printed]
    assert [sub.type.to_bytes(value).hex() for value in expected] == sent_bytes
    assert [sub.type.log_summary(value) for value in got] == [summary for _, summary in printed]
    assert sub.try_recv() is None and sub.type.name == name


@pytest.mark.parametrize("kind", CASES)
def test_python_publishes_and_cpp_reads_equal_values_and_bytes(value_peer, kind):
    spec, _, expected = CASES[kind]
    proc = value_peer("sub", kind, "values", str(len(expected)))
    assert proc.stdout.readline().strip() == "ready"
    pub = horus.Topic(spec, "values")
    wire = horus.Topic(spec, "values")
    for value in expected:
        assert pub.send(value)
    printed = _finished(proc)
    # What C++ read, encoded again by C++, is byte for byte what Python put on the topic.
    assert [hex_bytes for hex_bytes, _ in printed] == [wire._core.try_recv().hex() for _ in expected]
    assert [summary for _, summary in printed] == [pub.type.log_summary(v) for v in expected]


def test_a_python_float_is_refused_on_a_cpp_int32_topic_naming_both_types(value_peer):
    holder = value_peer("hold", "i32", "level")
    assert holder.stdout.readline().strip() == "ready"
    with pytest.raises(horus.HorusError) as raised:
        horus.Topic(float, "level")
    text = str(raised.value)
    i32, f64 = horus.plain_value("i32"), horus.plain_value(float)
    assert f"carries i32 (fingerprint 0x{i32.fingerprint:016x})" in text, text
    assert f"cannot open it as f64 (fingerprint 0x{f64.fingerprint:016x})" in text, text
    holder.stdin.close()
    assert holder.wait(timeout=30) == 0


def test_a_cpp_int32_is_refused_on_a_python_float_topic_naming_both_types(value_peer):
    incumbent = horus.Topic(float, "level")
    refused = value_peer("hold", "i32", "level")
    out, _ = refused.communicate(timeout=30)
    assert refused.returncode == 1, out
    assert "carries f64 (fingerprint 0x" in out and "cannot open it as i32 (fingerprint 0x" in out
    assert incumbent.send(2.5)


def test_a_node_declares_a_plain_value_by_its_python_type(value_peer):
    got = []
    reader = horus.Node(name="reader", subs={"values": float},
                        tick=lambda node: got.append(node.recv("values")))
    with horus.Scheduler() as sched:
        sched.add(reader)
        sched.tick_once()  # opens the topic as f64
        _finished(value_peer("pub", "f64", "values"))
        for _ in CASES["f64"][2]:
            sched.tick_once()
        assert [t["type_name"] for t in horus._core.list_topics() if t["name"] == "values"] == ["f64"]
    assert _same("f64", got[1:], CASES["f64"][2])


def test_a_node_that_takes_a_plain_value_topic_for_dicts_is_told_how_to_declare_it(value_peer):
    holder = value_peer("hold", "f64", "speed")
    assert holder.stdout.readline().strip() == "ready"
    node = horus.Node(name="reader", subs=["speed"])
    with pytest.raises(horus.HorusError, match=r"declare subs=\{'speed': float\}"):
        node.open_topics()
    holder.stdin.close()
    assert holder.wait(timeout=30) == 0


def test_python_types_map_to_one_schema_type_each():
    spelled = {spec: horus.plain_value(spec).name for spec in (
        float, int, bool, str, bytes, numpy.float32, numpy.uint16, numpy.dtype((numpy.uint8, (2, 4))),
        "Vec<[f32; 3]>", "Vec<String>")}
    assert list(spelled.values()) == ["f64", "i64", "bool", "String", "Vec<u8>", "f32", "u16",
                                      "[[u8; 4]; 2]", "Vec<[f32; 3]>", "Vec<String>"]
    assert horus.plain_value("[[u8; 4]; 2]").size == 8
    with pytest.raises(ValueError, match="not a plain value type: 'f33'"):
        horus.plain_value("f33")
    with pytest.raises(ValueError, match="fixed size"):
        horus.plain_value("[String; 2]")


def test_a_value_of_another_type_is_refused_naming_the_topic_and_its_type():
    counts = horus.Topic(int, "counts")
    with pytest.raises(ValueError, match="topic 'counts' carries i64: expected an integer, got str"):
        counts.send("3")
    with pytest.raises(ValueError, match="out of range for i64"):
        counts.send(2**63)
    position = horus.Topic("[f32; 3]", "position")
    with pytest.raises(ValueError, match=r"carries \[f32; 3\]: expected an array of shape \(3,\)"):
        position.send([1.0, 2.0])
    with pytest.raises(TypeError, match="plain value"):
        position.loan()
    assert counts.try_recv() is None and position.try_recv() is None
