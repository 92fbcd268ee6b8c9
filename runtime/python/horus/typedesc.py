"""Message classes made at run time from a type description (docs/type-description.md).

A description is the tree `horus-gen describe --json` prints and generated code, segments and links
carry as MessagePack (`T.__horus__["description"]`, `horus::TypeInfo<T>::description`). From it this
module makes classes that behave as generated ones do (`from_bytes`, `to_bytes`, `__horus__` with
fields, codecs, offsets, `log_summary()`), over the same support module, so their bytes are the
generated classes' bytes: POD struct layouts at the described offsets, MessagePack as msgpack-cxx
writes it.

    cls = message_class(description)           # a dict or the carried MessagePack bytes
    plain = to_plain(cls.from_bytes(payload))  # dicts, lists, numbers, strings, enum names
    payload = from_plain(cls, {"x": 1.0}).to_bytes()
    cls = load_type("demo.Pose", schema_text, 0x72b8e8dd8bd50428)  # from stored schema text

`load_type` compiles schema text with horus-gen in process (`horus_gen.describe_schema_text`). The
identities the runtime spells itself are checked against the FNV-1a hash of the stored text, as the
runtime computes it: a plain value (`value [f32; 3]`) is described by `plain_value_description`, as
the runtime and horus.plain_value describe it; `horus.ServiceRegistration` is compiled under the
package `horus_runtime` (horus-gen keeps `horus` for the runtime), then named and described as the
runtime describes it; a service frame
(`horus.ServiceRequest<demo.AddRequest>`) is described from its payload's description by
`service_frame`, the tree the runtime builds (runtime/src/service/frame_description.cpp).

Errors are `SchemaError` (a description or schema text that cannot become a class, or one of another
fingerprint) and `ValueError` (a value that does not fit its type), each naming the problem.
"""
from __future__ import annotations

import enum
import importlib
import importlib.util
import math
import os
import re
import shutil
import struct
import sys
import threading

__all__ = ["FORMAT", "VERSION", "SchemaError", "parse", "carried", "classes", "message_class", "load_type",
           "describe_files", "to_plain", "from_plain", "decode", "encode", "zero", "runtime_fingerprint"]

FORMAT = "horus.typedesc"
VERSION = 1  # the highest description version this module reads
_SUPPORT = "_horus_gen_support_v1"
_SUPPORT_CONTRACT = 2  # the support module's TypeInfo takes `description`

_PRIMITIVE_CODECS = {"bool": "BOOL", "u8": "U8", "u16": "U16", "u32": "U32", "u64": "U64",
                     "i8": "I8", "i16": "I16", "i32": "I32", "i64": "I64", "f32": "F32", "f64": "F64"}


class SchemaError(Exception):
    """A description or stored schema text that cannot become a class (one line, names the type)."""


# -- the description ------------------------------------------------------------------------------

def parse(description) -> dict:
    """The description tree of `description` (a dict, or MessagePack bytes), checked to be one this
    module reads: SchemaError for another format or a higher version."""
    if isinstance(description, (bytes, bytearray, memoryview)):
        import msgpack
        try:
            description = msgpack.unpackb(bytes(description), raw=False, strict_map_key=False)
        except (ValueError, TypeError, msgpack.UnpackException) as error:
            raise SchemaError(f"a type description is not valid MessagePack ({error})") from None
    if not isinstance(description, dict) or description.get("format") != FORMAT:
        raise SchemaError(f"not a type description (expected a map whose format is '{FORMAT}')")
    version = description.get("version")
    if not isinstance(version, int) or version > VERSION:
        raise SchemaError(f"type description version {version} is newer than this reader's {VERSION}: "
                          "update horus to read it")
    if not isinstance(description.get("types"), list):
        raise SchemaError("a type description without its list of types")
    return description


