"""The type descriptions of service frames and registrations: what the topic segments of a C++
server and client carry (built from the payload's description, runtime/src/service/
frame_description.cpp) is the tree horus.typedesc derives for the same type, from the payload's
description (`service_frame`) and from the stored schema text alone (`load_type`, what a
recording's reader has): same entries, same fingerprint, same bytes."""
from __future__ import annotations

import os
import subprocess

import msgpack
import pytest

from horus import introspection, typedesc
from pyrt_test import AddRequest, AddResponse, EchoRequest, EchoResponse

SERVICE_PEER = os.environ.get("HORUS_PY_SERVICE_PEER", "")
PAYLOADS = {t.__horus__.name: t for t in (AddRequest, AddResponse, EchoRequest, EchoResponse)}


@pytest.fixture
def cpp_server():
    assert SERVICE_PEER, "HORUS_PY_SERVICE_PEER names the C++ service peer (run through ctest)"
    proc = subprocess.Popen([SERVICE_PEER, "serve"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "serving"
    yield proc
    proc.stdin.close()
    assert proc.wait(timeout=30) == 0


def _service_topics() -> list[dict]:
    return [t for t in introspection.list_topics() if t["type_name"].startswith("horus.Service")]


def test_cpp_frames_are_described_as_typedesc_describes_them(cpp_server):
    # A C++ client too: every frame topic is made by C++ typed code.
    called = subprocess.run([SERVICE_PEER, "call", "2", "3", "ab"], capture_output=True, text=True,
                            timeout=30)
    assert called.stdout.strip() == "5 abab", called.stdout + called.stderr
    frames = [t for t in _service_topics() if t["type_name"] != "horus.ServiceRegistration"]
    # Both services' request topics and a reply topic of each.
    assert len({t["type_name"] for t in frames}) == 4, [t["name"] for t in frames]
    for topic in frames:
        name = topic["type_name"]
        carried = topic["description"]
        assert carried, f"{topic['name']} ({name}) carries no type description"
        tree = msgpack.unpackb(carried)
        assert tree["root"] == name
        assert int(tree["types"][-1]["fingerprint"], 16) == topic["fingerprint"]
        assert tree["types"][-1]["schema"] == topic["schema"]

        payload = PAYLOADS[name.split("<", 1)[1][:-1]]
        derived = typedesc.service_frame(payload.__horus__.description, name.startswith("horus.ServiceResponse"))
        assert derived == tree, f"typedesc.service_frame differs from the runtime's description of {name}"
        assert msgpack.packb(derived) == carried, f"the bytes of {name}'s description differ"

        loaded = typedesc.load_type(name, topic["schema"], topic["fingerprint"])
        assert msgpack.unpackb(loaded.__horus__.description) == tree, \
            f"load_type's description of {name} (from its schema text) differs from the runtime's"
        assert loaded.__horus__.fingerprint == topic["fingerprint"]


def test_the_registration_is_described_as_typedesc_describes_it(cpp_server):
    registrations = [t for t in _service_topics() if t["type_name"] == "horus.ServiceRegistration"]
    assert registrations
    for topic in registrations:
        tree = msgpack.unpackb(topic["description"])
        loaded = typedesc.load_type(topic["type_name"], topic["schema"], topic["fingerprint"])
        assert msgpack.unpackb(loaded.__horus__.description) == tree
        assert loaded.__horus__.fingerprint == topic["fingerprint"] == int(tree["types"][-1]["fingerprint"], 16)
