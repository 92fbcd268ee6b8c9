"""The live view's codecs (bridges/view/codecs.hpp) read by readers that are not ours, for every
standard type and every test schema type: through view_codec_tool, each type's channel schema and
the payload of a message with every field filled.

- Both homes of the "which Foxglove schema" rule agree: the live view gives each type the schema
  the recording export gives it (horus.foxglove.foxglove_mapping, a pool-backed descriptor with its
  data).
- A type shown as its plain values: the channel's JSON Schema is what `horus-gen --lang
  jsonschema` writes (descriptions aside: the type description has no doc comments) with u64 and
  i64 as strings, and exactly the export's; the payload validates (python3-jsonschema), equals the
  export's JSON, and a viewer's copy of it decodes back to the same frame.
- Foxglove's JSON schemas (LaserScan, PoseInFrame, PosesInFrame, FrameTransform): the export's
  schema and values, and a viewer's message back to the HORUS type (a laser scan refused).
- Foxglove's protobuf schemas: the FileDescriptorSet loads into a fresh python3-protobuf descriptor
  pool, its field numbers are Foxglove's, and the payloads decode to the export's values: a 640x480
  rgb8 image and a point cloud checked value by value.
"""
from __future__ import annotations

import base64
import json
import math
import os
import struct
import subprocess
from pathlib import Path

import jsonschema
import msgpack
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from horus import foxglove, typedesc

ROOT = Path(__file__).resolve().parents[2]
STANDARD = ROOT / "schemas"
TEST_SCHEMAS = ROOT / "tests" / "schemas"
TOOL = os.environ.get("HORUS_VIEW_CODEC_TOOL", "")
GENERATOR = os.environ.get("HORUS_GEN_PROGRAM", "")

# The descriptors of the pool-backed types: their frames carry the block's data after them.
POOL_DESCRIPTORS = {"horus.msg.ImageDescriptor", "horus.msg.DepthImageDescriptor",
                    "horus.msg.PointCloudDescriptor", "horus.msg.TensorDescriptor"}
POOL_DATA = bytes(range(256)) * 3


def schema_files(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.iterdir() if p.suffix in (".hmsg", ".hsrv"))


# (schema files, include folders): the standard library and the test schema types.
SCHEMA_SETS = {
    "standard": (schema_files(STANDARD / "horus" / "msg"), [str(STANDARD)]),
    "test": (schema_files(TEST_SCHEMAS / "test_msgs") + schema_files(TEST_SCHEMAS / "other_pkg")
             + schema_files(TEST_SCHEMAS / "crosslang"), [str(TEST_SCHEMAS), str(STANDARD)]),
}


@pytest.fixture(scope="module", autouse=True)
def tool():
    if not TOOL or not os.path.isfile(TOOL):
        pytest.fail("HORUS_VIEW_CODEC_TOOL does not name view_codec_tool (set by tests/view/CMakeLists.txt)")


def messages(set_name: str) -> list[tuple[str, bytes, dict]]:
    """(name, carried description bytes, describe tree) of every message of a schema set."""
    files, includes = SCHEMA_SETS[set_name]
    tree = typedesc.describe_files(files, includes)
    found = []
    for entry in tree["types"]:
        if entry["kind"] != "message":
            continue
        carried = typedesc.carried(tree, entry["name"])
        found.append((entry["name"], msgpack.packb(carried), tree))
    assert found
    return found


ALL_MESSAGES = [item for name in SCHEMA_SETS for item in messages(name)]
ENTRIES = {entry["name"]: entry for _, _, tree in ALL_MESSAGES for entry in tree["types"]}


