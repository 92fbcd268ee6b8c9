"""tools/horus/dynamic_types.py: classes compiled from the schema text a live segment stores,
for a standard type and a user type this process never imported, POD and serialized."""
from __future__ import annotations

import os
import sys

import pytest


sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "tools", "horus"))
import dynamic_types  # noqa: E402

PUBLISH_USER_TYPES = """
import sys, time
sys.path.insert(0, {python!r})
import horus
from horus.msg import Accel
from cli_user import Gear, Pose, Route
pose = Pose(gear=Gear.Drive, x=1.5, label="dock", corners=[[1, 2], [3, 4]])
route = Route(name="to dock", poses=[pose, Pose(x=-2.0)], speed=0.25,
              accel=Accel(linear=[0.5, 0, 0]))
poses, routes = horus.Topic(Pose, "pose"), horus.Topic(Route, "route")
poses.send(pose)
routes.send(route)
print(pose.to_bytes().hex(), route.to_bytes().hex(), flush=True)
while True:
    time.sleep(1)
"""

POSE_PLAIN = {"gear": "Drive", "x": 1.5, "label": "dock", "corners": [[1.0, 2.0], [3.0, 4.0]]}


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """A cold cache per test: every test compiles what it loads."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    dynamic_types._loaded.clear()


def _segment(name: str):
    from horus import _core
    return next(t for t in _core.list_topics("") if t["name"] == name)


def _latest(topic: dict, cls) -> bytes:
    from horus import _core
    info = cls.__horus__
    handle = _core.Topic(topic["name"], topic["type_name"], topic["fingerprint"], topic["schema"],
                         topic["is_pod"], info.size if info.is_pod else 0,
                         info.alignment if info.is_pod else 1, 64, 16 * 1024, False)
    return handle.read_latest()


def test_user_types_decode_and_encode_from_the_stored_schema_alone(children, user_types):
    child = children.python(PUBLISH_USER_TYPES.format(python=user_types))
    pose_hex, route_hex = child.stdout.readline().split()
    assert "cli_user" not in sys.modules

    pose_segment = _segment("pose")
    pose_cls = dynamic_types.load_type(pose_segment["type_name"], pose_segment["schema"],
                                       pose_segment["fingerprint"])
    assert pose_cls.__horus__.is_pod and pose_cls.__horus__.size == 48
    received = _latest(pose_segment, pose_cls)
    assert received.hex() == pose_hex
    assert dynamic_types.to_plain(pose_cls.from_bytes(received)) == POSE_PLAIN
    assert dynamic_types.from_plain(pose_cls, POSE_PLAIN).to_bytes().hex() == pose_hex

    route_segment = _segment("route")
    assert not route_segment["is_pod"]
    route_cls = dynamic_types.load_type(route_segment["type_name"], route_segment["schema"],
                                        route_segment["fingerprint"])
    route = dynamic_types.to_plain(route_cls.from_bytes(_latest(route_segment, route_cls)))
    assert route["name"] == "to dock" and route["speed"] == 0.25
    assert route["poses"][0] == POSE_PLAIN and route["poses"][1]["gear"] == "Park"
    assert route["accel"]["linear"] == [0.5, 0.0, 0.0]
    assert dynamic_types.from_plain(route_cls, route).to_bytes().hex() == route_hex
    # Loading twice gives the same class; the private import left no cli_user module behind.
    assert dynamic_types.load_type(route_segment["type_name"], route_segment["schema"],
                                   route_segment["fingerprint"]) is route_cls
    assert "cli_user" not in sys.modules


def test_a_standard_type_loads_beside_the_installed_package_without_replacing_it():
    import horus.msg
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    loaded = dynamic_types.load_type(info.name, info.schema, info.fingerprint)
    assert loaded is not CmdVel and sys.modules["horus.msg"] is horus.msg
    assert horus.msg.CmdVel is CmdVel
    message = dynamic_types.from_plain(loaded, {"linear": 1.0, "angular": -0.5})
    assert message.to_bytes() == CmdVel(linear=1.0, angular=-0.5).to_bytes()
    # An f32 shows as the shortest decimal that reads back as the same f32.
    shown = dynamic_types.to_plain(loaded.from_bytes(CmdVel(angular=0.1).to_bytes()))
    assert shown["angular"] == 0.1 and dynamic_types.from_plain(loaded, shown).angular == CmdVel(angular=0.1).angular


def test_values_that_do_not_fit_are_one_clear_error():
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    cls = dynamic_types.load_type(info.name, info.schema, info.fingerprint)
    for value, expected in (({"linear": "fast"}, "field 'linear'"),
                            ({"speed": 1.0}, "no field 'speed' (fields: stamp_nanos, linear, angular)"),
                            ({"stamp_nanos": -1}, "out of range"),
                            ([1, 2], "expected a mapping")):
        with pytest.raises(ValueError, match=None) as raised:
            dynamic_types.from_plain(cls, value)
        assert expected in str(raised.value) and "\n" not in str(raised.value)


def test_a_schema_that_does_not_give_the_fingerprint_is_refused():
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    with pytest.raises(dynamic_types.SchemaError, match="gives fingerprint"):
        dynamic_types.load_type(info.name, info.schema, info.fingerprint ^ 1)
    with pytest.raises(dynamic_types.SchemaError, match="unexpected schema line"):
        dynamic_types.load_type(info.name, "struct Foo {}", 1)
    with pytest.raises(dynamic_types.SchemaError, match="does not compile"):
        dynamic_types.load_type("a.B", "message a.B {\n  x: f33,\n}\n", 1)


def test_a_type_cache_others_can_write_is_refused(tmp_path):
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    root = tmp_path / "cache" / "horus" / "types"
    root.mkdir(parents=True)
    root.chmod(0o777)
    with pytest.raises(dynamic_types.SchemaError, match="not this user's alone"):
        dynamic_types.load_type(info.name, info.schema, info.fingerprint)
