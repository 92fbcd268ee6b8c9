"""A node's `params { }` block checked and resolved into model.NodeParam.

Everything the runtime would refuse when the node declares its parameters (horus/params.hpp:
a type it cannot hold, a default outside its own range or choices, a value over
kMaxParamValueBytes) is an error here, at the line that says it, so that a generated node never
throws ParamError from its constructor.
"""
from __future__ import annotations

import re
import struct
from typing import TYPE_CHECKING

from . import identity
from .diagnostics import Note, Reporter, did_you_mean
from .model import DynString, EnumRef, FixedArray, Model, NodeParam, Primitive, Type, Value
from .syntax import Attribute, FieldDecl, Literal
from .values import convert_value

if TYPE_CHECKING:
    from .loader import Unit
    from .resolve import Resolver

# horus::ParamDeclaration::name.
PARAM_NAME = re.compile(r"[a-z_][a-z0-9_]{0,62}")
# horus::kMaxParamValueBytes: the most bytes a String or fixed-array parameter holds.
MAX_PARAM_VALUE_BYTES = 256
PARAM_ATTRIBUTES = ("min", "max", "choices", "unit", "read_only")
TYPE_RULE = ("a parameter is a number, bool, String, enum or fixed array of numbers or bool "
             f"(at most {MAX_PARAM_VALUE_BYTES} bytes)")


def _is_number(t: Type) -> bool:
    return isinstance(t, Primitive) and not t.is_bool


def _numbers_of(t: Type) -> Primitive | None:
    """The number type that #[min]/#[max] bound: the parameter's own, or its array's element's."""
    element = t.element if isinstance(t, FixedArray) else t
    return element if _is_number(element) else None