def filled(t: dict):
    """A plain value of the described type with every field set, away from zero where it can be:
    integers past 2^53 (the strings' reason), the far ends of each range, text needing escapes."""
    kind = t["kind"]
    if kind == "primitive":
        return {"bool": True, "u8": 200, "u16": 60000, "u32": 4_000_000_000, "u64": 2**60 + 1,
                "i8": -100, "i16": -30000, "i32": -2_000_000_000, "i64": -(2**60) - 3,
                "f32": 0.1, "f64": 0.1 + 2**-40}[t["name"]]
    if kind == "string":
        return "a\"b"[:t["capacity"]] if "capacity" in t else "h\u00e9llo \"q\"\n\\"
    if kind == "bytes":
        return b"\x00\xffab"
    if kind == "array":
        return [filled(t["element"])] * t["length"]
    if kind == "vec":
        if t["element"] == {"kind": "primitive", "name": "u8"}:
            return b"\x01\x02\x03"
        return [filled(t["element"])] * 2
    if kind == "optional":
        return filled(t["element"])
    if kind == "message":
        return {f["name"]: filled(f["type"]) for f in ENTRIES[t["name"]]["fields"]}
    if kind == "enum":
        return ENTRIES[t["name"]]["values"][-1]["name"]
    raise AssertionError(f"no filled value for {kind}")


def run_tool(tmp_path: Path, topic: str, description: bytes, requests: list[tuple[str, bytes]]):
    """(channel, schema bytes, [(output bytes or None, error text or None)]) of one codec."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "description").write_bytes(description)
    arguments = []
    for index, (action, data) in enumerate(requests):
        (tmp_path / f"input{index}").write_bytes(data)
        arguments += [action, str(tmp_path / f"input{index}")]
    result = subprocess.run([TOOL, topic, str(tmp_path / "description"), str(tmp_path), *arguments],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    outputs = []
    for index in range(len(requests)):
        out, error = tmp_path / f"{index}.out", tmp_path / f"{index}.error"
        outputs.append((out.read_bytes() if out.exists() else None,
                        error.read_text() if error.exists() else None))
    channel = json.loads((tmp_path / "channel.json").read_text())
    return channel, (tmp_path / "schema").read_bytes(), outputs


def frame_of(name: str, cls, value: dict) -> bytes:
    frame = typedesc.encode(cls, value)
    return frame + POOL_DATA if name in POOL_DESCRIPTORS else frame


def plain_with_data(name: str, cls, frame: bytes) -> dict:
    """What the export decodes a frame to: a pool frame's data as the field `data`."""
    if name in POOL_DESCRIPTORS:
        size = len(cls().to_bytes())
        return {**typedesc.decode(cls, frame[:size]), "data": frame[size:]}
    return typedesc.decode(cls, frame)


def without(schema, key: str):
    if isinstance(schema, dict):
        return {k: without(v, key) for k, v in schema.items() if k != key}
    if isinstance(schema, list):
        return [without(v, key) for v in schema]
    return schema


@pytest.fixture(scope="module")
def horus_gen_schemas(tmp_path_factory) -> dict:
    """Every type's JSON Schema as `horus-gen --lang jsonschema` writes it, by title."""
    schemas = {}
    for set_name, (files, includes) in SCHEMA_SETS.items():
        out = tmp_path_factory.mktemp(f"jsonschema_{set_name}")
        include_args = [arg for folder in includes for arg in ("-I", folder)]
        subprocess.run([GENERATOR, "generate", "--lang", "jsonschema", "--out", str(out),
                        *include_args, *files], check=True)
        for path in (out / "jsonschema").rglob("*.schema.json"):
            schema = json.loads(path.read_text(encoding="utf-8"))
            schemas[schema["title"]] = schema
    return schemas


def test_every_type_gets_the_schema_the_recording_export_gives_it(tmp_path):
    checked = {"json": 0, "foxglove": 0}
    for name, description, _ in ALL_MESSAGES:
        cls = typedesc.message_class(description)
        fields = list(cls.__horus__.fields) + (["data"] if name in POOL_DESCRIPTORS else [])
        mapping = foxglove.foxglove_mapping(name, fields)
        expected = mapping[0] if mapping else name
        channel, _, _ = run_tool(tmp_path / name, "view/topic", description, [])
        assert channel["schema_name"] == expected, name
        protobuf = expected in ("foxglove.RawImage", "foxglove.CompressedImage", "foxglove.PointCloud")
        assert channel["encoding"] == ("protobuf" if protobuf else "json"), name
        assert channel["schema_encoding"] == ("protobuf" if protobuf else "jsonschema"), name
        assert channel["schema_is_binary"] == protobuf, name
        checked["foxglove" if mapping else "json"] += 1
    assert checked["json"] > 60 and checked["foxglove"] == 8, checked


