"""The type description (docs/type-description.md): the model's types as one versioned tree of plain
values, the intermediate form that tools, segments and links read instead of re-parsing schema text.

`describe --json` prints `model_description(model)`; generated code carries `carried_bytes(model,
qualified)`, the MessagePack bytes of one type's description (the type and every type it uses).
The tree is built here only, from the resolved model; the CLI and the emitters call these functions
and never assemble a part of it themselves.

The MessagePack encoding is written here rather than with the `msgpack` package, which horus-gen
does not otherwise need: the subset the tree uses (nil, booleans, integers, float64, strings,
arrays, maps) in its smallest forms, map keys in the order the tree gives them, so the same model
always gives the same bytes.
"""
from __future__ import annotations

import struct

from .model import (Action, Bytes, Constant, DynString, Enum, EnumRef, EnumValue, Field, FixedArray, FixedString,
                    Message, MessageRef, Model, Optional, Primitive, Service, SummaryExpr, SummaryPart, Type, Vec)

FORMAT = "horus.typedesc"
# Raised when a reader of version N could misread the tree (a key renamed or removed, a meaning
# changed); added keys keep the version, since readers ignore keys they do not know.
VERSION = 1


def type_tree(t: Type) -> dict:
    """TYPE: the recursive description of a field's or constant's type."""
    if isinstance(t, Primitive):
        return {"kind": "primitive", "name": t.name}
    if isinstance(t, FixedString):
        return {"kind": "string", "capacity": t.capacity}
    if isinstance(t, DynString):
        return {"kind": "string"}
    if isinstance(t, Bytes):
        return {"kind": "bytes"}
    if isinstance(t, FixedArray):
        return {"kind": "array", "element": type_tree(t.element), "length": t.length}
    if isinstance(t, Vec):
        return {"kind": "vec", "element": type_tree(t.element)}
    if isinstance(t, Optional):
        return {"kind": "optional", "element": type_tree(t.element)}
    if isinstance(t, MessageRef):
        return {"kind": "message", "name": t.qualified}
    if isinstance(t, EnumRef):
        return {"kind": "enum", "name": t.qualified}
    raise ValueError(t)


def value_tree(value) -> object:
    """VALUE: a default or constant as plain data; an enumerator as its name, an array as a list."""
    if isinstance(value, EnumValue):
        return value.variant
    if isinstance(value, tuple):
        return [value_tree(v) for v in value]
    return value


def _field(f: Field) -> dict:
    return {"name": f.name, "type": type_tree(f.type), "offset": f.offset, "size": f.size,
            "default": value_tree(f.default) if f.default is not None else None, "unit": f.unit,
            "spelling": f.spelling}


def _constant(c: Constant) -> dict:
    return {"name": c.name, "type": type_tree(c.type), "value": value_tree(c.value), "spelling": c.spelling}


def _expression(expr: SummaryExpr) -> dict:
    if expr.op == "field":
        return {"op": "field", "field": expr.field}
    if expr.op == "number":
        return {"op": "number", "number": expr.number}
    return {"op": expr.op, "operands": [_expression(e) for e in expr.operands]}


def _summary_part(part: SummaryPart) -> dict:
    if part.expression is not None:
        return {"expression": _expression(part.expression), "precision": part.precision}
    if part.field is None:
        return {"text": part.text}
    return {"field": part.field, "label": part.label, "unit": part.unit}


def _fingerprint(value: int) -> str:
    return f"0x{value:016x}"


def entry(item: Message | Enum | Service) -> dict:
    """ENTRY: one message, enum or service."""
    common = {"name": item.qualified, "package": item.package, "fingerprint": _fingerprint(item.fingerprint)}
    if isinstance(item, Service):
        return {"kind": "service", **common, "request": item.request.qualified,
                "response": item.response.qualified, "request_topic": item.request_topic,
                "response_topic": item.response_topic}
    if isinstance(item, Enum):
        return {"kind": "enum", **common, "underlying": item.underlying.name,
                "values": [{"name": v.name, "value": v.value} for v in item.variants], "schema": item.schema}
    return {"kind": "message", **common, "tier": "pod" if item.is_pod else "serialized",
            "size": item.size, "alignment": item.alignment,
            "fields": [_field(f) for f in item.fields],
            "constants": [_constant(c) for c in item.constants],
            "padding": [{"offset": p.offset, "size": p.size} for p in item.padding],
            "summary": [_summary_part(p) for p in item.summary],
            "topic": item.topic, "schema": item.schema}