def carried(description, name: str) -> dict:
    """The carried form for `name`: it and every type it uses, from a description holding them."""
    tree = parse(description)
    by_name = {entry["name"]: entry for entry in tree["types"]}
    ordered: list[str] = []

    def visit(qualified: str) -> None:
        if qualified in ordered:
            return
        if qualified not in by_name:
            raise SchemaError(f"the type description has no type {qualified}")
        for f in by_name[qualified].get("fields", ()):
            for used in _named(f["type"]):
                visit(used)
        ordered.append(qualified)

    visit(name)
    return {"format": FORMAT, "version": tree["version"], "root": name, "types": [by_name[q] for q in ordered]}


def _named(t: dict) -> list[str]:
    if t["kind"] in ("message", "enum"):
        return [t["name"]]
    if "element" in t:
        return _named(t["element"])
    return []


# -- classes --------------------------------------------------------------------------------------

def classes(description) -> dict[str, type]:
    """A class per message and enum of the description (qualified name -> class)."""
    tree = parse(description)
    root = tree.get("root")
    raw = bytes(description) if isinstance(description, (bytes, bytearray, memoryview)) else None
    made: dict[str, type] = {}
    entries = {entry["name"]: entry for entry in tree["types"]}
    for entry in tree["types"]:
        if entry["kind"] in ("message", "enum"):
            _make(entry, entries, made, raw if entry["name"] == root else None)
    return made


def message_class(description, name: str | None = None) -> type:
    """The class of `name` (default: the description's root) made from the description."""
    tree = parse(description)
    name = name or tree.get("root")
    if name is None:
        raise SchemaError("the type description has no root: name the type")
    made = classes(description)
    if name not in made:
        raise SchemaError(f"the type description has no message or enum {name}")
    return made[name]


def _make(entry: dict, entries: dict, made: dict, raw: bytes | None) -> type:
    name = entry["name"]
    if name in made:
        return made[name]
    s = support()
    if raw is None:
        raw = _pack_description(carried({"format": FORMAT, "version": VERSION, "types": list(entries.values())}, name))
    if entry["kind"] == "enum":
        cls = enum.IntEnum(name.rsplit(".", 1)[1], [(v["name"], v["value"]) for v in entry["values"]])
        cls.__horus__ = s.EnumInfo(name=name, package=entry["package"], fingerprint=int(entry["fingerprint"], 16),
                                   schema=entry.get("schema", ""), underlying=entry["underlying"], description=raw)
        made[name] = cls
        return cls
    for f in entry["fields"]:
        for used in _named(f["type"]):
            if used not in entries:
                raise SchemaError(f"{name}.{f['name']} uses {used}, which the type description lacks")
            _make(entries[used], entries, made, None)
    cls = _message(s, entry, made, raw)
    made[name] = cls
    return cls


def _pack_description(tree: dict) -> bytes:
    import msgpack
    return msgpack.packb(tree, use_bin_type=True)


def _codec(s, t: dict, made: dict, initial=None):
    kind = t["kind"]
    if kind == "primitive":
        return getattr(s, _PRIMITIVE_CODECS[t["name"]])
    if kind == "string":
        return s.FixedStr(t["capacity"]) if "capacity" in t else s.STR
    if kind == "bytes" or (kind == "vec" and t["element"] == {"kind": "primitive", "name": "u8"}):
        return s.BYTES
    if kind == "enum":
        cls = made[t["name"]]
        return s.Enum(cls, getattr(s, _PRIMITIVE_CODECS[cls.__horus__.underlying]))
    if kind == "message":
        return s.Nested(made[t["name"]])
    if kind == "array":
        shape, inner = [], t
        while inner["kind"] == "array":
            shape.append(inner["length"])
            inner = inner["element"]
        if inner["kind"] == "primitive":
            return s.NumArray(_codec(s, inner, made), tuple(shape), initial)
        return s.ListArray(_codec(s, t["element"], made), t["length"], initial)
    if kind == "vec":
        return s.Vec(_codec(s, t["element"], made))
    if kind == "optional":
        return s.Option(_codec(s, t["element"], made))
    raise SchemaError(f"unknown type kind '{kind}' in a type description")


