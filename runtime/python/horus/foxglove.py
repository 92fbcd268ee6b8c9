"""`horus record export F --foxglove OUT`: a recording rewritten as an MCAP that Foxglove displays
with no plugin, every message JSON with a JSON Schema schema.

Each recorded message is decoded with its type's class made from the schema text the file stores
(horus.typedesc, so types the command was never built with decode too). Types Foxglove draws
become its well-known schemas: a laser scan (horus.msg.LaserScan) foxglove.LaserScan, a pose in a
frame (horus.msg.PoseStamped) foxglove.PoseInFrame, a path (horus.msg.Path) foxglove.PosesInFrame
(its valid waypoints, each turned about +Z by its heading), a transform
(horus.msg.TransformStamped) foxglove.FrameTransform, horus.msg.CompressedImage
foxglove.CompressedImage, and by shape any message carrying its pixels (width, height, step,
encoding, data) foxglove.RawImage and any carrying its points (point_count, fields_per_point,
dtype, data) foxglove.PointCloud. A recorded Image, DepthImage or PointCloud (encoding horus.pool:
the descriptor, then its data) is such a message with the data as `data` (a depth image: RawImage
32FC1 or 16UC1). Every other type is its plain values under the JSON Schema `horus-gen --lang
jsonschema` writes for it (made here from the type's description, as that language makes it from
the schema), with every integer that can pass 2^53 (u64, i64) written as a string of its decimal
digits and its schema saying so: JavaScript, Foxglove's language, reads a JSON number as a double
and rounds those. The node-tick channel is copied with the same rule (its integers are unbounded:
all become strings). HORUS types without a frame name take the topic's name as frame (a transform:
parent "world", child the topic). The namespace's frame tree, which recordings hold on
/horus/frames and /horus/frames_static as foxglove.FrameTransform records already, is copied as
it is under Foxglove's schema: its 3D panel places every frame from them.
"""
from __future__ import annotations

import base64
import json
import math

from . import mcap
from .mcap import MSGPACK_ENCODING, POD_ENCODING, POOL_ENCODING, TICKS_TOPIC

# The frame tree's channels in a recording (horus/recording.hpp): each message one
# foxglove.FrameTransform JSON record, dynamic entries and the static set.
FRAMES_TOPIC = "/horus/frames"
FRAMES_STATIC_TOPIC = "/horus/frames_static"
FRAME_TOPICS = (FRAMES_TOPIC, FRAMES_STATIC_TOPIC)
FRAME_TRANSFORM = "foxglove.FrameTransform"


# ImageEncoding names -> Foxglove's RawImage encodings (those it draws).
IMAGE_ENCODINGS = {"Mono8": "mono8", "Mono16": "mono16", "Rgb8": "rgb8", "Bgr8": "bgr8",
                   "Rgba8": "rgba8", "Bgra8": "bgra8", "Yuv422": "yuv422", "Mono32F": "32FC1",
                   "BayerRggb8": "bayer_rggb8", "Depth16": "16UC1"}
# TensorDtype names -> (Foxglove NumericType, bytes) for point cloud fields.
POINT_TYPES = {"F32": (7, 4), "F64": (8, 8), "U8": (1, 1), "U16": (3, 2), "I16": (4, 2),
               "I32": (6, 4)}
POINT_FIELDS = {3: ("x", "y", "z"), 4: ("x", "y", "z", "intensity"),
                6: ("x", "y", "z", "red", "green", "blue")}


class ExportError(Exception):
    """A recording that cannot be exported (one line, naming the type or topic)."""


# -- Foxglove's well-known schemas, written from the field lists its documentation gives -------
# (written into the export's schema records; the tests validate every exported message against
# Foxglove's published schemas, npm @foxglove/schemas, not against these: tests/recording)

def _number() -> dict:
    return {"type": "number"}


def _object(title: str, properties: dict, description: str = "") -> dict:
    schema = {"title": title, "type": "object", "properties": properties,
              "required": sorted(properties)}
    if description:
        schema["description"] = description
    return schema