def action_entry(action: Action) -> dict:
    """ENTRY (action): the action and the names of the services and topics that make it up."""
    return {"kind": "action", "name": action.qualified, "package": action.package,
            "fingerprint": _fingerprint(action.fingerprint), "goal": action.goal.qualified,
            "result": action.result.qualified, "feedback": action.feedback.qualified,
            "services": {role: {"name": s.wire_name, "type": s.qualified}
                         for role, s in zip(("send_goal", "cancel_goal", "get_result"), action.services)},
            "topics": {topic.rsplit(".", 1)[1]: {"name": topic, "type": m.qualified} for topic, m in action.topics},
            "docs": list(action.docs)}


def used_types(model: Model, qualified: str) -> list[str]:
    """`qualified` and every message and enum it uses, each once, a type after all it uses."""
    ordered: list[str] = []

    def visit(name: str) -> None:
        if name in ordered:
            return
        item = model.types[name]
        if isinstance(item, Message):
            for f in item.fields:
                for used in _named(f.type):
                    visit(used)
        ordered.append(name)

    visit(qualified)
    return ordered


def _named(t: Type) -> list[str]:
    if isinstance(t, (MessageRef, EnumRef)):
        return [t.qualified]
    if isinstance(t, (FixedArray, Vec, Optional)):
        return _named(t.element)
    return []


def type_description(model: Model, qualified: str) -> dict:
    """The carried form: the description of one message or enum and of everything it uses."""
    return {"format": FORMAT, "version": VERSION, "root": qualified,
            "types": [entry(model.types[name]) for name in used_types(model, qualified)]}


def model_description(model: Model, extra: dict[str, dict] | None = None) -> dict:
    """What `describe --json` prints: every message, enum, service and action the inputs declare, in
    source order (an action after the messages and services it owns, which name it in "action").
    `extra` adds keys to the entries it names (by qualified name)."""
    types = []
    for item in model.generated_items():
        if isinstance(item, Action):
            types.append(action_entry(item))
        elif isinstance(item, (Message, Enum, Service)):
            owner = {"action": item.action} if getattr(item, "action", None) else {}
            types.append({**entry(item), **owner, **(extra or {}).get(item.qualified, {})})
    return {"format": FORMAT, "version": VERSION, "types": types}


def carried_bytes(model: Model, qualified: str) -> bytes:
    """The MessagePack bytes generated code carries for the message or enum `qualified`."""
    return pack(type_description(model, qualified))


def pack(value) -> bytes:
    """MessagePack of a tree of None, bool, int, float, str, list and dict (keys in their order)."""
    out: list[bytes] = []
    _pack(value, out)
    return b"".join(out)


def _pack(value, out: list[bytes]) -> None:
    if value is None:
        out.append(b"\xc0")
    elif value is True or value is False:
        out.append(b"\xc3" if value else b"\xc2")
    elif isinstance(value, int):
        out.append(_pack_int(value))
    elif isinstance(value, float):
        out.append(b"\xcb" + struct.pack(">d", value))
    elif isinstance(value, str):
        data = value.encode("utf-8")
        out.append(_header(len(data), 0xA0, 31, b"\xd9", b"\xda", b"\xdb") + data)
    elif isinstance(value, (list, tuple)):
        out.append(_header(len(value), 0x90, 15, None, b"\xdc", b"\xdd"))
        for item in value:
            _pack(item, out)
    elif isinstance(value, dict):
        out.append(_header(len(value), 0x80, 15, None, b"\xde", b"\xdf"))
        for key, item in value.items():
            _pack(key, out)
            _pack(item, out)
    else:
        raise TypeError(f"no MessagePack form for {type(value).__name__} in a type description")


def _header(length: int, fix: int, fix_max: int, one: bytes | None, two: bytes, four: bytes) -> bytes:
    if length <= fix_max:
        return bytes([fix | length])
    if one is not None and length < 1 << 8:
        return one + struct.pack(">B", length)
    if length < 1 << 16:
        return two + struct.pack(">H", length)
    return four + struct.pack(">I", length)


def _pack_int(value: int) -> bytes:
    if 0 <= value < 0x80:
        return struct.pack(">B", value)
    if -32 <= value < 0:
        return struct.pack(">b", value)
    if value >= 0:
        for code, fmt, limit in ((b"\xcc", ">B", 1 << 8), (b"\xcd", ">H", 1 << 16), (b"\xce", ">I", 1 << 32),
                                 (b"\xcf", ">Q", 1 << 64)):
            if value < limit:
                return code + struct.pack(fmt, value)
    else:
        for code, fmt, limit in ((b"\xd0", ">b", 1 << 7), (b"\xd1", ">h", 1 << 15), (b"\xd2", ">i", 1 << 31),
                                 (b"\xd3", ">q", 1 << 63)):
            if value >= -limit:
                return code + struct.pack(fmt, value)
    raise ValueError(f"{value} does not fit 64 bits")
