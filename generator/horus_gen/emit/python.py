"""Python spelling of the model: codecs, literals, struct formats, module paths, type hints.

Every generated package `a.b` is `python/a/b/__init__.py` re-exporting one private module per type
(`_motor_feedback.py`); the support code the classes share is one module at the root of the output,
`_horus_gen_support_v1.py`, whose text never depends on the schemas (two output roots on sys.path
hold the same file). No `__init__.py` is written above a package, so `a` stays a namespace package
that other output roots, and a hand-written `horus` package, can share.
"""
from __future__ import annotations

import os
import struct

from . import banner, environment
from ..model import (Bytes, DynString, Enum, EnumRef, EnumValue, Field, FixedArray, FixedString, Message,
                     MessageRef, Model, Optional, Primitive, Service, Type, Vec)
from ..names import snake_case

SUPPORT_MODULE = "_horus_gen_support_v1"

STRUCT_CODES = {"bool": "?", "u8": "B", "u16": "H", "u32": "I", "u64": "Q",
                "i8": "b", "i16": "h", "i32": "i", "i64": "q", "f32": "f", "f64": "d"}
PRIMITIVE_CODECS = {"bool": "BOOL", "u8": "U8", "u16": "U16", "u32": "U32", "u64": "U64",
                    "i8": "I8", "i16": "I16", "i32": "I32", "i64": "I64", "f32": "F32", "f64": "F64"}
PRIMITIVE_HINTS = {"bool": "bool", "f32": "float", "f64": "float"}


def module_name(qualified: str) -> str:
    """The private module that holds a type: test_msgs.Pose2 -> test_msgs._pose2."""
    package, name = qualified.rsplit(".", 1)
    return f"{package}._{snake_case(name)}"


def module_path(qualified: str) -> str:
    return module_name(qualified).replace(".", "/") + ".py"


class Names:
    """The local Python name of every type a module refers to, with the imports that bind them.

    Types of the module's own package keep their names; a type of another package whose name is
    taken here is imported under an alias made from its package."""

    def __init__(self, package: str, own: str, uses: list[str]) -> None:
        taken = {own}
        self.local: dict[str, str] = {}
        for q in uses:
            if q.rsplit(".", 1)[0] == package:
                self.local[q] = q.rsplit(".", 1)[1]
                taken.add(self.local[q])
        for q in uses:
            if q in self.local:
                continue
            short = q.rsplit(".", 1)[1]
            self.local[q] = short if short not in taken else "_" + q.replace(".", "_")
            taken.add(self.local[q])
        self.package = package

    def __getitem__(self, qualified: str) -> str:
        return self.local[qualified]

    def imports(self) -> list[str]:
        lines = []
        for q, local in self.local.items():
            owner, short = q.rsplit(".", 1)
            source = "." + module_name(q).rsplit(".", 1)[1] if owner == self.package else module_name(q)
            lines.append(f"from {source} import {short}" + (f" as {local}" if local != short else ""))
        return lines


def _dims(t: FixedArray) -> tuple[tuple[int, ...], Type]:
    shape: list[int] = []
    inner: Type = t
    while isinstance(inner, FixedArray):
        shape.append(inner.length)
        inner = inner.element
    return tuple(shape), inner


def is_num_array(t: Type) -> bool:
    """A fixed array whose innermost element is a number or bool: a numpy array in Python."""
    return isinstance(t, FixedArray) and isinstance(_dims(t)[1], Primitive)