def _time() -> dict:
    return _object("time", {"sec": {"type": "integer", "minimum": 0},
                            "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}})


def _vector3(title: str = "foxglove.Vector3") -> dict:
    return _object(title, {axis: _number() for axis in "xyz"})


def _quaternion() -> dict:
    return _object("foxglove.Quaternion", {axis: _number() for axis in "xyzw"})


def _pose() -> dict:
    return _object("foxglove.Pose", {"position": _vector3(), "orientation": _quaternion()})


def _base64() -> dict:
    return {"type": "string", "contentEncoding": "base64"}


def _string() -> dict:
    return {"type": "string"}


def _count() -> dict:
    return {"type": "integer", "minimum": 0}


FOXGLOVE_SCHEMAS = {
    "foxglove.LaserScan": _object("foxglove.LaserScan", {
        "timestamp": _time(), "frame_id": _string(), "pose": _pose(), "start_angle": _number(),
        "end_angle": _number(), "ranges": {"type": "array", "items": _number()},
        "intensities": {"type": "array", "items": _number()}},
        "A single scan from a planar laser range-finder"),
    "foxglove.PoseInFrame": _object("foxglove.PoseInFrame", {
        "timestamp": _time(), "frame_id": _string(), "pose": _pose()},
        "A timestamped pose for an object or reference frame in 3D space"),
    "foxglove.PosesInFrame": _object("foxglove.PosesInFrame", {
        "timestamp": _time(), "frame_id": _string(), "poses": {"type": "array", "items": _pose()}},
        "An array of timestamped poses for an object or reference frame in 3D space"),
    "foxglove.FrameTransform": _object("foxglove.FrameTransform", {
        "timestamp": _time(), "parent_frame_id": _string(), "child_frame_id": _string(),
        "translation": _vector3(), "rotation": _quaternion()},
        "A transform between two reference frames in 3D space"),
    "foxglove.RawImage": _object("foxglove.RawImage", {
        "timestamp": _time(), "frame_id": _string(), "width": _count(), "height": _count(),
        "encoding": _string(), "step": _count(), "data": _base64()}, "A raw image"),
    "foxglove.CompressedImage": _object("foxglove.CompressedImage", {
        "timestamp": _time(), "frame_id": _string(), "data": _base64(), "format": _string()},
        "A compressed image"),
    "foxglove.PointCloud": _object("foxglove.PointCloud", {
        "timestamp": _time(), "frame_id": _string(), "pose": _pose(), "point_stride": _count(),
        "fields": {"type": "array", "items": _object("foxglove.PackedElementField", {
            "name": _string(), "offset": _count(),
            "type": {"type": "integer", "minimum": 0, "maximum": 8}})},
        "data": _base64()},
        "A collection of N-dimensional points"),
}


# -- conversions ---------------------------------------------------------------------------------

def _stamp(plain: dict, log_time: int) -> dict:
    ns = plain.get("timestamp_ns") or log_time
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _finite(value: float) -> float:
    """A laser range or coordinate Foxglove can read: HORUS marks an invalid range with 0, and
    JSON has no NaN or infinity."""
    return value if math.isfinite(value) else 0.0


def _identity_pose() -> dict:
    return {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _bytes_of(value) -> bytes:
    return value if isinstance(value, (bytes, bytearray)) else bytes(value)


def _laser_scan(plain, topic, log_time):
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "pose": _identity_pose(), "start_angle": _finite(plain["angle_min"]),
            "end_angle": _finite(plain["angle_max"]),
            "ranges": [_finite(r) for r in plain["ranges"]], "intensities": []}


def _pose_in_frame(plain, topic, log_time):
    pose = plain["pose"]
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "pose": {"position": {k: _finite(pose["position"][k]) for k in "xyz"},
                     "orientation": {k: _finite(pose["orientation"][k]) for k in "xyzw"}}}


def _yaw_orientation(theta: float) -> dict:
    """The quaternion of a planar heading (a turn about +Z); a heading that is not a number
    (NaN, infinite) as no turn, as _finite reads it."""
    half = _finite(theta) / 2
    return {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)}