def _value(t: dict, value, made: dict):
    """A default as the generated class holds it: enum names as members, f32 rounded, arrays as tuples."""
    if value is None:
        return None
    if t["kind"] == "array":
        return tuple(_value(t["element"], v, made) for v in value)
    if t["kind"] == "enum":
        return made[t["name"]][value]
    if t["kind"] == "primitive" and t["name"] == "f32":
        return struct.unpack("<f", struct.pack("<f", float(value)))[0]
    if t["kind"] == "primitive" and t["name"] == "f64":
        return float(value)
    return value


def _needs_factory(t: dict) -> bool:
    """Fields whose value is a fresh mutable object per message (as lang/python.py decides)."""
    if t["kind"] == "vec" and t["element"] == {"kind": "primitive", "name": "u8"}:
        return False
    return t["kind"] in ("array", "vec", "message")


def _scalar_default(codec, t: dict, made: dict, default):
    if default is not None:
        return _value(t, default, made)
    if t["kind"] == "optional":
        return None
    return codec.default()


def _message(s, entry: dict, made: dict, raw: bytes) -> type:
    name, fields = entry["name"], entry["fields"]
    names = tuple(f["name"] for f in fields)
    codecs = tuple(_codec(s, f["type"], made, _value(f["type"], f.get("default"), made) if f["type"]["kind"] == "array"
                          else None) for f in fields)
    pod = entry["tier"] == "pod"
    offsets = tuple(f["offset"] for f in fields) if pod else ()
    index = {n: i for i, n in enumerate(names)}
    summary = tuple((p["text"], None, "", "") if "text" in p else ("", index[p["field"]], p["label"], p["unit"])
                    for p in entry.get("summary", ()) if "expression" not in p)
    computed = any("expression" in p for p in entry.get("summary", ()))
    info = s.TypeInfo(name=name, package=entry["package"], fingerprint=int(entry["fingerprint"], 16), is_pod=pod,
                      size=entry["size"], alignment=entry["alignment"], schema=entry["schema"],
                      topic=entry.get("topic"), fields=names, codecs=codecs, offsets=offsets, summary=summary,
                      description=raw)
    factories = [_needs_factory(f["type"]) for f in fields]
    scalars = [None if factory else _scalar_default(codec, f["type"], made, f.get("default"))
               for f, codec, factory in zip(fields, codecs, factories)]

    def __init__(self, **values):
        unknown = set(values) - set(names)
        if unknown:
            raise TypeError(f"{name} has no field '{sorted(unknown)[0]}' (fields: {', '.join(names)})")
        for field, codec, factory, initial in zip(names, codecs, factories, scalars):
            given = values.get(field)
            if not factory:
                setattr(self, field, values.get(field, initial))
            elif given is None:
                setattr(self, field, [] if isinstance(codec, s.Vec) else codec.default())
            elif isinstance(codec, (s.Vec, s.Nested)):
                setattr(self, field, given)
            else:
                setattr(self, field, codec.coerce(given))

    # A plain value's message is named as its type is spelled, with no package ("f32").
    short_name = name.rsplit(".", 1)[-1]
    namespace = {"__slots__": names, "__horus__": info, "__init__": __init__, "__module__": __name__,
                 "__qualname__": short_name}
    if pod:
        def _horus_pack_into(self, buf, off: int) -> None:
            for field, codec, offset in zip(names, codecs, offsets):
                codec.raw_into(buf, off + offset, getattr(self, field))

        def _horus_unpack_from(cls, buf, off: int):
            self = cls.__new__(cls)
            for field, codec, offset in zip(names, codecs, offsets):
                setattr(self, field, codec.raw_from(buf, off + offset))
            return self

        namespace["_horus_pack_into"] = _horus_pack_into
        namespace["_horus_unpack_from"] = classmethod(_horus_unpack_from)
    if computed:
        parts = entry["summary"]

        def log_summary(self) -> str:
            """One line for logs, the text C++'s log_summary() gives for the same values."""
            return "".join(_summary_part(s, self, part, codecs, index) for part in parts)

        namespace["log_summary"] = log_summary
    base = s.PodMessage if pod else s.SerializedMessage
    return type(short_name, (base,), namespace)


