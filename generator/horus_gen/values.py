"""Values written in schemas: attribute values checked against what each declaration accepts, and
literals (defaults, constants) checked and converted to the type they initialise."""
from __future__ import annotations

import math

from . import identity
from .diagnostics import Reporter, did_you_mean
from .model import (PRIMITIVES, DynString, Enum, EnumRef, EnumValue, FixedArray, FixedString, Message,
                    Primitive, Type, Value)
from .syntax import Attribute, Literal

INTEGER_RANGES = {p.name: ((-(1 << (p.size * 8 - 1)), (1 << (p.size * 8 - 1)) - 1) if p.is_signed
                           else (0, (1 << (p.size * 8)) - 1))
                  for p in PRIMITIVES.values() if p.is_integer}
F32_MAX = 3.4028234663852886e38


def is_constant_type(t: Type) -> bool:
    return isinstance(t, (Primitive, FixedString, DynString, EnumRef))


def check_attributes(reporter: Reporter, attributes: tuple[Attribute, ...], allowed: dict[str, str], owner: str) -> dict:
    found: dict[str, object] = {}
    for attribute in attributes:
        kind = allowed.get(attribute.name)
        if kind is None:
            if allowed:
                hint = did_you_mean(attribute.name, list(allowed)) or \
                    "known here: " + ", ".join(f"#[{a}]" for a in sorted(allowed))
            else:
                hint = f"{owner} takes no attributes"
            reporter.error(attribute.span, f"unknown attribute '{attribute.name}' on {owner}", hint)
            continue
        if attribute.value is not None and attribute.value.kind == "list" and kind != "list":
            reporter.error(attribute.span, f"attribute '{attribute.name}' takes '= value', not a list",
                           f'write #[{attribute.name} = "..."]' if kind != "flag" else f"write #[{attribute.name}]")
            continue
        if kind == "list":
            if attribute.value is None or attribute.value.kind != "list":
                reporter.error(attribute.span, f"attribute '{attribute.name}' takes a list of names",
                               f"write #[{attribute.name}(Debug, Clone)]")
                continue
            found.setdefault(attribute.name, []).extend(attribute.value.value)
            continue
        if kind == "flag":
            if attribute.value is not None:
                reporter.error(attribute.span, f"attribute '{attribute.name}' takes no value",
                                    f"write #[{attribute.name}]")
            found[attribute.name] = True
            continue
        if attribute.value is None or attribute.value.kind != "string":
            reporter.error(attribute.span, f"attribute '{attribute.name}' needs a string value",
                                f'write #[{attribute.name} = "..."]')
            continue
        if kind == "strings":
            found.setdefault(attribute.name, []).append(attribute.value.value)
        elif attribute.name in found:
            reporter.error(attribute.span, f"attribute '{attribute.name}' is given twice on {owner}")
        else:
            found[attribute.name] = attribute.value.value
    return found


# The derives of the Rust structs and enums that schemas come from, and why each holds of the generated
# type as it is: a derive is accepted and changes nothing. A derive of neither list is an error.
DERIVES = {
    "Debug": "log_summary() prints it, and Python's repr()",
    "Clone": "C++ copies it, and Python's copy.copy()",
    "Copy": "a POD message or an enum is trivially copyable",
    "PartialEq": "operator== in C++, == in Python",
    "Eq": "operator== in C++, == in Python",
    "Default": "a value-initialised message holds zeros or the schema's defaults",
    "Serialize": "horus::encode() in C++, to_bytes() in Python",
    "Deserialize": "horus::decode() in C++, from_bytes() in Python",
    "LogSummary": "log_summary() in C++ and Python (the default line, or #[summary])",
}
# What only an enum is: ordered and hashable (enum class in C++, enum.IntEnum in Python).
ENUM_DERIVES = {"Hash": "std::hash in C++, hash() in Python",
                "PartialOrd": "< in C++ and Python", "Ord": "< in C++ and Python"}