def _poses_in_frame(plain, topic, log_time):
    """A path's first waypoint_count waypoints (at most the array's length) as poses: a
    waypoint's 2D pose (x, y, theta) is position (x, y, 0) and the orientation its heading theta
    gives (a turn about +Z, identity when theta is NaN or infinite); its velocity, timing and
    curvature have no place in foxglove.PosesInFrame."""
    waypoints = plain["waypoints"][:plain["waypoint_count"]]
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "poses": [{"position": {"x": _finite(w["pose"]["x"]), "y": _finite(w["pose"]["y"]),
                                    "z": 0.0},
                       "orientation": _yaw_orientation(w["pose"]["theta"])} for w in waypoints]}


def _frame_transform(plain, topic, log_time):
    translation, rotation = plain["translation"], plain["rotation"]
    return {"timestamp": _stamp(plain, log_time),
            "parent_frame_id": plain.get("parent_frame_id") or "world",
            "child_frame_id": plain.get("child_frame_id") or topic,
            "translation": {k: _finite(v) for k, v in zip("xyz", translation)},
            "rotation": {k: _finite(v) for k, v in zip("xyzw", rotation)}}


def _compressed_image(plain, topic, log_time):
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "data": base64.b64encode(_bytes_of(plain["data"])).decode("ascii"),
            "format": plain["format"]}


def _raw_image(plain, topic, log_time):
    encoding = plain["encoding"]
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "width": plain["width"], "height": plain["height"],
            "encoding": IMAGE_ENCODINGS.get(encoding, str(encoding).lower()), "step": plain["step"],
            "data": base64.b64encode(_bytes_of(plain["data"])).decode("ascii")}


def _point_cloud(plain, topic, log_time):
    numeric, size = POINT_TYPES.get(plain["dtype"], (7, 4))
    names = POINT_FIELDS.get(plain["fields_per_point"],
                             tuple(f"f{i}" for i in range(plain["fields_per_point"])))
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "pose": _identity_pose(), "point_stride": size * plain["fields_per_point"],
            "fields": [{"name": name, "offset": i * size, "type": numeric}
                       for i, name in enumerate(names)],
            "data": base64.b64encode(_bytes_of(plain["data"])).decode("ascii")}


# DepthImage dtype -> (RawImage encoding, bytes per pixel).
DEPTH_ENCODINGS = {"F32": ("32FC1", 4), "U16": ("16UC1", 2)}


def _depth_image(plain, topic, log_time):
    encoding, size = DEPTH_ENCODINGS.get(plain["dtype"], ("32FC1", 4))
    return {"timestamp": _stamp(plain, log_time), "frame_id": plain.get("frame_id") or topic,
            "width": plain["width"], "height": plain["height"], "encoding": encoding,
            "step": plain["width"] * size,
            "data": base64.b64encode(_bytes_of(plain["data"])).decode("ascii")}


BY_TYPE = {"horus.msg.LaserScan": ("foxglove.LaserScan", _laser_scan),
           "horus.msg.PoseStamped": ("foxglove.PoseInFrame", _pose_in_frame),
           "horus.msg.Path": ("foxglove.PosesInFrame", _poses_in_frame),
           "horus.msg.TransformStamped": ("foxglove.FrameTransform", _frame_transform),
           "horus.msg.CompressedImage": ("foxglove.CompressedImage", _compressed_image)}
BY_SHAPE = ((frozenset({"width", "height", "step", "encoding", "data"}),
             ("foxglove.RawImage", _raw_image)),
            (frozenset({"point_count", "fields_per_point", "dtype", "data"}),
             ("foxglove.PointCloud", _point_cloud)))


# Only with their data (a horus.pool channel) can these be drawn.
WITH_DATA_BY_TYPE = {"horus.msg.DepthImageDescriptor": ("foxglove.RawImage", _depth_image)}


def foxglove_mapping(type_name: str, fields: list[str]):
    """(Foxglove schema name, converter) for a type Foxglove draws, else None."""
    if type_name in BY_TYPE:
        return BY_TYPE[type_name]
    if "data" in fields and type_name in WITH_DATA_BY_TYPE:
        return WITH_DATA_BY_TYPE[type_name]
    for shape, mapping in BY_SHAPE:
        if shape <= set(fields):
            return mapping
    return None