def test_plain_types_have_horus_gens_schema_and_payloads_that_match_it(tmp_path, horus_gen_schemas):
    checked = 0
    for name, description, _ in ALL_MESSAGES:
        cls = typedesc.message_class(description)
        fields = list(cls.__horus__.fields) + (["data"] if name in POOL_DESCRIPTORS else [])
        if foxglove.foxglove_mapping(name, fields):
            continue
        value = filled({"kind": "message", "name": name})
        frame = frame_of(name, cls, value)
        channel, schema_bytes, [(payload, error)] = run_tool(
            tmp_path / name, "view/topic", description, [("encode", frame)])
        assert error is None, f"{name}: {error}"
        schema = json.loads(schema_bytes)
        jsonschema.Draft202012Validator.check_schema(schema)
        # The export's schema, exactly (units as descriptions: the description has no docs) ...
        generated = foxglove.generated_json_schema(name, cls)
        assert schema == foxglove.wide_integers_as_strings(generated), name
        # ... and horus-gen's, descriptions (doc comments) and the generator's $comment aside.
        from_generator = {k: v for k, v in horus_gen_schemas[name].items() if k != "$comment"}
        assert without(schema, "description") == without(
            foxglove.wide_integers_as_strings(from_generator), "description"), name
        sent = json.loads(payload)
        jsonschema.validate(sent, schema)
        plain = typedesc.decode(cls, frame[:len(cls().to_bytes())] if name in POOL_DESCRIPTORS else frame)
        assert sent == foxglove.strings_for_wide_integers(generated, foxglove.plain_json(plain)), name
        # A viewer sends the same JSON back: the same frame (pool frames are refused).
        [(decoded, error)] = run_tool(tmp_path / name / "back", "view/topic", description,
                                      [("decode", payload)])[2]
        if name in POOL_DESCRIPTORS:
            assert decoded is None and "not supported" in error, name
        else:
            assert error is None, f"{name}: {error}"
            assert decoded == frame, name
        checked += 1
    assert checked > 60


def test_a_viewers_bad_json_is_refused_naming_the_field(tmp_path):
    name, description = next((n, d) for n, d, _ in ALL_MESSAGES if n == "horus.msg.CmdVel")
    requests = [("decode", b'{"linear": "fast", "angular": 0.0, "stamp_nanos": "0"}'),
                ("decode", b'{"linear": 1.0, "stamp_nanos": "0"}'),
                ("decode", b'{"linear": 1.0, "angular": 0.0, "stamp_nanos": "-1"}'),
                ("decode", b'{"linear": 1.0, "angular": 0.0, "stamp_nanos": "0", "x": 1}'),
                ("decode", b'{"linear": 1.0,')]
    _, _, outputs = run_tool(tmp_path, "cmd_vel", description, requests)
    errors = [error for _, error in outputs]
    assert "horus.msg.CmdVel.linear: expected a number or null" in errors[0]
    assert "missing field 'angular'" in errors[1]
    assert "horus.msg.CmdVel.stamp_nanos: out of range for u64" in errors[2]
    assert "no field 'x'" in errors[3]
    assert "JSON payload:" in errors[4]


# The types the export writes with Foxglove's JSON schemas, and its converters (BY_TYPE).
FOXGLOVE_JSON = ("horus.msg.LaserScan", "horus.msg.PoseStamped", "horus.msg.Path",
                 "horus.msg.TransformStamped")