def codec(t: Type, model: Model, names: Names, default=None) -> str:
    """The support-module expression that encodes, decodes and summarises values of `t`."""
    if isinstance(t, Primitive):
        return "_s." + PRIMITIVE_CODECS[t.name]
    if isinstance(t, FixedString):
        return f"_s.FixedStr({t.capacity})"
    if isinstance(t, DynString):
        return "_s.STR"
    if _is_bytes(t):
        return "_s.BYTES"
    if isinstance(t, EnumRef):
        found = model.types[t.qualified]
        assert isinstance(found, Enum)
        return f"_s.Enum({names[t.qualified]}, _s.{PRIMITIVE_CODECS[found.underlying.name]})"
    if isinstance(t, MessageRef):
        return f"_s.Nested({names[t.qualified]})"
    if isinstance(t, FixedArray):
        initial = "" if default is None else ", " + value_literal(default, t, model, names)
        shape, inner = _dims(t)
        if isinstance(inner, Primitive):
            return f"_s.NumArray({codec(inner, model, names)}, {shape!r}{initial})"
        return f"_s.ListArray({codec(t.element, model, names)}, {t.length}{initial})"
    if isinstance(t, Vec):
        return f"_s.Vec({codec(t.element, model, names)})"
    if isinstance(t, Optional):
        return f"_s.Option({codec(t.element, model, names)})"
    raise ValueError(t)


def float_literal(value: float, single: bool) -> str:
    """The exact value C++ holds: an f32 literal is rounded to single precision first."""
    if single:
        value = struct.unpack("<f", struct.pack("<f", value))[0]
    if value != value:
        return "float('nan')"
    if value in (float("inf"), float("-inf")):
        return "float('inf')" if value > 0 else "-float('inf')"
    return repr(float(value))


def value_literal(value, t: Type, model: Model, names: Names) -> str:
    if isinstance(t, Primitive):
        if t.is_bool:
            return "True" if value else "False"
        if t.is_float:
            return float_literal(float(value), t.name == "f32")
        return str(int(value))
    if isinstance(t, EnumRef):
        assert isinstance(value, EnumValue)
        return f"{names[t.qualified]}.{value.variant}"
    if isinstance(t, (FixedString, DynString)):
        return repr(value)
    if isinstance(t, FixedArray):
        items = [value_literal(v, t.element, model, names) for v in value]
        return "(" + ", ".join(items) + ("," if len(items) == 1 else "") + ")"
    raise ValueError(t)


def hint(t: Type, names: Names) -> str:
    """The type of the attribute as Python sees it after construction or decoding."""
    if isinstance(t, Primitive):
        return PRIMITIVE_HINTS.get(t.name, "int")
    if isinstance(t, (FixedString, DynString)):
        return "str"
    if _is_bytes(t):
        return "bytes"
    if isinstance(t, (EnumRef, MessageRef)):
        return names[t.qualified]
    if isinstance(t, FixedArray):
        return "numpy.ndarray" if is_num_array(t) else f"list[{hint(t.element, names)}]"
    if isinstance(t, Vec):
        return f"list[{hint(t.element, names)}]"
    if isinstance(t, Optional):
        return f"{hint(t.element, names)} | None"
    raise ValueError(t)


def _is_bytes(t: Type) -> bool:
    """bytes and Vec<u8>: both std::vector<std::uint8_t> in C++, bytes in Python."""
    return isinstance(t, Bytes) or (isinstance(t, Vec) and isinstance(t.element, Primitive) and t.element.name == "u8")


def needs_factory(f: Field) -> bool:
    """Whether the default is a fresh mutable object made in __init__ (arrays, lists, messages)."""
    return isinstance(f.type, (FixedArray, Vec, MessageRef)) and not _is_bytes(f.type)


def parameter(f: Field, model: Model, names: Names) -> str:
    """The keyword parameter of __init__ for a field."""
    t = f.type
    if needs_factory(f):
        if is_num_array(t):
            accepted = "numpy.typing.ArrayLike"
        elif isinstance(t, MessageRef):
            accepted = names[t.qualified]
        else:
            accepted = hint(t, names).replace("list[", "Sequence[", 1)
        return f"{f.name}: {accepted} | None = None"
    if f.default is not None:
        default = value_literal(f.default, t, model, names)
    elif isinstance(t, Primitive):
        default = "False" if t.is_bool else ("0.0" if t.is_float else "0")
    elif isinstance(t, (FixedString, DynString)):
        default = '""'
    elif _is_bytes(t):
        default = 'b""'
    elif isinstance(t, EnumRef):
        found = model.types[t.qualified]
        assert isinstance(found, Enum)
        zero = next((v.name for v in found.variants if v.value == 0), None)
        default = f"{names[t.qualified]}.{zero}" if zero else "0"
    elif isinstance(t, Optional):
        default = "None"
    else:
        raise ValueError(t)
    accepted = hint(t, names) + (" | int" if isinstance(t, EnumRef) else "")
    return f"{f.name}: {accepted} = {default}"