def check_derives(reporter: Reporter, derives: list[Literal], owner: str, is_enum: bool, is_pod: bool) -> None:
    """Reports each derive that the generated type does not already satisfy."""
    known = DERIVES | ENUM_DERIVES if is_enum else DERIVES
    for derive in derives:
        name = derive.value[-1]
        if name in known:
            if name == "Copy" and not is_pod:
                reporter.error(derive.span, f"{owner} derives Copy, but it is serialized: it holds a String, "
                               "bytes, Vec or Option", "remove Copy, or give the message fixed-size fields only")
        elif name in ENUM_DERIVES:
            reporter.error(derive.span, f"derive '{name}' of {owner} is not generated",
                           "generated messages have equality, but no hash or order; remove it")
        else:
            reporter.error(derive.span, f"unknown derive '{'::'.join(derive.value)}' on {owner}",
                           did_you_mean(name, list(known)) or "horus-gen knows " + ", ".join(sorted(known)))


def convert_value(reporter: Reporter, types: dict[str, Message | Enum], literal: Literal, t: Type,
                  owner: str) -> Value | None:
    """`literal` as a value of `t` (types: the model's types, for enumerations), or None after
    reporting why it is not one."""
    spelled = identity.spelling(t)
    wrong = f"{owner} has type '{spelled}', but its value is "

    def error(message: str, hint: str | None = None) -> None:
        reporter.error(literal.span, message, hint)

    if isinstance(t, Primitive):
        if t.is_bool:
            if literal.kind == "bool":
                return literal.value
            error(wrong + _describe(literal), "write true or false")
            return None
        if literal.kind not in ("int", "float"):
            error(wrong + _describe(literal))
            return None
        if t.is_integer:
            if literal.kind == "float":
                error(wrong + f"the non-integer {literal.value}", "write a whole number, or make it f32/f64")
                return None
            low, high = INTEGER_RANGES[t.name]
            if not low <= literal.value <= high:
                error(f"value {literal.value} of {owner} is out of range for {t.name} ({low}..{high})")
                return None
            return literal.value
        value = float(literal.value)  # the lexer's length limit keeps integers within a double's range
        if not math.isfinite(value):
            error(f"value {literal.value} of {owner} is out of range for {t.name}")
            return None
        if t.name == "f32" and abs(value) > F32_MAX:
            error(f"value {literal.value} of {owner} is out of range for f32 (about ±3.4e38)",
                  "use f64 for larger values")
            return None
        return value
    if isinstance(t, (FixedString, DynString)):
        if literal.kind != "string":
            error(wrong + _describe(literal), 'write a quoted string: "text"')
            return None
        if "\0" in literal.value:
            # C++ would initialise from the literal as a C string, ending it at the NUL, while
            # Python keeps the whole text: the two languages' defaults would differ.
            error(f"value of {owner} holds a NUL character, which {spelled} values cannot hold",
                  "text ends at its first NUL; use bytes for binary data")
            return None
        if isinstance(t, FixedString) and len(literal.value.encode("utf-8")) > t.capacity:
            error(f"value of {owner} is {len(literal.value.encode('utf-8'))} bytes, more than "
                  f"string<{t.capacity}> holds")
            return None
        return literal.value
    if isinstance(t, EnumRef):
        enum = types.get(t.qualified)
        if not isinstance(enum, Enum):
            return None
        if literal.kind != "path" or (len(literal.value) > 1 and literal.value[-2] != enum.name):
            error(wrong + _describe(literal), f"write {enum.name}::{enum.variants[0].name}" if enum.variants else None)
            return None
        variant = next((v for v in enum.variants if v.name == literal.value[-1]), None)
        if variant is None:
            error(f"'{literal.value[-1]}' is not an enumerator of '{enum.name}'",
                  did_you_mean(literal.value[-1], [v.name for v in enum.variants]))
            return None
        return EnumValue(enum.qualified, variant.name, variant.value)
    if isinstance(t, FixedArray) and is_constant_type(t.element):
        if literal.kind != "list":
            error(wrong + _describe(literal), f"write a list of {t.length} values: [a, b, ...]")
            return None
        if len(literal.value) != t.length:
            error(f"{owner} has {t.length} elements, but its value lists {len(literal.value)}")
            return None
        items = [convert_value(reporter, types, v, t.element, owner) for v in literal.value]
        return None if any(v is None for v in items) else tuple(items)
    error(f"{owner} of type '{spelled}' cannot have a default value",
          "defaults are for numbers, bool, enums, strings and fixed arrays of those")
    return None


def _describe(literal: Literal) -> str:
    if literal.kind == "path":
        return f"the name '{'::'.join(literal.value)}'"
    if literal.kind == "list":
        return "a list"
    return f"the {literal.kind} {literal.value!r}"