@pytest.mark.parametrize("name", FOXGLOVE_JSON)
def test_foxglove_json_schemas_carry_the_exports_values(tmp_path, name):
    description = next(d for n, d, _ in ALL_MESSAGES if n == name)
    cls = typedesc.message_class(description)
    value = filled({"kind": "message", "name": name})
    if "frame_id" in value:
        value["frame_id"] = ""  # the topic's name stands in
    if "waypoint_count" in value:
        value["waypoint_count"] = 3  # of 256 waypoints
    frame = typedesc.encode(cls, value)
    channel, schema_bytes, [(payload, error)] = run_tool(tmp_path, "robot/sensor", description,
                                                         [("encode", frame)])
    assert error is None, error
    schema_name = channel["schema_name"]
    assert json.loads(schema_bytes) == foxglove.FOXGLOVE_SCHEMAS[schema_name]
    sent = json.loads(payload)
    jsonschema.validate(sent, foxglove.FOXGLOVE_SCHEMAS[schema_name])
    assert sent == foxglove.BY_TYPE[name][1](typedesc.decode(cls, frame), "robot/sensor", 0)
    assert "robot/sensor" in json.dumps(sent)  # the frame name the message lacks
    [(decoded, error)] = run_tool(tmp_path / "back", "robot/sensor", description,
                                  [("decode", payload)])[2]
    if name == "horus.msg.LaserScan":
        assert decoded is None and "not supported" in error
        return
    assert error is None, error
    back = typedesc.decode(cls, decoded)
    original = typedesc.decode(cls, frame)
    assert back["timestamp_ns"] == original["timestamp_ns"]
    if name == "horus.msg.PoseStamped":
        assert back["frame_id"] == "" and back["pose"]["position"] == original["pose"]["position"]
        assert back["pose"]["orientation"] == original["pose"]["orientation"]
    elif name == "horus.msg.Path":
        assert back["frame_id"] == "" and back["waypoint_count"] == 3
        for waypoint, expected in zip(back["waypoints"][:3], original["waypoints"]):
            assert (waypoint["pose"]["x"], waypoint["pose"]["y"]) == (
                expected["pose"]["x"], expected["pose"]["y"])
            assert math.isclose(waypoint["pose"]["theta"], expected["pose"]["theta"])
    else:
        assert back["translation"] == original["translation"]
        assert back["rotation"] == original["rotation"]


def test_a_path_crosses_as_its_valid_waypoints_headings_as_turns_about_z(tmp_path):
    description, cls = descriptor_class("horus.msg.Path")
    headings = [0.0, math.pi / 2, float("nan"), -math.pi / 4]
    path = cls(frame_id="map", waypoint_count=len(headings), timestamp_ns=3_000_000_004)
    for i, theta in enumerate(headings):
        path.waypoints[i].pose.x = i + 0.5
        path.waypoints[i].pose.y = -i
        path.waypoints[i].pose.theta = theta
    path.waypoints[len(headings)].pose.x = 99.0  # past waypoint_count: not part of the path
    frame = typedesc.encode(cls, typedesc.to_plain(path))
    channel, _, [(payload, error)] = run_tool(tmp_path, "planner/path", description,
                                              [("encode", frame)])
    assert error is None, error
    assert channel["schema_name"] == "foxglove.PosesInFrame"
    sent = json.loads(payload)
    assert sent["frame_id"] == "map" and sent["timestamp"] == {"sec": 3, "nsec": 4}
    assert [p["position"] for p in sent["poses"]] == [
        {"x": i + 0.5, "y": -i, "z": 0.0} for i in range(len(headings))]
    half = math.sqrt(0.5)
    eighth = math.pi / 8
    expected = [(0.0, 1.0), (half, half), (0.0, 1.0), (-math.sin(eighth), math.cos(eighth))]
    for pose, (z, w) in zip(sent["poses"], expected):
        orientation = pose["orientation"]
        assert (orientation["x"], orientation["y"]) == (0.0, 0.0), orientation
        assert math.isclose(orientation["z"], z, abs_tol=1e-12), orientation
        assert math.isclose(orientation["w"], w), orientation
    # A viewer's path longer than the type holds is refused, saying so.
    too_long = json.dumps({"timestamp": {"sec": 0, "nsec": 0}, "frame_id": "map",
                           "poses": [sent["poses"][0]] * 257}).encode()
    [(decoded, error)] = run_tool(tmp_path / "long", "planner/path", description,
                                  [("decode", too_long)])[2]
    assert decoded is None and "257 poses, more than the 256 waypoints" in error, error