def _summary_part(s, message, part: dict, codecs, index) -> str:
    if "text" in part:
        return part["text"]
    if "field" in part:
        codec = codecs[index[part["field"]]]
        shown = codec.summary(getattr(message, part["field"]), part["label"])
        return shown + (" " + part["unit"] if part["unit"] else "")
    x = _evaluate(part["expression"], message, codecs, index)
    precision = part["precision"]
    if precision is None:
        return s.fmt_g(x)
    if x != x:
        return "-nan" if math.copysign(1.0, x) < 0 else "nan"
    return "%.*f" % (precision, x)


def _evaluate(expr: dict, message, codecs, index) -> float:
    """f64 arithmetic as C++ computes it (lang/python.py summary_expression)."""
    op = expr["op"]
    if op == "field":
        return float(codecs[index[expr["field"]]].number(getattr(message, expr["field"])))
    if op == "number":
        return float(expr["number"])
    if op == "neg":
        return -_evaluate(expr["operands"][0], message, codecs, index)
    a, b = (_evaluate(e, message, codecs, index) for e in expr["operands"])
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    return a / b if b else a * math.copysign(math.inf, b)


# -- values ---------------------------------------------------------------------------------------

def zero(cls):
    """The message every field of which has its default (the type's zero where none is declared)."""
    return cls()


def decode(cls, data: bytes):
    """The plain value of the bytes of a `cls` message (POD struct bytes or MessagePack)."""
    return to_plain(cls.from_bytes(data))


def encode(cls, value) -> bytes:
    """The bytes of the message whose plain value is `value` (fields left out keep their defaults)."""
    return from_plain(cls, value).to_bytes()


def to_plain(message):
    """The message as plain values: a dict per message, lists for arrays and Vec, None for an
    empty Option, enum member names, bytes for bytes fields. An f32 is the shortest decimal that
    reads back as the same f32 (0.1, not 0.10000000149011612)."""
    info = type(message).__horus__
    return {name: _plain(codec, getattr(message, name)) for name, codec in zip(info.fields, info.codecs)}


def _plain(codec, value):
    kind = type(codec).__name__  # by name: a class may hold another copy of the support module
    if value is None:
        return None
    if kind == "Nested":
        return to_plain(value)
    if kind == "Enum":
        return value.name if hasattr(value, "name") else int(value)
    if kind == "Float" and codec.single:
        return _short_f32(value)
    if kind == "NumArray":
        values = value.tolist()
        return _map_nested(values, _short_f32) if codec.kind == "f" and codec.element.single else values
    if kind in ("Vec", "ListArray"):
        return [_plain(codec.element, item) for item in value]
    if kind == "Option":
        return _plain(codec.element, value)
    return value


def _short_f32(value: float) -> float:
    import numpy
    return float(repr(numpy.float32(value)).removeprefix("np.float32(").removesuffix(")"))


def _map_nested(values, convert):
    return [_map_nested(v, convert) if isinstance(v, list) else convert(v) for v in values]


def from_plain(cls, value, path: str = ""):
    """An instance of `cls` from plain values (a dict of some or all of its fields; those left out
    keep their defaults). Enum fields take a member name or its integer. ValueError names the field
    and the problem: an unknown field, a value of the wrong kind."""
    message = cls()
    _fill(message, value, path or cls.__horus__.name)
    # Encoding checks every value against its type (range, length, kind) and names the field.
    message.to_bytes()
    return message


