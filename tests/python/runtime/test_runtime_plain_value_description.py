"""The type description a plain value carries (runtime/include/horus/plain_value.hpp,
horus/_values.py): the message `PlainValue { value: <name> }` its bytes are, named and fingerprinted
as the plain value, the same bytes from C++ and Python, so `horus topic echo` and the other
consumers of a segment's description read a plain-value topic as they read a message topic."""
from __future__ import annotations

import json
import os
import subprocess

import numpy
import pytest

import horus
from horus import typedesc

VALUE_PEER = os.environ.get("HORUS_PY_VALUE_PEER", "")
HORUS_CLI = os.path.join(os.environ.get("HORUS_BUILD_DIR", ""), "bin", "horus")

# kind (value_peer.cpp) -> the plain value type Python declares for it
KINDS = {"f64": float, "i64": int, "i32": "i32", "bool": bool, "string": str, "bytes": bytes,
         "f32x3": numpy.dtype((numpy.float32, 3)), "vec_f32": "Vec<f32>"}


@pytest.fixture
def held():
    """Opens a topic of a kind in the C++ peer (value_peer.cpp `hold`), which creates its
    segment, until the test ends."""
    assert VALUE_PEER, "HORUS_PY_VALUE_PEER names the C++ peer; run this suite through ctest"
    peers = []

    def hold(kind: str, topic: str) -> None:
        peer = subprocess.Popen([VALUE_PEER, "hold", kind, topic], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        peers.append(peer)
        assert peer.stdout.readline() == "ready\n", peer.communicate(timeout=10)
    yield hold
    for peer in peers:
        peer.communicate(timeout=10)
        assert peer.returncode == 0


def _stored_description(namespace: str, topic: str) -> bytes:
    (info,) = [t for t in horus._core.list_topics(namespace) if t["name"] == topic]
    return info["description"]


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_a_cpp_segment_stores_the_description_python_gives_the_same_plain_value(held, namespace,
                                                                                 kind):
    held(kind, "values")
    python = horus.plain_value(KINDS[kind])
    stored = _stored_description(namespace, "values")
    assert stored == python.description
    cls = typedesc.message_class(stored)
    info = cls.__horus__
    assert (info.name, info.fingerprint, info.schema, info.is_pod) == \
        (python.name, python.fingerprint, python.schema, python.is_pod)
    if python.is_pod:
        assert (info.size, info.alignment) == (python.size, python.alignment)


@pytest.mark.parametrize("name", ["bool", "u16", "f32", "[f32; 3]", "[[u8; 4]; 2]", "String",
                                  "Vec<u8>", "Vec<String>", "Vec<[f32; 3]>", "Vec<Vec<i16>>"])
def test_the_described_message_reads_and_writes_the_plain_values_bytes(name):
    plain = horus.plain_value(name)
    cls = typedesc.message_class(plain.description)
    zero = cls().to_bytes()
    value = plain.from_bytes(zero)
    assert plain.to_bytes(value) == zero
    assert cls.from_bytes(zero).log_summary() == plain.log_summary(value)
    assert typedesc.parse(plain.description)["types"][0]["fields"][0]["spelling"] == name


def test_echo_reads_a_plain_value_topic_from_its_segments_description(held, namespace):
    held("f32x3", "pose")
    topic = horus.Topic(numpy.dtype((numpy.float32, 3)), "pose")
    topic.send(numpy.array([1.0, 2.5, -3.25], numpy.float32))
    echo = subprocess.run([HORUS_CLI, "topic", "echo", "pose", "--once", "--json", "--timeout", "10"],
                          capture_output=True, text=True, timeout=30)
    assert echo.returncode == 0, echo.stderr
    assert json.loads(echo.stdout) == {"value": [1.0, 2.5, -3.25]}
    del topic


def test_stored_schema_text_alone_gives_the_plain_values_described_class():
    """A consumer holding only a plain value's stored schema text (load_type) makes the class its
    description makes, and refuses text of another plain value or a type that is none."""
    plain = horus.plain_value("[[u8; 4]; 2]")
    cls = typedesc.load_type(plain.name, plain.schema, plain.fingerprint)
    assert cls.__horus__.description == plain.description
    with pytest.raises(typedesc.SchemaError, match="describes f64, not f32"):
        typedesc.load_type("f32", "value f64\n", None)
    with pytest.raises(typedesc.SchemaError, match="not a plain value type"):
        typedesc.load_type("Vec<x>", "value Vec<x>\n", None)