# Foxglove's published .proto files (github.com/foxglove/schemas, schemas/proto/foxglove):
# message -> {field: (number, type name or scalar)}.
FOXGLOVE_PROTO_FIELDS = {
    "foxglove.RawImage": {"timestamp": 1, "frame_id": 7, "width": 2, "height": 3, "encoding": 4,
                          "step": 5, "data": 6},
    "foxglove.CompressedImage": {"timestamp": 1, "frame_id": 4, "data": 2, "format": 3},
    "foxglove.PointCloud": {"timestamp": 1, "frame_id": 2, "pose": 3, "point_stride": 4,
                            "fields": 5, "data": 6},
    "foxglove.PackedElementField": {"name": 1, "offset": 2, "type": 3},
    "foxglove.Pose": {"position": 1, "orientation": 2},
    "foxglove.Vector3": {"x": 1, "y": 2, "z": 3},
    "foxglove.Quaternion": {"x": 1, "y": 2, "z": 3, "w": 4},
    "google.protobuf.Timestamp": {"seconds": 1, "nanos": 2},
}


def protobuf_class(schema_name: str, descriptor_set: bytes):
    """The message class of `schema_name` from the channel's FileDescriptorSet, in a pool of its own."""
    files = descriptor_pb2.FileDescriptorSet.FromString(descriptor_set)
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    for message, numbers in FOXGLOVE_PROTO_FIELDS.items():
        try:
            descriptor = pool.FindMessageTypeByName(message)
        except KeyError:
            continue
        assert {f.name: f.number for f in descriptor.fields} == numbers, message
    descriptor = pool.FindMessageTypeByName(schema_name)
    if hasattr(message_factory, "GetMessageClass"):
        return message_factory.GetMessageClass(descriptor)
    return message_factory.MessageFactory(pool).GetPrototype(descriptor)


def as_export(schema_name: str, message) -> dict:
    """A decoded protobuf message as the export's dict of the same schema."""
    out = {"timestamp": {"sec": message.timestamp.seconds, "nsec": message.timestamp.nanos},
           "frame_id": message.frame_id,
           "data": base64.b64encode(message.data).decode("ascii")}
    if schema_name == "foxglove.RawImage":
        out.update(width=message.width, height=message.height, encoding=message.encoding,
                   step=message.step)
    elif schema_name == "foxglove.CompressedImage":
        out.update(format=message.format)
    else:
        pose = message.pose
        out.update(pose={"position": {k: getattr(pose.position, k) for k in "xyz"},
                         "orientation": {k: getattr(pose.orientation, k) for k in "xyzw"}},
                   point_stride=message.point_stride,
                   fields=[{"name": f.name, "offset": f.offset, "type": f.type}
                           for f in message.fields])
    return out