def plain_json(value):
    """Plain values (typedesc.to_plain) as JSON values: bytes as base64, NaN and the
    infinities as null (as the `jsonschema` output language describes them)."""
    if isinstance(value, dict):
        return {k: plain_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [plain_json(v) for v in value]
    if isinstance(value, (bytes, bytearray)):
        return base64.b64encode(value).decode("ascii")
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# The largest integer a JavaScript number (a double) holds exactly: Number.MAX_SAFE_INTEGER.
SAFE_INTEGER = 2**53 - 1


def _wide(schema: dict) -> bool:
    """An integer whose schema admits values a double cannot hold exactly (no bound: any)."""
    return schema.get("type") == "integer" and not (
        -SAFE_INTEGER <= schema.get("minimum", -SAFE_INTEGER - 1)
        and schema.get("maximum", SAFE_INTEGER + 1) <= SAFE_INTEGER)


def wide_integers_as_strings(schema: dict) -> dict:
    """`schema` with each integer that can pass 2^53 made a string of decimal digits (what
    strings_for_wide_integers writes)."""
    if _wide(schema):
        out = {k: v for k, v in schema.items() if k not in ("type", "minimum", "maximum")}
        negative = schema.get("minimum", -1) < 0
        out.update(type="string", pattern="^-?[0-9]+$" if negative else "^[0-9]+$")
        return out
    out = dict(schema)
    if "properties" in schema:
        out["properties"] = {k: wide_integers_as_strings(v) for k, v in schema["properties"].items()}
    for keyword in ("additionalProperties", "items"):
        if isinstance(schema.get(keyword), dict):
            out[keyword] = wide_integers_as_strings(schema[keyword])
    if "anyOf" in schema:
        out["anyOf"] = [wide_integers_as_strings(s) for s in schema["anyOf"]]
    return out


def strings_for_wide_integers(schema: dict, value):
    """A JSON value of `schema` (the schema before wide_integers_as_strings) with every integer
    that schema lets pass 2^53 written as a string of its digits."""
    if _wide(schema):
        return str(value) if isinstance(value, int) and not isinstance(value, bool) else value
    if isinstance(value, dict):
        properties = schema.get("properties", {})
        extra = schema.get("additionalProperties")
        return {k: strings_for_wide_integers(properties[k], v) if k in properties
                else strings_for_wide_integers(extra, v) if isinstance(extra, dict) else v
                for k, v in value.items()}
    if isinstance(value, list) and isinstance(schema.get("items"), dict):
        return [strings_for_wide_integers(schema["items"], v) for v in value]
    if value is not None and "anyOf" in schema:
        # An Option: its one branch that is not null.
        branch = next(s for s in schema["anyOf"] if s.get("type") != "null")
        return strings_for_wide_integers(branch, value)
    return value


# The JSON Schema dialect `horus-gen --lang jsonschema` writes (generator/horus_gen/lang/jsonschema.py).
JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


def generated_json_schema(type_name: str, cls) -> dict:
    """The JSON Schema that `horus-gen --lang jsonschema` writes for a recorded type, made from the
    type description of its class (horus.typedesc), titled with the recorded name (a type the
    runtime spells itself, such as a service frame, is described under another)."""
    from . import typedesc
    tree = typedesc.parse(cls.__horus__.description)
    entries = {entry["name"]: entry for entry in tree["types"]}
    schema = _message_json_schema(entries[cls.__horus__.name], entries)
    schema["title"] = type_name
    return {"$schema": JSON_SCHEMA_DIALECT, **schema}


def _with_unit(schema: dict, unit: str) -> dict:
    if unit:
        schema["description"] = f"[{unit}]"
    return schema


def _message_json_schema(entry: dict, entries: dict) -> dict:
    properties = {f["name"]: _with_unit(_type_json_schema(f["type"], entries), f.get("unit", ""))
                  for f in entry["fields"]}
    return {"title": entry["name"], "type": "object", "properties": properties,
            "required": [f["name"] for f in entry["fields"]], "additionalProperties": False}


def _type_json_schema(t: dict, entries: dict) -> dict:
    """One value of a described type as lang/jsonschema.py spells it."""
    kind = t["kind"]
    if kind == "primitive":
        name = t["name"]
        if name == "bool":
            return {"type": "boolean"}
        if name in ("f32", "f64"):
            return {"type": ["number", "null"]}  # null: NaN or an infinity
        bits = int(name[1:])
        low, high = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if name[0] == "i" else (0, (1 << bits) - 1)
        return {"type": "integer", "minimum": low, "maximum": high}
    if kind == "string":
        return {"type": "string"}
    if kind == "bytes" or (kind == "vec" and t["element"] == {"kind": "primitive", "name": "u8"}):
        return {"type": "string", "contentEncoding": "base64"}
    if kind == "array":
        return {"type": "array", "items": _type_json_schema(t["element"], entries),
                "minItems": t["length"], "maxItems": t["length"]}
    if kind == "vec":
        return {"type": "array", "items": _type_json_schema(t["element"], entries)}
    if kind == "optional":
        return {"anyOf": [_type_json_schema(t["element"], entries), {"type": "null"}]}
    if kind == "message":
        return _message_json_schema(entries[t["name"]], entries)
    if kind == "enum":
        enum = entries[t["name"]]
        return {"title": enum["name"], "type": "string", "enum": [v["name"] for v in enum["values"]]}
    raise ExportError(f"no JSON Schema for the described type kind '{kind}'")


def recorded_class(channel: mcap.Channel, type_name: str, schema: mcap.Schema, fingerprint: int):
    """The class of a recorded topic's type: from the type description its channel carries, else
    (a file written before recordings carried one) from the stored schema text. SchemaError when
    either is not `type_name` of `fingerprint`."""
    from . import typedesc
    description = channel.description
    if not description:
        return typedesc.load_type(type_name, schema.data.decode("utf-8"), fingerprint)
    cls = typedesc.message_class(description)
    if (cls.__horus__.name, cls.__horus__.fingerprint) != (type_name, fingerprint):
        raise typedesc.SchemaError(f"its type description is of {cls.__horus__.name} (fingerprint "
                                   f"{cls.__horus__.fingerprint:016x}), the channel says {type_name} "
                                   f"(fingerprint {fingerprint:016x})")
    return cls


class _ExportChannel:
    """How one recorded channel's messages are written: decoder, converter, output channel."""

    def __init__(self, channel: mcap.Channel, schema: mcap.Schema | None, writer: mcap.Writer,
                 schema_ids: dict[str, int]) -> None:
        self.topic = channel.topic
        self.decode = None
        self.convert = None
        if channel.topic == TICKS_TOPIC and channel.message_encoding == "json" and schema is not None \
                and schema.encoding == "jsonschema":
            # Already JSON: its integers (unbounded, start_ns past 2^53) become strings.
            tick_schema = json.loads(schema.data)
            self.decode = json.loads
            self.convert = lambda plain, log_time: strings_for_wide_integers(tick_schema, plain)
            key = f"{schema.name}:{schema.encoding}"
            if key not in schema_ids:
                schema_ids[key] = writer.add_schema(schema.name, schema.encoding, json.dumps(
                    wide_integers_as_strings(tick_schema), sort_keys=True).encode())
            self.id = writer.add_channel(channel.topic, "json", schema_ids[key], channel.metadata)
            return
        if channel.topic in FRAME_TOPICS and channel.message_encoding == "json" \
                and schema is not None and schema.name == FRAME_TRANSFORM:
            # Foxglove's records already: copied, under the schema a TransformStamped topic's
            # transforms share.
            if FRAME_TRANSFORM not in schema_ids:
                schema_ids[FRAME_TRANSFORM] = writer.add_schema(
                    FRAME_TRANSFORM, "jsonschema",
                    json.dumps(FOXGLOVE_SCHEMAS[FRAME_TRANSFORM], sort_keys=True).encode())
            self.schema = FOXGLOVE_SCHEMAS[FRAME_TRANSFORM]
            self.id = writer.add_channel(channel.topic, "json", schema_ids[FRAME_TRANSFORM],
                                         channel.metadata)
            return
        if channel.message_encoding not in (POD_ENCODING, MSGPACK_ENCODING, POOL_ENCODING):
            # Readable as it is: copied with its own schema.
            key = f"{schema.name}:{schema.encoding}" if schema else ""
            if schema is not None and key not in schema_ids:
                schema_ids[key] = writer.add_schema(schema.name, schema.encoding, schema.data)
            self.id = writer.add_channel(channel.topic, channel.message_encoding,
                                         schema_ids.get(key, 0), channel.metadata)
            return
        from . import typedesc
        type_name = channel.metadata.get("horus.type") or (schema.name if schema else "")
        if schema is None:
            raise ExportError(f"topic '{channel.topic}' has no schema record")
        try:
            cls = recorded_class(channel, type_name, schema,
                                 int(channel.metadata.get("horus.fingerprint", "0"), 16))
        except (typedesc.SchemaError, ValueError) as error:
            raise ExportError(f"topic '{channel.topic}': cannot decode {type_name}: {error}") from None
        fields = list(cls.__horus__.fields)
        if channel.message_encoding == POOL_ENCODING:
            size = int(channel.metadata.get("horus.payload_size", "0"))
            fields.append("data")
            self.decode = lambda data: {**typedesc.decode(cls, data[:size]), "data": data[size:]}
        else:
            self.decode = lambda data: typedesc.decode(cls, data)
        mapping = foxglove_mapping(type_name, fields)
        if mapping is None and channel.message_encoding == POOL_ENCODING:
            # A tensor: its descriptor's values (Foxglove has no schema for the data).
            decode_with_data = self.decode
            self.decode = lambda data: {k: v for k, v in decode_with_data(data).items()
                                        if k != "data"}
        if mapping is not None:
            schema_name, convert = mapping
            topic = channel.topic
            self.convert = lambda plain, log_time: convert(plain, topic, log_time)
            schema_json = FOXGLOVE_SCHEMAS[schema_name]
        else:
            schema_name = type_name
            generated = generated_json_schema(type_name, cls)
            self.convert = lambda plain, log_time: strings_for_wide_integers(
                generated, plain_json(plain))
            schema_json = wide_integers_as_strings(generated)
        if schema_name not in schema_ids:
            schema_ids[schema_name] = writer.add_schema(
                schema_name, "jsonschema", json.dumps(schema_json, sort_keys=True).encode())
        self.schema = schema_json
        metadata = {k: v for k, v in channel.metadata.items() if k in ("horus.type", "horus.fingerprint")}
        self.id = writer.add_channel(channel.topic, "json", schema_ids[schema_name], metadata)

    def payload(self, message: mcap.Message) -> bytes:
        if self.decode is None:
            return message.data
        value = self.convert(self.decode(message.data), message.log_time)
        return json.dumps(value, separators=(",", ":"), allow_nan=False).encode()


def export(path: str, output: str) -> tuple[dict[str, int], dict[str, str]]:
    """Writes the Foxglove form of the recording `path` to `output`. Returns the messages written
    per topic, and the topics left out with the reason (a type that cannot be decoded: its
    schema text does not compile, as for a plain value that is not a message)."""
    reader = mcap.Reader(path)
    counts: dict[str, int] = {}
    skipped: dict[str, str] = {}
    channels: dict[int, _ExportChannel | None] = {}
    schema_ids: dict[str, int] = {}
    with open(output, "wb") as stream:
        writer = mcap.Writer(stream, library="horus record export")
        for record in reader:
            if isinstance(record, mcap.Message):
                if record.channel_id not in channels:
                    channel = reader.channels[record.channel_id]
                    try:
                        channels[record.channel_id] = _ExportChannel(
                            channel, reader.schemas.get(channel.schema_id), writer, schema_ids)
                    except ExportError as error:
                        channels[record.channel_id] = None
                        skipped[channel.topic] = str(error)
                exported = channels[record.channel_id]
                if exported is None:
                    continue
                writer.add_message(exported.id, record.log_time, exported.payload(record),
                                   publish_time=record.publish_time, sequence=record.sequence)
                counts[exported.topic] = counts.get(exported.topic, 0) + 1
            elif isinstance(record, mcap.Metadata):
                writer.add_metadata(record.name, record.metadata)
        writer.finish()
    return counts, skipped
