"""JSON Schema spelling of the model (draft 2020-12): one `<Name>.schema.json` per message and
enum under `jsonschema/<package path>/` (a service gives its request and response messages).

A schema describes a message as JSON values (the HORUS recording export to Foxglove writes them):
an object per message with every field required, integers with their range, floats as numbers or
null (JSON has no NaN or infinity), strings, `bytes` and `Vec<u8>` as base64 strings, arrays (of exact length
for fixed arrays), an empty Option as null, an enum as its variant's name. Nested messages are
inlined, so each file stands alone (Foxglove reads one schema per channel).
"""
from __future__ import annotations

import json
import os

from ..data import DataPaths
from ..model import (Action, DynString, Enum, EnumRef, FixedArray, FixedString, Message, MessageRef,
                     Model, Node, Optional, Primitive, Service, Type, Vec)
from .common import environment
from .python import _is_bytes  # bytes and Vec<u8> are one thing on the wire, bytes in Python

DISPLAY_NAME = "JSON Schema"
KEYWORDS: frozenset[str] = frozenset()  # field names become JSON keys: any name suits
DIALECT = "https://json-schema.org/draft/2020-12/schema"


def reserved(name: str) -> str | None:
    return None


def schema_path(qualified: str) -> str:
    package, name = qualified.rsplit(".", 1)
    return os.path.join("jsonschema", *package.split("."), f"{name}.schema.json")


def _described(schema: dict, docs: tuple[str, ...], unit: str = "") -> dict:
    text = " ".join(line.strip() for line in docs if line.strip())
    if unit:
        text = f"{text} [{unit}]" if text else f"[{unit}]"
    if text:
        schema["description"] = text
    return schema


def _integer_range(primitive: Primitive) -> tuple[int, int]:
    bits = primitive.size * 8
    if primitive.is_signed:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return 0, (1 << bits) - 1


def type_schema(model: Model, spelled: Type) -> dict:
    """The JSON Schema of one value of a field's type."""
    if isinstance(spelled, Primitive):
        if spelled.is_bool:
            return {"type": "boolean"}
        if spelled.is_float:
            return {"type": ["number", "null"]}  # null: NaN or an infinity
        low, high = _integer_range(spelled)
        return {"type": "integer", "minimum": low, "maximum": high}
    if isinstance(spelled, (FixedString, DynString)):
        return {"type": "string"}
    if _is_bytes(spelled):
        return {"type": "string", "contentEncoding": "base64"}
    if isinstance(spelled, FixedArray):
        return {"type": "array", "items": type_schema(model, spelled.element),
                "minItems": spelled.length, "maxItems": spelled.length}
    if isinstance(spelled, Vec):
        return {"type": "array", "items": type_schema(model, spelled.element)}
    if isinstance(spelled, Optional):
        return {"anyOf": [type_schema(model, spelled.element), {"type": "null"}]}
    if isinstance(spelled, MessageRef):
        return message_schema(model, model.message(spelled.qualified))
    if isinstance(spelled, EnumRef):
        enum = model.types[spelled.qualified]
        assert isinstance(enum, Enum)
        return enum_schema(enum)
    raise TypeError(f"no JSON Schema for {spelled!r}")


def message_schema(model: Model, message: Message) -> dict:
    properties = {f.name: _described(type_schema(model, f.type), f.docs, f.unit) for f in message.fields}
    return _described({"title": message.qualified, "type": "object", "properties": properties,
                       "required": [f.name for f in message.fields], "additionalProperties": False},
                      message.docs)


def enum_schema(enum: Enum) -> dict:
    return _described({"title": enum.qualified, "type": "string",
                       "enum": [variant.name for variant in enum.variants]}, enum.docs)


def json_text(value: dict) -> str:
    return json.dumps(value, indent=2)


FILTERS = {"json_text": json_text, "basename": os.path.basename}


def emit(model: Model, data: DataPaths) -> dict[str, str]:
    env = environment(data, "jsonschema", FILTERS)
    files: dict[str, str] = {}
    for item in model.generated_items():
        if isinstance(item, (Node, Action)):
            continue  # no value any file or recording holds: an action's messages have their own
        messages = [item.request, item.response] if isinstance(item, Service) else [item]
        for declared in messages:
            if isinstance(declared, Enum):
                text = env.get_template("enum.schema.json.j2").render(
                    enum=declared, dialect=DIALECT, schema=enum_schema(declared))
            else:
                text = env.get_template("message.schema.json.j2").render(
                    message=declared, dialect=DIALECT, schema=message_schema(model, declared))
            files[schema_path(declared.qualified)] = text
    return files