def test_protobuf_payloads_decode_to_the_exports_values(tmp_path):
    checked = 0
    for name, description, _ in ALL_MESSAGES:
        cls = typedesc.message_class(description)
        fields = list(cls.__horus__.fields) + (["data"] if name in POOL_DESCRIPTORS else [])
        mapping = foxglove.foxglove_mapping(name, fields)
        if mapping is None or mapping[0] not in ("foxglove.RawImage", "foxglove.CompressedImage",
                                                 "foxglove.PointCloud"):
            continue
        value = filled({"kind": "message", "name": name})
        # Sizes a protobuf fixed32 holds (a depth image's step is width times its pixel size)
        # and a handful of point components.
        value.update({k: v for k, v in {"width": 640, "height": 480, "step": 1920,
                                        "fields_per_point": 4}.items() if k in value})
        value["frame_id"] = "cam\u00e9ra"
        frame = frame_of(name, cls, value)
        channel, descriptor_set, [(payload, error), (_, refused)] = run_tool(
            tmp_path / name, "camera/front", description, [("encode", frame), ("decode", b"{}")])
        assert error is None, f"{name}: {error}"
        assert "from a viewer is not supported" in refused
        message = protobuf_class(channel["schema_name"], descriptor_set).FromString(payload)
        expected = mapping[1](plain_with_data(name, cls, frame), "camera/front", 0)
        assert as_export(channel["schema_name"], message) == expected, name
        checked += 1
    assert checked == 4  # CompressedImage, and Image, DepthImage, PointCloud with their data


def descriptor_class(name: str):
    description = next(d for n, d, _ in ALL_MESSAGES if n == name)
    return description, typedesc.message_class(description)


def test_a_640x480_rgb8_image_crosses_as_foxglove_raw_image(tmp_path):
    description, cls = descriptor_class("horus.msg.ImageDescriptor")
    pixels = bytes((i * 7) % 251 for i in range(640 * 480 * 3))
    descriptor = typedesc.encode(cls, {"width": 640, "height": 480, "encoding": "Rgb8",
                                       "channels": 3, "step": 1920, "data_size": len(pixels),
                                       "frame_id": "camera", "timestamp_ns": 1_700_000_000_123_456_789})
    channel, descriptor_set, [(payload, error)] = run_tool(
        tmp_path, "camera/image", description, [("encode", descriptor + pixels)])
    assert error is None, error
    assert channel == {"encoding": "protobuf", "schema_name": "foxglove.RawImage",
                       "schema_encoding": "protobuf", "schema_is_binary": True}
    image = protobuf_class("foxglove.RawImage", descriptor_set).FromString(payload)
    assert (image.width, image.height, image.step, image.encoding) == (640, 480, 1920, "rgb8")
    assert image.frame_id == "camera"
    assert (image.timestamp.seconds, image.timestamp.nanos) == (1_700_000_000, 123_456_789)
    assert image.data == pixels
    # The pixels are the payload's tail, after a few header bytes.
    assert payload.endswith(pixels) and len(payload) - len(pixels) < 64


def test_a_point_cloud_crosses_as_foxglove_point_cloud(tmp_path):
    description, cls = descriptor_class("horus.msg.PointCloudDescriptor")
    points = [(i * 0.5, -i * 0.25, 1.0 + i) for i in range(100)]
    data = b"".join(struct.pack("<3f", *p) for p in points)
    descriptor = typedesc.encode(cls, {"point_count": 100, "fields_per_point": 3, "dtype": "F32",
                                       "data_size": len(data), "timestamp_ns": 5_000_000_001})
    _, descriptor_set, [(payload, error)] = run_tool(tmp_path, "lidar/points", description,
                                                     [("encode", descriptor + data)])
    assert error is None, error
    cloud = protobuf_class("foxglove.PointCloud", descriptor_set).FromString(payload)
    assert cloud.frame_id == "lidar/points"  # the descriptor names no frame: the topic's name
    assert (cloud.timestamp.seconds, cloud.timestamp.nanos) == (5, 1)
    assert cloud.point_stride == 12
    float32 = 7  # PackedElementField.NumericType.FLOAT32
    assert [(f.name, f.offset, f.type) for f in cloud.fields] == [
        ("x", 0, float32), ("y", 4, float32), ("z", 8, float32)]
    assert cloud.pose.orientation.w == 1.0 and cloud.pose.position.x == 0.0
    decoded = [struct.unpack_from("<3f", cloud.data, 12 * i) for i in range(100)]
    assert all(math.isclose(a, b) for p, q in zip(decoded, points) for a, b in zip(p, q))