class ParamResolver:
    def __init__(self, resolver: "Resolver"):
        self.resolver = resolver
        self.reporter: Reporter = resolver.reporter
        self.model: Model = resolver.model

    def build(self, node: str, field: FieldDecl, unit: "Unit") -> NodeParam | None:
        """The parameter `field` declares, or None after reporting every error of it."""
        owner = f"parameter '{field.name}'"
        if not PARAM_NAME.fullmatch(field.name):
            self.reporter.error(field.span, f"parameter name '{field.name}' is not lower_snake_case of at most "
                                "63 bytes", "a parameter name is what `horus param` and YAML files spell: "
                                "a-z, 0-9 and _, not starting with a digit")
        elif field.name.endswith("_"):
            self.reporter.error(field.span, f"parameter name '{field.name}' ends with '_'",
                                f"generated C++ keeps parameter '{field.name[:-1]}' in a member named so; rename it")
        attributes = self.attributes(field)
        t = self.resolver.resolve_type(field.type, unit)
        if t is None:
            return None
        if not self.allowed_type(field, t):
            return None
        if field.default is None:
            self.reporter.error(field.span, f"{owner} of node '{node}' has no default value",
                                "a parameter starts at its default: write "
                                f"{field.name}: {identity.spelling(t)} = ...")
            return None
        default = convert_value(self.reporter, self.model.types, field.default, t, owner)
        if default is None:
            return None
        if isinstance(t, DynString) and len(default.encode("utf-8")) > MAX_PARAM_VALUE_BYTES:
            self.reporter.error(field.default.span, f"default of {owner} is {len(default.encode('utf-8'))} "
                                f"bytes, more than a parameter holds ({MAX_PARAM_VALUE_BYTES})")
            return None
        errors_before = len(self.reporter.diagnostics)
        minimum = self.bound(field, t, attributes.get("min"))
        maximum = self.bound(field, t, attributes.get("max"))
        if minimum is not None and maximum is not None and minimum > maximum:
            self.reporter.error(attributes["max"].span, f"{owner} has #[min = {minimum}] above #[max = {maximum}]",
                                "the bounds are inclusive: min <= max",
                                (Note(attributes["min"].span, "min given here"),))
        choices = self.choices(field, t, attributes.get("choices"))
        unit_attribute = attributes.get("unit")
        unit_text = ""
        if unit_attribute is not None:
            if unit_attribute.value is None or unit_attribute.value.kind != "string":
                self.reporter.error(unit_attribute.span, "attribute 'unit' needs a string value",
                                    'write #[unit = "m/s"]')
            elif any(not c.isprintable() for c in unit_attribute.value.value):
                self.reporter.error(unit_attribute.value.span, "#[unit] holds a line break or another control "
                                    "character", "a unit is a short word shown beside the value: m/s, rad, ms")
            else:
                unit_text = unit_attribute.value.value
        read_only = attributes.get("read_only")
        if read_only is not None and read_only.value is not None:
            self.reporter.error(read_only.span, "attribute 'read_only' takes no value",
                                "write #[read_only]: the parameter keeps the value it starts with")
        if len(self.reporter.diagnostics) > errors_before:
            return None
        self.check_default(field, t, default, minimum, maximum, choices, attributes)
        if len(self.reporter.diagnostics) > errors_before:
            return None
        return NodeParam(field.name, t, identity.spelling(t), default, minimum, maximum, choices, unit_text,
                         field.docs, read_only is not None, field.span)

    def attributes(self, field: FieldDecl) -> dict[str, Attribute]:
        found: dict[str, Attribute] = {}
        for attribute in field.attributes:
            if attribute.name not in PARAM_ATTRIBUTES:
                self.reporter.error(attribute.span, f"unknown attribute '{attribute.name}' on parameter '{field.name}'",
                                    did_you_mean(attribute.name, list(PARAM_ATTRIBUTES))
                                    or "known here: " + ", ".join(f"#[{a}]" for a in PARAM_ATTRIBUTES))
            elif attribute.name in found:
                self.reporter.error(attribute.span, f"attribute '{attribute.name}' is given twice on parameter "
                                    f"'{field.name}'", "keep one",
                                    (Note(found[attribute.name].span, "first given here"),))
            else:
                found[attribute.name] = attribute
        return found

    def allowed_type(self, field: FieldDecl, t: Type) -> bool:
        element = t.element if isinstance(t, FixedArray) else t
        fits = isinstance(t, (Primitive, DynString, EnumRef)) or isinstance(element, Primitive)
        if fits and isinstance(t, FixedArray):
            size = t.length * element.size
            if size > MAX_PARAM_VALUE_BYTES:
                self.reporter.error(field.type.span, f"parameter '{field.name}' of type '{identity.spelling(t)}' "
                                    f"is {size} bytes, more than a parameter holds ({MAX_PARAM_VALUE_BYTES})",
                                    "use data { } or a topic for bulk values")
                return False
        if not fits:
            self.reporter.error(field.type.span, f"parameter '{field.name}' has type '{identity.spelling(t)}'",
                                f"{TYPE_RULE}; use data {{ }} for other state, a topic for messages")
        return fits

    def bound(self, field: FieldDecl, t: Type, attribute: Attribute | None) -> float | int | None:
        if attribute is None:
            return None
        number = _numbers_of(t)
        if number is None:
            self.reporter.error(attribute.span, f"#[{attribute.name}] on parameter '{field.name}' of type "
                                f"'{identity.spelling(t)}', which is not a number",
                                "#[min] and #[max] bound numbers (and each element of an array of numbers); "
                                "#[choices = [...]] limits other types")
            return None
        value = attribute.value
        if value is None or value.kind not in ("int", "float"):
            self.reporter.error(attribute.span, f"#[{attribute.name}] needs a number",
                                f"write #[{attribute.name} = 0.5]")
            return None
        bound = convert_value(self.reporter, self.model.types, value, number,
                              f"#[{attribute.name}] of parameter '{field.name}'")
        return None if bound is None else _as_stored(bound, number)  # type: ignore[arg-type]

    def choices(self, field: FieldDecl, t: Type, attribute: Attribute | None) -> tuple[Value, ...]:
        if attribute is None:
            return ()
        value = attribute.value
        if value is None or value.kind != "list" or not value.value:
            self.reporter.error(attribute.span, "#[choices] needs a list of the allowed values",
                                'write #[choices = ["eco", "sport"]]')
            return ()
        if isinstance(t, Primitive) and t.is_bool:
            self.reporter.error(attribute.span, f"#[choices] on bool parameter '{field.name}'",
                                "a bool has two values; remove it")
            return ()
        found: list[Value] = []
        for item in value.value:
            converted = convert_value(self.reporter, self.model.types, item, t, f"choice of parameter '{field.name}'")
            if converted is None:
                continue
            if converted in found:
                self.reporter.error(item.span, f"choice {_shown(item)} of parameter '{field.name}' is listed twice")
                continue
            found.append(converted)
        return tuple(found)

    def check_default(self, field: FieldDecl, t: Type, default: Value, minimum, maximum,
                      choices: tuple[Value, ...], attributes: dict[str, Attribute]) -> None:
        literal = field.default
        assert literal is not None
        items = list(zip(literal.value, default)) if isinstance(t, FixedArray) else [(literal, default)]
        number = _numbers_of(t)
        for item, value in items:
            if number is not None:
                value = _as_stored(value, number)
            if minimum is not None and value < minimum:
                self.reporter.error(item.span, f"default {_shown(item)} of parameter '{field.name}' is below its "
                                    f"#[min = {minimum}]", notes=(Note(attributes["min"].span, "min given here"),))
            elif maximum is not None and value > maximum:
                self.reporter.error(item.span, f"default {_shown(item)} of parameter '{field.name}' is above its "
                                    f"#[max = {maximum}]", notes=(Note(attributes["max"].span, "max given here"),))
        if choices and default not in choices:
            self.reporter.error(literal.span, f"default {_shown(literal)} of parameter '{field.name}' is not "
                                "among its #[choices]", "add it to the choices, or choose one of them",
                                (Note(attributes["choices"].span, "choices given here"),))
        if choices and number is not None:
            for item in attributes["choices"].value.value:
                numbers = item.value if item.kind == "list" else (item,)
                for choice in numbers:
                    stored = _as_stored(choice.value, number)
                    if (minimum is not None and stored < minimum) or (maximum is not None and stored > maximum):
                        self.reporter.error(choice.span, f"choice {_shown(choice)} of parameter '{field.name}' is "
                                            "outside its #[min]/#[max]", "a value must satisfy both")


def _as_stored(value: float | int, number: Primitive) -> float | int:
    """`value` as a parameter of type `number` holds it: an f32 rounded to single precision, so
    that a bound and the values checked against it (in C++, Python and here) are the same
    numbers (#[max = 0.1] on an f32 is 0.1f, which a default 0.1 then equals)."""
    if number.name == "f32":
        return struct.unpack("<f", struct.pack("<f", float(value)))[0]
    return value


def _shown(literal: Literal) -> str:
    if literal.kind == "path":
        return "::".join(literal.value)
    if literal.kind == "string":
        return repr(literal.value).replace("'", '"')
    if literal.kind == "bool":
        return "true" if literal.value else "false"
    if literal.kind == "list":
        return "[...]"
    return str(literal.value)