def _fill(message, value, path: str) -> None:
    info = type(message).__horus__
    if not isinstance(value, dict):
        raise ValueError(f"{path}: expected a mapping of the fields of {info.name}, got {type(value).__name__}")
    for name, item in value.items():
        if name not in info.fields:
            raise ValueError(f"{path}: no field '{name}' (fields: {', '.join(info.fields)})")
        codec = info.codecs[info.fields.index(name)]
        setattr(message, name, _convert(codec, item, f"{path}.{name}", getattr(message, name)))


def _convert(codec, value, path: str, current):
    kind = type(codec).__name__
    if kind == "Nested":
        _fill(current, value, path)
        return current
    if kind == "Enum":
        if isinstance(value, str):
            member = codec.cls.__members__.get(value)
            if member is None:
                raise ValueError(f"{path}: '{value}' is not a value of {codec.cls.__horus__.name} "
                                 f"({', '.join(codec.cls.__members__)})")
            return member
        return value
    if kind == "Option":
        return None if value is None else _convert(codec.element, value, path, codec.element.default())
    if kind in ("Vec", "ListArray"):
        if not isinstance(value, list):
            raise ValueError(f"{path}: expected a list, got {type(value).__name__}")
        return [_convert(codec.element, item, f"{path}[{index}]", codec.element.default())
                for index, item in enumerate(value)]
    if kind == "NumArray":
        try:
            return codec.coerce(value)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{path}: {error}") from None
    if kind == "Bytes" and isinstance(value, list):
        try:
            return bytes(value)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{path}: {error}") from None
    return value


# -- schema text ----------------------------------------------------------------------------------

# The identities the runtime spells itself (runtime/include/horus/plain_value.hpp,
# detail/service_frame.hpp): the runtime's own package `horus`, a service frame's name with its
# payload's in angle brackets, a plain value.
_RUNTIME_NAME = re.compile(r"^horus\.([A-Za-z_][A-Za-z0-9_]*)(<[A-Za-z0-9_.]+>)?$")
_PLAIN_VALUE = "value "
_RUNTIME_PACKAGE = "horus_runtime"
_loaded: dict[tuple[str, str], type] = {}
_loading = threading.Lock()


