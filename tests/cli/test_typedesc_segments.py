"""horus.typedesc on what a live segment stores: classes made from the type description the
segment carries, and from its schema text alone (compiled in process), for a standard type and a
user type this process never imported, POD and serialized."""
from __future__ import annotations

import sys

import pytest

from horus import typedesc

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


def _classes(segment: dict) -> list[type]:
    """The segment's type made from the description it carries and from its schema text alone."""
    carried = typedesc.message_class(segment["description"])
    compiled = typedesc.load_type(segment["type_name"], segment["schema"], segment["fingerprint"])
    for cls in (carried, compiled):
        assert (cls.__horus__.name, cls.__horus__.fingerprint) == \
            (segment["type_name"], segment["fingerprint"])
    return [carried, compiled]


def test_user_types_decode_and_encode_from_what_the_segment_stores(children, user_types):
    child = children.python(PUBLISH_USER_TYPES.format(python=user_types))
    pose_hex, route_hex = child.stdout.readline().split()
    assert "cli_user" not in sys.modules

    pose_segment = _segment("pose")
    assert pose_segment["description"], "a generated type's segment carries its description"
    for pose_cls in _classes(pose_segment):
        assert pose_cls.__horus__.is_pod and pose_cls.__horus__.size == 48
        received = _latest(pose_segment, pose_cls)
        assert received.hex() == pose_hex
        # An enum shows as its member's name, and is taken by it.
        assert typedesc.decode(pose_cls, received) == POSE_PLAIN
        assert typedesc.encode(pose_cls, POSE_PLAIN).hex() == pose_hex

    route_segment = _segment("route")
    assert not route_segment["is_pod"]
    for route_cls in _classes(route_segment):
        route = typedesc.decode(route_cls, _latest(route_segment, route_cls))
        # Vec of a nested POD message, Option, a message of another package.
        assert route["name"] == "to dock" and route["speed"] == 0.25
        assert route["poses"][0] == POSE_PLAIN and route["poses"][1]["gear"] == "Park"
        assert route["accel"]["linear"] == [0.5, 0.0, 0.0]
        assert typedesc.encode(route_cls, route).hex() == route_hex
        assert typedesc.decode(route_cls, typedesc.encode(route_cls, {**route, "speed": None}))["speed"] is None
    # Loading the text twice gives the same class; nothing made a cli_user module.
    assert typedesc.load_type(route_segment["type_name"], route_segment["schema"],
                              route_segment["fingerprint"]) is _classes(route_segment)[1]
    assert "cli_user" not in sys.modules


def test_a_standard_type_loads_beside_the_installed_package_without_replacing_it():
    import horus.msg
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    loaded = typedesc.load_type(info.name, info.schema, info.fingerprint)
    assert loaded is not CmdVel and sys.modules["horus.msg"] is horus.msg
    assert horus.msg.CmdVel is CmdVel
    assert typedesc.encode(loaded, {"linear": 1.0, "angular": -0.5}) == \
        CmdVel(linear=1.0, angular=-0.5).to_bytes()
    # An f32 shows as the shortest decimal that reads back as the same f32.
    shown = typedesc.decode(loaded, CmdVel(angular=0.1).to_bytes())
    assert shown["angular"] == 0.1
    assert typedesc.from_plain(loaded, shown).angular == CmdVel(angular=0.1).angular


def test_values_that_do_not_fit_are_one_clear_error_naming_the_field():
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    cls = typedesc.load_type(info.name, info.schema, info.fingerprint)
    for value, expected in (({"linear": "fast"}, "field 'linear'"),
                            ({"speed": 1.0}, "no field 'speed' (fields: stamp_nanos, linear, angular)"),
                            ({"stamp_nanos": -1}, "out of range"),
                            ([1, 2], "expected a mapping")):
        with pytest.raises(ValueError) as raised:
            typedesc.from_plain(cls, value)
        assert expected in str(raised.value) and "\n" not in str(raised.value)


def test_an_enum_value_that_is_not_a_member_names_the_members(user_types):
    sys.path.insert(0, user_types)
    try:
        from cli_user import Pose
    finally:
        sys.path.remove(user_types)
        sys.modules.pop("cli_user", None)
    cls = typedesc.message_class(Pose.__horus__.description)
    with pytest.raises(ValueError, match=r"cli_user\.Pose\.gear: 'Reverse' is not a value of "
                                         r"cli_user\.Gear \(Park, Drive\)"):
        typedesc.from_plain(cls, {"gear": "Reverse"})


def test_a_schema_that_does_not_give_the_fingerprint_or_compile_is_refused():
    from horus.msg import CmdVel
    info = CmdVel.__horus__
    with pytest.raises(typedesc.SchemaError, match="gives fingerprint"):
        typedesc.load_type(info.name, info.schema, info.fingerprint ^ 1)
    for name, text in ((info.name, "struct Foo {}"), ("a.B", "message a.B {\n  x: f33,\n}\n")):
        with pytest.raises(typedesc.SchemaError, match="does not compile") as raised:
            typedesc.load_type(name, text, 1)
        assert "\n" not in str(raised.value)