def initializer(f: Field, names: Names) -> str:
    """The right-hand side that stores a factory-made field in __init__."""
    if isinstance(f.type, MessageRef):
        local = names[f.type.qualified]
        return f"{local}() if {f.name} is None else {f.name}"
    if isinstance(f.type, Vec):
        return f"[] if {f.name} is None else {f.name}"
    return f"_c_{f.name}.default() if {f.name} is None else _c_{f.name}.coerce({f.name})"


# -- POD struct bytes -----------------------------------------------------------------------------

def _is_scalar(t: Type) -> bool:
    return isinstance(t, (Primitive, EnumRef, FixedString))


def _struct_code(t: Type, model: Model) -> str:
    if isinstance(t, Primitive):
        return STRUCT_CODES[t.name]
    if isinstance(t, EnumRef):
        found = model.types[t.qualified]
        assert isinstance(found, Enum)
        return STRUCT_CODES[found.underlying.name]
    assert isinstance(t, FixedString)
    return f"{t.capacity}s"


def raw_format(message: Message, model: Model) -> str:
    """struct format of the message's scalar fields at their offsets; padding and the bytes of
    arrays and nested messages are 'x' (written as zeros, then by their own statements)."""
    assert message.size is not None
    codes, cursor = ["<"], 0
    for f in message.fields:
        assert f.offset is not None and f.size is not None
        if f.offset > cursor:
            codes.append(f"{f.offset - cursor}x")
        codes.append(_struct_code(f.type, model) if _is_scalar(f.type) else f"{f.size}x")
        cursor = f.offset + f.size
    if message.size > cursor:
        codes.append(f"{message.size - cursor}x")
    merged: list[str] = []
    for code in codes:  # "24x12x" -> "36x"
        if code.endswith("x") and merged and merged[-1].endswith("x") and merged[-1][:-1].isdigit():
            merged[-1] = f"{int(merged[-1][:-1]) + int(code[:-1])}x"
        else:
            merged.append(code)
    return "".join(merged)


def scalar_fields(message: Message) -> list[Field]:
    return [f for f in message.fields if _is_scalar(f.type)]


def other_fields(message: Message) -> list[Field]:
    return [f for f in message.fields if not _is_scalar(f.type)]


def raw_store(f: Field) -> str:
    """The value struct packs for a scalar field."""
    return f"_c_{f.name}.raw(self.{f.name})" if isinstance(f.type, FixedString) else f"self.{f.name}"


def raw_load(f: Field, index: int) -> str:
    """The attribute value made from the struct-unpacked tuple `v`."""
    if isinstance(f.type, (FixedString, EnumRef)):
        return f"_c_{f.name}.from_raw(v[{index}])"
    return f"v[{index}]"


def raw_write(f: Field, names: Names) -> str:
    """The statement that writes a non-scalar field into `buf` at `off`."""
    if isinstance(f.type, MessageRef):
        return f"self.{f.name}._horus_pack_into(buf, off + {f.offset})"
    if is_num_array(f.type):
        return f"buf[off + {f.offset}:off + {f.offset + f.size}] = _c_{f.name}.raw(self.{f.name})"
    return f"_c_{f.name}.raw_into(buf, off + {f.offset}, self.{f.name})"


def raw_read(f: Field, names: Names) -> str:
    if isinstance(f.type, MessageRef):
        return f"{names[f.type.qualified]}._horus_unpack_from(buf, off + {f.offset})"
    return f"_c_{f.name}.raw_from(buf, off + {f.offset})"


# -- text -----------------------------------------------------------------------------------------