def runtime_fingerprint(text: str) -> int:
    """The FNV-1a hash (64 bits) the runtime gives the identities it spells itself."""
    value = 0xCBF29CE484222325
    for byte in text.encode():
        value = ((value ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return value


def _runtime_spelled(type_name: str, schema_text: str) -> bool:
    return schema_text.startswith(_PLAIN_VALUE) or _RUNTIME_NAME.match(type_name) is not None


# A service frame's name, its payload's inside (detail/service_frame.hpp).
_SERVICE_FRAME = re.compile(r"^horus\.Service(Request|Response)<([A-Za-z0-9_.]+)>$")
_POD_ERROR_CAPACITY = 236  # the error text of a POD response frame: its payload starts at byte 256
_U64 = {"kind": "primitive", "name": "u64"}
_U32 = {"kind": "primitive", "name": "u32"}


def service_frame(payload_description, response: bool) -> dict:
    """The carried description of the request (`response` False) or response frames of the payload
    whose carried description is `payload_description`: its types, then the frame, named, laid out,
    summarised and fingerprinted as the runtime does (the FNV-1a hash of the frame's schema text: its
    own block, then the payload's text)."""
    tree = parse(payload_description)
    payload_name = tree.get("root")
    payload_types = carried(tree, payload_name)["types"] if payload_name else []
    payload = payload_types[-1] if payload_types else None
    if payload is None or payload["kind"] != "message":
        raise SchemaError("a service frame's payload description has no root message")
    pod = payload["tier"] == "pod"
    name = f"horus.Service{'Response' if response else 'Request'}<{payload_name}>"
    head = [("client_id", _U64, "u64"), ("request_id", _U64, "u64")]
    if response:
        error = ({"kind": "string", "capacity": _POD_ERROR_CAPACITY}, f"string<{_POD_ERROR_CAPACITY}>") if pod \
            else ({"kind": "string"}, "String")
        head += [("status", _U32, "u32"), ("error", *error)]
    else:
        head.append(("reply_to", _U64, "u64"))
    head.append(("payload", {"kind": "message", "name": payload_name}, payload_name))
    schema = (f"message {name} {{\n" + "".join(f"  {field}: {spelling},\n" for field, _, spelling in head) + "}\n"
              + payload["schema"])
    fields = [{"name": field, "type": t, "offset": None, "size": None, "default": None, "unit": "",
               "spelling": spelling} for field, t, spelling in head]
    size = alignment = None
    padding: list[dict] = []
    if pod:
        size, alignment = _lay_out(fields, payload)
        end = 0
        for f in fields:
            if f["offset"] > end:
                padding.append({"offset": end, "size": f["offset"] - end})
            end = f["offset"] + f["size"]
        if size > end:
            padding.append({"offset": end, "size": size - end})
    short = name.split("<", 1)[0].rsplit(".", 1)[1]
    summary: list[dict] = []
    before = short + "{"
    for f in fields:
        summary += [{"text": f"{before}{f['name']}: "}, {"field": f["name"], "label": "", "unit": ""}]
        before = ", "
    summary.append({"text": "}"})
    frame = {"kind": "message", "name": name, "package": "horus",
             "fingerprint": f"0x{runtime_fingerprint(schema):016x}", "tier": "pod" if pod else "serialized",
             "size": size, "alignment": alignment, "fields": fields, "constants": [], "padding": padding,
             "summary": summary, "topic": None, "schema": schema}
    return {"format": FORMAT, "version": VERSION, "root": name, "types": [*payload_types, frame]}


def _lay_out(fields: list[dict], payload: dict) -> tuple[int, int]:
    """The C++ layout of a POD frame's fields (each at its alignment): their offsets and sizes set in
    place; the frame's size and alignment."""
    end, alignment = 0, 1
    for f in fields:
        t = f["type"]
        if t["kind"] == "primitive":
            size = align = 8 if t["name"] == "u64" else 4
        elif t["kind"] == "string":
            size, align = t["capacity"], 1
        else:
            size, align = payload["size"], payload["alignment"]
        f["offset"] = -(-end // align) * align
        f["size"] = size
        end = f["offset"] + size
        alignment = max(alignment, align)
    return -(-end // alignment) * alignment, alignment


_PLAIN_ARRAY = re.compile(r"^\[(.+); ([1-9][0-9]*)\]$")
_PLAIN_VEC = re.compile(r"^Vec<(.+)>$")


def _plain_value_type(name: str) -> tuple[dict, int | None, int | None, str]:
    """(TYPE, size and alignment or None for a serialized value, element label) of a plain value's
    spelling, as runtime/include/horus/plain_value.hpp lays the C++ type out."""
    if name in _PRIMITIVE_CODECS:
        size = 1 if name == "bool" else int(name[1:]) // 8
        return {"kind": "primitive", "name": name}, size, size, ""
    if name == "String":
        return {"kind": "string"}, None, None, ""
    array = _PLAIN_ARRAY.match(name)
    if array is not None:
        element, size, alignment, _label = _plain_value_type(array.group(1))
        if size is None:
            raise SchemaError(f"plain value {name!r}: an array's elements have a fixed size")
        length = int(array.group(2))
        return {"kind": "array", "element": element, "length": length}, size * length, alignment, array.group(1)
    vec = _PLAIN_VEC.match(name)
    if vec is not None:
        return {"kind": "vec", "element": _plain_value_type(vec.group(1))[0]}, None, None, vec.group(1)
    raise SchemaError(f"not a plain value type: {name!r} (bool, i8..i64, u8..u64, f32, f64, String, "
                      "[T; N], Vec<T>)")


def plain_value_description(name: str) -> dict:
    """The carried description of the plain value `name` (`f32`, `[f32; 3]`, `Vec<u8>`:
    runtime/include/horus/plain_value.hpp): the message `PlainValue { value: <name> }` its bytes
    are, named, fingerprinted and with the schema text of the plain value's identity, laid out as
    the C++ type, summarised as its log_summary prints it. The tree
    runtime/src/types/plain_value_description.cpp builds. SchemaError for no plain value type."""
    value_type, size, alignment, label = _plain_value_type(name)
    schema = f"{_PLAIN_VALUE}{name}\n"
    pod = size is not None
    value = {"name": "value", "type": value_type, "offset": 0 if pod else None, "size": size,
             "default": None, "unit": "", "spelling": name}
    entry = {"kind": "message", "name": name, "package": "",
             "fingerprint": f"0x{runtime_fingerprint(schema):016x}", "tier": "pod" if pod else "serialized",
             "size": size, "alignment": alignment, "fields": [value], "constants": [], "padding": [],
             "summary": [{"field": "value", "label": label, "unit": ""}], "topic": None, "schema": schema}
    return {"format": FORMAT, "version": VERSION, "root": name, "types": [entry]}


def plain_value_bytes(name: str) -> bytes:
    """plain_value_description(name) as the MessagePack bytes a segment stores."""
    return _pack_description(plain_value_description(name))


def _plain_value_described(type_name: str, schema_text: str) -> dict:
    """The carried description of the plain value a segment stores as `value <name>`."""
    value_type = schema_text[len(_PLAIN_VALUE):].strip()
    if value_type != type_name:
        raise SchemaError(f"the stored schema describes {value_type}, not {type_name}")
    return plain_value_description(type_name)


def _compilable(type_name: str, schema_text: str) -> tuple[str, str]:
    """(the name horus-gen compiles the type under, schema text it compiles) for a type as a segment
    stores it, the runtime's registration included."""
    runtime = _RUNTIME_NAME.match(type_name)
    if runtime is None:
        return type_name, schema_text
    compiled = f"{_RUNTIME_PACKAGE}.{runtime.group(1)}"
    opener = f"message {type_name} {{"
    if not schema_text.startswith(opener):
        raise SchemaError(f"the stored schema does not describe {type_name}")
    return compiled, schema_text.replace(opener, f"message {compiled} {{", 1)


def _described(type_name: str, schema_text: str) -> dict:
    """The carried description of a type as a segment stores it (name and schema text)."""
    if schema_text.startswith(_PLAIN_VALUE):
        return _plain_value_described(type_name, schema_text)
    generator = _generator()
    frame = _SERVICE_FRAME.match(type_name)
    if frame is not None:
        # The frame's own block, then its payload's text: the payload is compiled, the frame
        # described from it as the runtime describes it.
        block_end = schema_text.find("\n}\n")
        if not schema_text.startswith(f"message {type_name} {{") or block_end < 0:
            raise SchemaError(f"the stored schema does not describe {type_name}")
        compiled, text = frame.group(2), schema_text[block_end + 3:]
    else:
        compiled, text = _compilable(type_name, schema_text)
    try:
        tree = generator.describe_schema_text(compiled, text)
    except generator.SchemaCompileError as error:
        first = (str(error).strip().splitlines() or ["(no message)"])[0]
        raise SchemaError(f"the stored schema of {type_name} does not compile: {first}") from None
    if frame is not None:
        tree = service_frame(tree, frame.group(1) == "Response")
        if tree["types"][-1]["schema"] != schema_text:
            raise SchemaError(f"the stored schema of {type_name} is not the runtime's frame of {compiled}")
    elif _RUNTIME_NAME.match(type_name) is not None:
        # Named and fingerprinted as the runtime describes its own types.
        tree["root"] = type_name
        tree["types"][-1].update(name=type_name, package="horus", schema=schema_text,
                                 fingerprint=f"0x{runtime_fingerprint(schema_text):016x}")
    return tree


def load_type(type_name: str, schema_text: str, fingerprint: int | None) -> type:
    """The class of `type_name` made from `schema_text` (as a segment stores it), checked to have
    `fingerprint` (None: the caller checks the identity another way). Kept for the process.
    Raises SchemaError."""
    key = (type_name, schema_text)
    with _loading:
        cls = _loaded.get(key)
        if cls is None:
            cls = _loaded[key] = message_class(_described(type_name, schema_text))
    if fingerprint is None:
        return cls
    actual = (runtime_fingerprint(schema_text) if _runtime_spelled(type_name, schema_text)
              else cls.__horus__.fingerprint)
    if actual != fingerprint:
        raise SchemaError(f"the stored schema of {type_name} gives fingerprint "
                          f"{actual:016x}, the segment says {fingerprint:016x}")
    return cls


def describe_files(paths: list[str], include_dirs: list[str] = ()) -> dict:
    """The description of every message, enum and service schema files declare (what `horus-gen
    describe --json` prints, less nodes and DDS names), compiled in process. Raises SchemaError
    with the first error line."""
    generator = _generator()
    try:
        return generator.describe_files(list(paths), list(include_dirs))
    except generator.SchemaCompileError as error:
        first = (str(error).strip().splitlines() or ["(no message)"])[0]
        raise SchemaError(f"the schemas do not compile: {first}") from None


# -- where horus-gen and the support module are ---------------------------------------------------

def _launcher_folders() -> list[str]:
    """Folders the horus-gen launcher (HORUS_GEN_PROGRAM, else `horus-gen` on PATH) names: its own
    (a checkout's generator/) and those it joins to it (the installed one states where the generator
    package and the support module are)."""
    program = os.environ.get("HORUS_GEN_PROGRAM") or shutil.which("horus-gen")
    if not program or not os.path.isfile(program):
        return []
    launcher = os.path.realpath(program)
    here = os.path.dirname(launcher)
    try:
        with open(launcher, encoding="utf-8") as handle:
            text = handle.read()
    except (OSError, UnicodeDecodeError):
        return [here]
    joined = re.findall(r'os\.path\.join\(here, "([^"]+)"\)', text)
    return [here] + [os.path.normpath(os.path.join(here, relative)) for relative in joined]


def _generator():
    """The horus_gen package: importable already, or found through the horus-gen launcher."""
    try:
        found = importlib.import_module("horus_gen")
    except ImportError:
        found = None
        for folder in _launcher_folders():
            if os.path.isfile(os.path.join(folder, "horus_gen", "__init__.py")):
                sys.path.append(folder)
                found = importlib.import_module("horus_gen")
                break
    if found is not None and not hasattr(found, "describe_schema_text"):
        raise SchemaError(f"the horus_gen package at {os.path.dirname(found.__file__)} is older than this horus "
                          "(it has no describe_schema_text): install the horus-gen of this version")
    if found is not None:
        return found
    raise SchemaError("cannot find horus-gen's Python package (horus_gen): put horus-gen on PATH or name it "
                      "with HORUS_GEN_PROGRAM")


_support_module = None


def support():
    """The support module of generated classes (_horus_gen_support_v1) of the contract these classes
    need: the one importable, else the copy beside horus-gen."""
    global _support_module
    if _support_module is not None:
        return _support_module
    try:
        found = importlib.import_module(_SUPPORT)
        if getattr(found, "CONTRACT_VERSION", None) == _SUPPORT_CONTRACT:
            _support_module = found
            return found
    except ImportError:
        pass
    for folder in _launcher_folders():
        for candidate in (os.path.join(folder, _SUPPORT + ".py"),
                          os.path.join(os.path.dirname(folder), "runtime", "python", _SUPPORT + ".py")):
            if os.path.isfile(candidate):
                spec = importlib.util.spec_from_file_location(f"{__name__}._support", candidate)
                module = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
                if getattr(module, "CONTRACT_VERSION", None) == _SUPPORT_CONTRACT:
                    _support_module = module
                    return module
    raise SchemaError(f"cannot find {_SUPPORT}.py of contract {_SUPPORT_CONTRACT} (generated packages hold it; "
                      "horus-gen installs it): put horus-gen on PATH or name it with HORUS_GEN_PROGRAM")