def docstring(lines: tuple[str, ...] | list[str], indent: str = "") -> str:
    """A triple-quoted docstring of `lines` (escaped), indented for its place."""
    escaped = [line.replace("\\", "\\\\").replace('"""', '\\"\\"\\"') for line in lines]
    if not escaped:
        return '""""""'
    if len(escaped) == 1:
        text = escaped[0]
        return f'"""{text}"""' if not text.endswith('"') else f'"""{text} """'
    body = "\n".join((indent + line).rstrip() for line in escaped[1:])
    return f'"""{escaped[0]}\n{body}\n{indent}"""'


def class_doc(message: Message) -> list[str]:
    lines = list(message.docs) or [f"The {message.qualified} message."]
    documented = [f for f in message.fields if f.docs or f.unit]
    if documented:
        lines += ["", "Attributes:"]
        for f in documented:
            text = " ".join(list(f.docs) + ([f"[{f.unit}]"] if f.unit else []))
            lines.append(f"    {f.name}: {text}")
    return lines


def summary_table(message: Message) -> str:
    """The log-summary parts as (text, field index, element label, unit) tuples."""
    index = {f.name: i for i, f in enumerate(message.fields)}
    rows = []
    for part in message.summary:
        if part.field is None:
            rows.append(f"({part.text!r}, None, '', '')")
        else:
            rows.append(f"('', {index[part.field]}, {part.label!r}, {part.unit!r})")
    return "(" + "".join(r + ", " for r in rows) + ")"


def string_literal(text: str) -> str:
    return repr(text)


FILTERS = {
    "codec": codec, "value_literal": value_literal, "float_literal": float_literal, "hint": hint,
    "parameter": parameter, "initializer": initializer, "needs_factory": needs_factory,
    "raw_format": raw_format, "scalar_fields": scalar_fields, "other_fields": other_fields,
    "raw_store": raw_store, "raw_load": raw_load, "raw_write": raw_write, "raw_read": raw_read,
    "docstring": docstring, "class_doc": class_doc, "summary_table": summary_table,
    "string_literal": string_literal, "hex": lambda n: f"0x{n:016x}",
}


def emit(model: Model) -> dict[str, str]:
    env = environment("python", FILTERS)
    files: dict[str, str] = {}
    exports: dict[str, list[tuple[str, str]]] = {}  # package -> (module, class name)
    for item in model.generated_items():
        path = os.path.join("python", module_path(item.qualified))
        common = {"banner": banner("#", [item.source]), "support": SUPPORT_MODULE, "model": model}
        if isinstance(item, Service):
            names = Names(item.package, item.name, [item.request.qualified, item.response.qualified])
            text = env.get_template("service.py.j2").render(service=item, names=names, **common)
        elif isinstance(item, Enum):
            text = env.get_template("enum.py.j2").render(enum=item, **common)
        else:
            names = Names(item.package, item.name, list(item.uses))
            mixin = None
            if item.py_mixin is not None:
                mixin = os.path.splitext(os.path.basename(item.py_mixin.output_path))[0]
                mixin_path = os.path.join("python", item.py_mixin.output_path)
                if mixin_path == path:
                    raise ValueError(f"{item.qualified}: the mixin file {item.py_mixin.output_path} "
                                     "collides with a generated module")
                if mixin_path not in files:  # messages that share a helper module share one copy
                    with open(item.py_mixin.source_path, encoding="utf-8") as handle:
                        files[mixin_path] = handle.read()
            text = env.get_template("message.py.j2").render(message=item, names=names, mixin=mixin, **common)
        if path in files:
            raise ValueError(f"{item.qualified}: module {path} is generated twice (two names with one snake_case)")
        files[path] = text
        exports.setdefault(item.package, []).append((module_name(item.qualified).rsplit(".", 1)[1], item.name))
    for package, members in exports.items():
        folder = os.path.join("python", *package.split("."))
        sources = [i.source for i in model.generated_items() if i.package == package]
        files[os.path.join(folder, "__init__.py")] = env.get_template("package.py.j2").render(
            banner=banner("#", sources), package=package, members=sorted(members, key=lambda m: m[1]))
        files[os.path.join(folder, "py.typed")] = ""
    if exports:
        files[os.path.join("python", SUPPORT_MODULE + ".py")] = env.get_template("support.py.j2").render(
            module=SUPPORT_MODULE)
    return files
