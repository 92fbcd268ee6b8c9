"""Resolver: syntax trees -> the resolved model (names bound, checks done, layout and identity).

Every check reports through the Reporter and carries on, so a run lists all of its errors. A
type whose definition is broken is left out of the model quietly (its error was reported), so
one mistake does not cascade into errors about every type that uses it.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from . import identity
from .diagnostics import Note, Reporter, Source, Span, did_you_mean
from .layout import struct_layout, type_layout
from .model import (PRIMITIVES, Bytes, Constant, DynString, Enum, EnumRef, EnumValue, Field,
                    FixedArray, FixedString, Message, MessageRef, Mixin, Model, Optional, Padding,
                    Primitive, Service, SummaryPart, Type, Value, Variant, Vec)
from .names import RESERVED_MEMBERS, keyword_clash, snake_case
from .parser import FILE_KINDS, parse
from .syntax import (Attribute, EnumDecl, FieldDecl, FileSyntax, Literal, MessageDecl,
                     ServiceDecl, TypeExpr)

BUILTIN_NAMES = sorted(list(PRIMITIVES) + ["String", "bytes", "string", "Vec", "Option"])

# Attributes each kind of declaration accepts: "flag" (no value), "string", or "strings" (repeatable).
MESSAGE_ATTRIBUTES = {"topic": "string", "fixed": "flag", "summary": "string",
                      "cpp_mixin": "string", "cpp_include": "strings", "py_mixin": "string"}
FIELD_ATTRIBUTES = {"unit": "string"}
NO_ATTRIBUTES: dict[str, str] = {}

INTEGER_RANGES = {p.name: ((-(1 << (p.size * 8 - 1)), (1 << (p.size * 8 - 1)) - 1) if p.is_signed
                           else (0, (1 << (p.size * 8)) - 1))
                  for p in PRIMITIVES.values() if p.is_integer}
F32_MAX = 3.4028234663852886e38


@dataclass
class Options:
    include_dirs: list[str] = field(default_factory=list)
    package: str | None = None


@dataclass
class Unit:
    """One schema file: its syntax and the package its items live in."""
    path: str
    syntax: FileSyntax
    package: str


@dataclass
class Decl:
    qualified: str
    unit: Unit
    item: MessageDecl | EnumDecl
    service: str | None = None


class Resolver:
    def __init__(self, reporter: Reporter, options: Options):
        self.reporter = reporter
        self.options = options
        self.units: dict[str, Unit] = {}
        self.decls: dict[str, Decl] = {}
        self.service_decls: dict[str, tuple[ServiceDecl, Unit]] = {}
        self.scanned_folders: set[str] = set()
        self.mixin_outputs: dict[str, Mixin] = {}  # output path -> the helper file copied there
        self.model = Model()
        self.broken: set[str] = set()
        self.types: dict[str, dict[str, Type]] = {}  # message -> field name -> resolved type

    # -- loading ---------------------------------------------------------------------------------
    def run(self, paths: list[str]) -> Model:
        roots = [u for u in (self.load(p, root=True) for p in paths) if u is not None]
        generated: list[str] = []
        for unit in roots:
            for item in unit.syntax.items:
                qualified = f"{unit.package}.{item.name}"
                if isinstance(item, ServiceDecl):
                    generated += [qualified + "Request", qualified + "Response", qualified]
                else:
                    generated.append(qualified)
        self.resolve_all()
        self.model.generated = [q for q in dict.fromkeys(generated)
                                if q in self.model.types or q in self.model.services]
        self.check_file_names(roots)
        return self.model

    def load(self, path: str, import_span: Span | None = None, root: bool = False) -> Unit | None:
        real = os.path.realpath(path)
        if real in self.units:
            return self.units[real]
        kind = FILE_KINDS.get(os.path.splitext(path)[1])
        if kind is None:
            if import_span:
                self.reporter.error(import_span, f"cannot import '{path}': not a .hmsg or .hsrv file")
            return None
        try:
            with open(path, encoding="utf-8") as handle:
                text = handle.read()
        except (OSError, UnicodeDecodeError) as error:
            if import_span:
                self.reporter.error(import_span, f"cannot read '{path}': {error}")
            else:
                self.reporter.error(Span(Source(path, ""), 1, 1), f"cannot read file: {error}")
            return None
        source = Source(path, text)
        self.model.inputs.append(path)
        syntax = parse(source, self.reporter, kind)
        package = self.package_of(syntax, path, root)
        unit = Unit(path, syntax, package)
        self.units[real] = unit
        for target, span in syntax.imports:
            found = self.find_import(target, os.path.dirname(path))
            if found is None:
                searched = [os.path.dirname(path) or "."] + self.options.include_dirs
                self.reporter.error(span, f"cannot find imported file '{target}'",
                                    "searched " + ", ".join(f"'{d}'" for d in searched)
                                    + "; add the folder that holds it with -I (INCLUDE_DIRS in CMake)")
            else:
                self.load(found, span)
        self.declare(unit)
        return unit

    def package_of(self, syntax: FileSyntax, path: str, root: bool) -> str:
        """The file's own `package`, else --package for the files being compiled, else the
        name of the file's folder (so a library reached through -I keeps its own package)."""
        if syntax.package is not None:
            name, span = syntax.package
        else:
            given = self.options.package if root else None
            name = given or os.path.basename(os.path.dirname(os.path.abspath(path)))
            span = Span(syntax.source, 1, 1)
        for part in name.split("."):
            clash = keyword_clash(part)
            if not part.isidentifier() or clash:
                self.reporter.error(span, f"package name '{name}' cannot be a C++ namespace and a Python package"
                                    + (f": '{part}' is {clash}" if clash else ""),
                                    "use lowercase identifiers separated by '.', such as 'my_robot.msg'")
                break
        return name

    def find_import(self, target: str, base: str) -> str | None:
        for folder in [base] + self.options.include_dirs:
            candidate = os.path.join(folder, target)
            if os.path.isfile(candidate):
                return candidate
        return None

    def scan_package_folders(self, package: str, near: str | None) -> None:
        """Loads the schema files of `package`'s folder in every include dir, so that a qualified
        name resolves without an explicit import. Their errors are reported like any other: a
        package the schema uses is part of what it compiles against."""
        relative = package.replace(".", os.sep)
        folders = [os.path.join(d, relative) for d in self.options.include_dirs] + ([near] if near else [])
        for folder in folders:
            real = os.path.realpath(folder)
            if real in self.scanned_folders or not os.path.isdir(folder):
                continue
            self.scanned_folders.add(real)
            for name in sorted(os.listdir(folder)):
                if os.path.splitext(name)[1] in FILE_KINDS:
                    self.load(os.path.join(folder, name))

    # -- declarations ----------------------------------------------------------------------------
    def declare(self, unit: Unit) -> None:
        for item in unit.syntax.items:
            if isinstance(item, ServiceDecl):
                qualified = f"{unit.package}.{item.name}"
                if self.check_unique(qualified, item.span):
                    self.service_decls[qualified] = (item, unit)
                for part in (item.request, item.response):
                    part_name = f"{unit.package}.{part.name}"
                    if self.check_unique(part_name, part.span):
                        self.decls[part_name] = Decl(part_name, unit, part, service=qualified)
                continue
            qualified = f"{unit.package}.{item.name}"
            if self.check_unique(qualified, item.span):
                self.decls[qualified] = Decl(qualified, unit, item)

    def check_unique(self, qualified: str, span: Span) -> bool:
        previous = self.decls.get(qualified)
        previous_span = previous.item.span if previous else None
        if qualified in self.service_decls:
            previous_span = self.service_decls[qualified][0].span
        if previous_span is None:
            name = qualified.rsplit(".", 1)[-1]
            clash = keyword_clash(name)
            if clash:
                self.reporter.error(span, f"type name '{name}' is {clash}", "rename the type")
            return True
        self.reporter.error(span, f"duplicate type '{qualified.rsplit('.', 1)[-1]}' in package "
                            f"'{qualified.rsplit('.', 1)[0]}'", "type names are unique per package",
                            (Note(previous_span, "first declared here"),))
        return False

    def check_file_names(self, roots: list[Unit]) -> None:
        sources: dict[tuple[str, str], Unit] = {}
        for unit in (u for u in roots if u.syntax.items):
            key = (unit.package, os.path.basename(unit.path))
            first = sources.setdefault(key, unit)
            if first is not unit:
                self.reporter.error(Span(unit.syntax.source, 1, 1),
                                    f"schema files '{first.path}' and '{unit.path}' of package '{unit.package}' "
                                    f"would both be compiled into '{key[1]}.cpp'", "rename one of them")
        seen: dict[tuple[str, str], str] = {}
        for qualified in self.model.generated:
            package, name = qualified.rsplit(".", 1)
            key = (package, snake_case(name))
            if key in seen:
                decl = self.decls.get(qualified)
                span = decl.item.span if decl else self.service_decls[qualified][0].span
                self.reporter.error(span, f"types '{seen[key]}' and '{name}' would both be written to "
                                    f"'{key[1]}.hpp'", "rename one of them")
            seen[key] = name

    # -- resolution ------------------------------------------------------------------------------
    def preload_referenced_packages(self) -> None:
        """Loads, before anything is resolved, the package folders that names refer to, so that
        every declaration the run needs is known when resolution starts."""
        done: set[str] = set()
        while True:
            pending = [d for d in self.decls.values() if d.qualified not in done]
            if not pending:
                return
            for decl in pending:
                done.add(decl.qualified)
                if not isinstance(decl.item, MessageDecl):
                    continue
                for member in list(decl.item.fields) + list(decl.item.constants):
                    for path in _type_paths(member.type):
                        if len(path) == 1 and (path[0] in BUILTIN_NAMES or
                                               f"{decl.unit.package}.{path[0]}" in self.decls):
                            continue
                        if len(path) > 1 and ".".join(path) in self.decls:
                            continue
                        package = decl.unit.package if len(path) == 1 else ".".join(path[:-1])
                        own_folder = os.path.dirname(decl.unit.path) if package == decl.unit.package else None
                        self.scan_package_folders(package, own_folder)

    def resolve_all(self) -> None:
        self.preload_referenced_packages()
        for decl in list(self.decls.values()):
            if isinstance(decl.item, EnumDecl):
                self.build_enum(decl)
        for decl in list(self.decls.values()):
            if isinstance(decl.item, MessageDecl):
                self.types[decl.qualified] = self.resolve_fields(decl)
        cyclic = self.find_cycles()
        self.broken |= cyclic
        order = self.topological_order()
        for qualified in order:
            self.build_message(self.decls[qualified])
        for qualified, (item, unit) in self.service_decls.items():
            request = self.model.types.get(f"{qualified}Request")
            response = self.model.types.get(f"{qualified}Response")
            if isinstance(request, Message) and isinstance(response, Message):
                text = identity.service_text(qualified, (request.qualified, request.fingerprint),
                                             (response.qualified, response.fingerprint))
                self.model.services[qualified] = Service(unit.package, item.name, request, response, item.docs,
                                                         unit.path, identity.fingerprint(text))

    def resolve_fields(self, decl: Decl) -> dict[str, Type]:
        item = decl.item
        assert isinstance(item, MessageDecl)
        resolved: dict[str, Type] = {}
        seen: dict[str, Span] = {}
        for member in list(item.fields) + list(item.constants):
            if member.name in seen:
                self.reporter.error(member.span, f"duplicate member '{member.name}' in '{item.name}'",
                                    "field and constant names are unique within a message",
                                    (Note(seen[member.name], "first declared here"),))
                continue
            seen[member.name] = member.span
            clash = keyword_clash(member.name)
            if clash:
                self.reporter.error(member.span, f"member name '{member.name}' is {clash}",
                                    f"rename it (for example '{member.name}_')" if "keyword" in clash
                                    else "rename it")
            elif member.name in RESERVED_MEMBERS:
                self.reporter.error(member.span, f"member name '{member.name}' is taken by the generated code",
                                    "rename it")
            elif member.name == item.name:
                self.reporter.error(member.span, f"member '{member.name}' has the name of its message",
                                    "C++ does not allow a member named like its class; rename it")
            if isinstance(member, FieldDecl):
                t = self.resolve_type(member.type, decl.unit)
                if t is not None:
                    resolved[member.name] = t
        return resolved

    def resolve_type(self, expr: TypeExpr, unit: Unit) -> Type | None:
        if expr.element is not None:
            element = self.resolve_type(expr.element, unit)
            length = self.array_length(expr.length)
            if element is None or length is None:
                return None
            return FixedArray(element, length)
        name = expr.name
        if len(expr.path) == 1 and name in PRIMITIVES | {"String": 0, "bytes": 0, "string": 0, "Vec": 0, "Option": 0}:
            return self.resolve_builtin(expr, unit)
        if expr.args:
            self.reporter.error(expr.span, f"type '{name}' takes no arguments")
            return None
        candidates = [f"{unit.package}.{name}"] if len(expr.path) == 1 else [name]
        found = self.lookup(candidates)
        if found is None:
            self.report_unknown_type(expr, unit)
            return None
        decl = self.decls[found]
        if found in self.broken:
            return None
        return EnumRef(found) if isinstance(decl.item, EnumDecl) else MessageRef(found)

    def lookup(self, candidates: list[str]) -> str | None:
        return next((c for c in candidates if c in self.decls), None)

    def report_unknown_type(self, expr: TypeExpr, unit: Unit) -> None:
        name = expr.name
        visible = set(BUILTIN_NAMES)
        visible |= {q.rsplit(".", 1)[-1] for q in self.decls if q.startswith(unit.package + ".")}
        visible |= {q.replace(".", "::") for q in self.decls}
        spelled = "::".join(expr.path)
        hint = did_you_mean(spelled, visible)
        if hint is None and len(expr.path) == 1:
            elsewhere = sorted(q for q in self.decls if q.rsplit(".", 1)[-1] == name)
            if elsewhere:
                hint = f"'{name}' is declared as '{elsewhere[0].replace('.', '::')}': use the qualified name"
        if hint is None and len(expr.path) > 1:
            hint = (f"import the file that declares it, or add the folder holding "
                    f"'{'/'.join(expr.path[:-1])}/' with -I")
        self.reporter.error(expr.span, f"unknown type '{spelled}'", hint)

    def resolve_builtin(self, expr: TypeExpr, unit: Unit) -> Type | None:
        name = expr.name
        if name in PRIMITIVES or name in ("String", "bytes"):
            if expr.args:
                self.reporter.error(expr.span, f"type '{name}' takes no arguments")
                return None
            return PRIMITIVES.get(name) or (DynString() if name == "String" else Bytes())
        if name == "string":
            if len(expr.args) != 1 or not isinstance(expr.args[0], Literal):
                self.reporter.error(expr.span, "'string' needs a capacity: string<N>",
                                    "use string<32> for inline text of up to 32 bytes, or String for any length")
                return None
            capacity = expr.args[0]
            if capacity.kind != "int" or capacity.value < 1:
                self.reporter.error(capacity.span, f"string capacity must be a positive integer, found {capacity.value}",
                                    "string<0> holds nothing; use string<N> with N >= 1")
                return None
            return FixedString(capacity.value)
        if len(expr.args) != 1 or not isinstance(expr.args[0], TypeExpr):
            self.reporter.error(expr.span, f"'{name}' takes one type argument: {name}<T>")
            return None
        element = self.resolve_type(expr.args[0], unit)
        if element is None:
            return None
        return Vec(element) if name == "Vec" else Optional(element)

    def array_length(self, literal: Literal | None) -> int | None:
        if literal is None or literal.kind != "int":
            self.reporter.error(literal.span if literal else Span(Source("", ""), 1, 1),
                                "array length must be an integer literal")
            return None
        if literal.value < 1:
            self.reporter.error(literal.span, f"array length must be at least 1, found {literal.value}",
                                "a zero-length array holds nothing; remove the field or use Vec<T>")
            return None
        return literal.value

    # -- cycles and order -----------------------------------------------------------------------
    def message_edges(self, qualified: str) -> list[tuple[str, str]]:
        """(field name, nested message) pairs of a message."""
        edges = []
        for name, t in self.types.get(qualified, {}).items():
            for nested in _nested_messages(t):
                edges.append((name, nested))
        return edges

    def find_cycles(self) -> set[str]:
        cyclic: set[str] = set()
        state: dict[str, int] = {}
        stack: list[tuple[str, str]] = []

        def visit(qualified: str) -> None:
            state[qualified] = 1
            for field_name, nested in self.message_edges(qualified):
                stack.append((qualified, field_name))
                if state.get(nested) == 1:
                    start = next(i for i, (q, _) in enumerate(stack) if q == nested)
                    loop = stack[start:]
                    cyclic.update(q for q, _ in loop)
                    path = " -> ".join(f"{q.rsplit('.', 1)[-1]}.{f}" for q, f in loop)
                    owner, owner_field = loop[-1]
                    item = self.decls[owner].item
                    span = next(f.span for f in item.fields if f.name == owner_field)
                    self.reporter.error(span, f"message '{nested.rsplit('.', 1)[-1]}' contains itself "
                                        f"({path} -> {nested.rsplit('.', 1)[-1]})",
                                        "a message cannot hold itself, even through Vec or Option; "
                                        "refer to the other item by an id instead")
                elif state.get(nested) is None:
                    visit(nested)
                stack.pop()
            state[qualified] = 2

        for qualified in sorted(self.types):
            if qualified not in state:
                visit(qualified)
        return cyclic

    def topological_order(self) -> list[str]:
        order: list[str] = []
        done: set[str] = set()

        def visit(qualified: str) -> None:
            if qualified in done:
                return
            done.add(qualified)
            for _, nested in self.message_edges(qualified):
                if nested in self.types:
                    visit(nested)
            order.append(qualified)

        for qualified in self.types:
            if qualified not in self.broken:
                visit(qualified)
        return [q for q in order if q not in self.broken]

    # -- enums ---------------------------------------------------------------------------------
    def build_enum(self, decl: Decl) -> None:
        item = decl.item
        assert isinstance(item, EnumDecl)
        self.check_attributes(item.attributes, NO_ATTRIBUTES, f"enum '{item.name}'")
        underlying = PRIMITIVES["i32"]
        if item.underlying is not None:
            candidate = PRIMITIVES.get(item.underlying.name)
            if candidate is None or not candidate.is_integer:
                self.reporter.error(item.underlying.span,
                                    f"enum '{item.name}' needs an integer underlying type, found '{item.underlying.name}'",
                                    did_you_mean(item.underlying.name, [p for p in PRIMITIVES if p[0] in "ui"])
                                    or "use one of u8 u16 u32 u64 i8 i16 i32 i64")
                self.broken.add(decl.qualified)
                return
            underlying = candidate
        low, high = INTEGER_RANGES[underlying.name]
        variants: list[Variant] = []
        names: dict[str, Span] = {}
        values: dict[int, tuple[str, Span]] = {}
        next_value = 0
        for variant in item.variants:
            value = next_value
            if variant.value is not None:
                if variant.value.kind != "int":
                    self.reporter.error(variant.value.span, f"enumerator '{variant.name}' needs an integer value")
                    continue
                value = variant.value.value
            span = variant.value.span if variant.value is not None else variant.span
            if not low <= value <= high:
                self.reporter.error(span, f"value {value} of '{item.name}::{variant.name}' is out of range "
                                    f"for {underlying.name} ({low}..{high})",
                                    "pick a wider underlying type or a smaller value")
            if variant.name in names:
                self.reporter.error(variant.span, f"duplicate enumerator '{variant.name}' in '{item.name}'",
                                    notes=(Note(names[variant.name], "first declared here"),))
            elif value in values:
                self.reporter.error(span, f"duplicate enum value {value}: '{variant.name}' and "
                                    f"'{values[value][0]}' of '{item.name}'", "give each enumerator its own value",
                                    (Note(values[value][1], "first used here"),))
            else:
                clash = keyword_clash(variant.name)
                if clash:
                    self.reporter.error(variant.span, f"enumerator name '{variant.name}' is {clash}", "rename it")
                variants.append(Variant(variant.name, value, variant.docs))
            names.setdefault(variant.name, variant.span)
            values.setdefault(value, (variant.name, span))
            next_value = value + 1
        if not item.variants:
            self.reporter.error(item.span, f"enum '{item.name}' has no enumerators")
        text = identity.enum_text(decl.qualified, underlying.name, [(v.name, v.value) for v in variants])
        self.model.types[decl.qualified] = Enum(decl.unit.package, item.name, underlying, tuple(variants),
                                                item.docs, decl.unit.path, text, text, text,
                                                identity.fingerprint(text))

    # -- messages --------------------------------------------------------------------------------
    def build_message(self, decl: Decl) -> None:
        item = decl.item
        assert isinstance(item, MessageDecl)
        if decl.service is None:
            attributes = self.check_attributes(item.attributes, MESSAGE_ATTRIBUTES, f"message '{item.name}'")
        else:
            attributes = self.check_attributes(item.attributes, NO_ATTRIBUTES, f"'{item.name}'")
        types = self.types[decl.qualified]
        fields: list[Field] = []
        for f in item.fields:
            field_attributes = self.check_attributes(f.attributes, FIELD_ATTRIBUTES, f"field '{f.name}'")
            t = types.get(f.name)
            if t is None or self.is_missing(t):
                continue
            default = self.convert_value(f.default, t, f"field '{f.name}'") if f.default is not None else None
            fields.append(Field(f.name, t, identity.spelling(t), default, field_attributes.get("unit", ""),
                                f.docs, f.span))
        constants: list[Constant] = []
        for c in item.constants:
            self.check_attributes(c.attributes, NO_ATTRIBUTES, f"constant '{c.name}'")
            t = self.resolve_type(c.type, decl.unit)
            if t is None:
                continue
            if not _is_constant_type(t):
                self.reporter.error(c.type.span, f"constant '{c.name}' has type '{identity.spelling(t)}'",
                                    "constants are numbers, bool, enums or strings")
                continue
            value = self.convert_value(c.value, t, f"constant '{c.name}'")
            if value is not None:
                constants.append(Constant(c.name, t, identity.spelling(t), value, c.docs))
        if len(fields) < len(item.fields):
            assert self.reporter.has_errors, f"{decl.qualified} lost a field without an error"
            return  # an unresolved field type was reported; a partial model would mislead

        is_pod = all(self.is_pod(t) for t in types.values())
        if "fixed" in attributes and not is_pod:
            for f in fields:
                if not self.is_pod(f.type):
                    self.reporter.error(f.span, f"field '{f.name}' of '{item.name}' has serialized type "
                                        f"'{f.spelling}', but the message is #[fixed]",
                                        "use a fixed-size type (string<N>, [T; N]) or remove #[fixed]")
                    break
        size = alignment = None
        padding: tuple[Padding, ...] = ()
        if is_pod:
            layouts = [type_layout(f.type, self.nested_layout, self.enum_underlying) for f in fields]
            offsets, size, alignment, padding = struct_layout(layouts)
            fields = [_with_offset(f, o, lay[0]) for f, o, lay in zip(fields, offsets, layouts)]

        fingerprints = {q: t.fingerprint for q, t in self.model.types.items()}
        canonical, readable = identity.message_texts(decl.qualified, [(f.name, f.type) for f in fields], fingerprints)
        uses = list(dict.fromkeys(q for f in fields for q in _named_types(f.type)))
        schema = readable + "".join(self.model.types[q].definition for q in self.schema_dependencies(uses))
        summary = self.summary(item, fields, attributes.get("summary"))
        directory = os.path.dirname(decl.unit.path)
        self.model.types[decl.qualified] = Message(
            decl.unit.package, item.name, tuple(fields), tuple(constants), item.docs, decl.unit.path, is_pod,
            size, alignment, padding, canonical, readable, schema, identity.fingerprint(canonical), summary,
            attributes.get("topic"), self.mixin(attributes, "cpp_mixin", directory, decl.unit.package, item),
            tuple(attributes.get("cpp_include", ())),
            self.mixin(attributes, "py_mixin", directory, decl.unit.package, item), tuple(uses), decl.service)

    def is_missing(self, t: Type) -> bool:
        return any(q not in self.model.types for q in _named_types(t))

    def schema_dependencies(self, uses: list[str]) -> list[str]:
        """Every type reachable from `uses`, each once, in first-use order."""
        seen: list[str] = []

        def visit(qualified: str) -> None:
            if qualified in seen:
                return
            seen.append(qualified)
            found = self.model.types[qualified]
            if isinstance(found, Message):
                for nested in found.uses:
                    visit(nested)

        for q in uses:
            visit(q)
        return seen

    def is_pod(self, t: Type) -> bool:
        if isinstance(t, (Primitive, FixedString, EnumRef)):
            return True
        if isinstance(t, FixedArray):
            return self.is_pod(t.element)
        if isinstance(t, MessageRef):
            found = self.model.types.get(t.qualified)
            return isinstance(found, Message) and found.is_pod
        return False

    def nested_layout(self, qualified: str) -> tuple[int, int, tuple[Padding, ...]]:
        message = self.model.message(qualified)
        assert message.size is not None and message.alignment is not None
        return message.size, message.alignment, message.padding

    def enum_underlying(self, qualified: str) -> Primitive:
        found = self.model.types[qualified]
        assert isinstance(found, Enum)
        return found.underlying

    def summary(self, item: MessageDecl, fields: list[Field], template: str | None) -> tuple[SummaryPart, ...]:
        by_name = {f.name: f for f in fields}

        def part(f: Field) -> SummaryPart:
            return SummaryPart(field=f.name, label=_element_label(f.type), unit=f.unit)

        if template is None:
            parts = [SummaryPart(text=f"{item.name}{{")]
            for i, f in enumerate(fields):
                parts.append(SummaryPart(text=(", " if i else "") + f"{f.name}: "))
                parts.append(part(f))
            parts.append(SummaryPart(text="}"))
            return _join_text(parts)
        parts = []
        i, text = 0, ""
        span = next(a.span for a in item.attributes if a.name == "summary")
        while i < len(template):
            c = template[i]
            if template.startswith("{{", i) or template.startswith("}}", i):
                text += c
                i += 2
                continue
            if c == "{":
                end = template.find("}", i)
                if end < 0:
                    self.reporter.error(span, "unclosed '{' in #[summary]", "write '{{' for a literal brace")
                    break
                name = template[i + 1:end]
                if name not in by_name:
                    self.reporter.error(span, f"#[summary] names '{name}', which is not a field of '{item.name}'",
                                        did_you_mean(name, list(by_name)))
                else:
                    parts.append(SummaryPart(text=text))
                    parts.append(part(by_name[name]))
                    text = ""
                i = end + 1
                continue
            text += c
            i += 1
        parts.append(SummaryPart(text=text))
        return _join_text(parts)

    def mixin(self, attributes: dict, key: str, directory: str, package: str, item: MessageDecl) -> Mixin | None:
        relative = attributes.get(key)
        if relative is None:
            return None
        span = next(a.span for a in item.attributes if a.name == key)
        normalized = os.path.normpath(relative)
        if os.path.isabs(relative) or normalized.startswith(".."):
            self.reporter.error(span, f"#[{key}] path '{relative}' must stay inside the schema's folder",
                                "keep helper files in a folder beside the schema, e.g. 'mixins/name.hpp'")
            return None
        source = os.path.join(directory, normalized)
        if not os.path.isfile(source):
            self.reporter.error(span, f"#[{key}] file '{relative}' not found (looked for '{source}')")
            return None
        self.model.inputs.append(source)
        if key == "py_mixin":
            stem = os.path.splitext(os.path.basename(normalized))[0]
            output = os.path.join(*package.split("."), f"_mixin_{stem}.py")
        else:
            output = os.path.join(*package.split("."), normalized)
        mixin = Mixin(os.path.abspath(source), output)
        previous = self.mixin_outputs.setdefault(output, mixin)
        if previous.source_path != mixin.source_path:
            self.reporter.error(span, f"#[{key}] file '{relative}' would be written to '{output}', "
                                f"like '{previous.source_path}'", "give the two helper files different names")
            return None
        return mixin

    # -- attributes and values --------------------------------------------------------------------
    def check_attributes(self, attributes: tuple[Attribute, ...], allowed: dict[str, str], owner: str) -> dict:
        found: dict[str, object] = {}
        for attribute in attributes:
            kind = allowed.get(attribute.name)
            if kind is None:
                if allowed:
                    hint = did_you_mean(attribute.name, list(allowed)) or \
                        "known here: " + ", ".join(f"#[{a}]" for a in sorted(allowed))
                else:
                    hint = f"{owner} takes no attributes"
                self.reporter.error(attribute.span, f"unknown attribute '{attribute.name}' on {owner}", hint)
                continue
            if kind == "flag":
                if attribute.value is not None:
                    self.reporter.error(attribute.span, f"attribute '{attribute.name}' takes no value",
                                        f"write #[{attribute.name}]")
                found[attribute.name] = True
                continue
            if attribute.value is None or attribute.value.kind != "string":
                self.reporter.error(attribute.span, f"attribute '{attribute.name}' needs a string value",
                                    f'write #[{attribute.name} = "..."]')
                continue
            if kind == "strings":
                found.setdefault(attribute.name, []).append(attribute.value.value)
            elif attribute.name in found:
                self.reporter.error(attribute.span, f"attribute '{attribute.name}' is given twice on {owner}")
            else:
                found[attribute.name] = attribute.value.value
        return found

    def convert_value(self, literal: Literal, t: Type, owner: str) -> Value | None:
        spelled = identity.spelling(t)
        wrong = f"{owner} has type '{spelled}', but its value is "

        def error(message: str, hint: str | None = None) -> None:
            self.reporter.error(literal.span, message, hint)

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
            value = float(literal.value)
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
            if isinstance(t, FixedString) and len(literal.value.encode("utf-8")) > t.capacity:
                error(f"value of {owner} is {len(literal.value.encode('utf-8'))} bytes, more than "
                      f"string<{t.capacity}> holds")
                return None
            return literal.value
        if isinstance(t, EnumRef):
            enum = self.model.types.get(t.qualified)
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
        if isinstance(t, FixedArray) and _is_constant_type(t.element):
            if literal.kind != "list":
                error(wrong + _describe(literal), f"write a list of {t.length} values: [a, b, ...]")
                return None
            if len(literal.value) != t.length:
                error(f"{owner} has {t.length} elements, but its value lists {len(literal.value)}")
                return None
            items = [self.convert_value(v, t.element, owner) for v in literal.value]
            return None if any(v is None for v in items) else tuple(items)
        error(f"{owner} of type '{spelled}' cannot have a default value",
              "defaults are for numbers, bool, enums, strings and fixed arrays of those")
        return None


def _type_paths(expr: TypeExpr) -> list[tuple[str, ...]]:
    if expr.element is not None:
        return _type_paths(expr.element)
    nested = [p for arg in expr.args if isinstance(arg, TypeExpr) for p in _type_paths(arg)]
    return [expr.path] + nested


def _describe(literal: Literal) -> str:
    if literal.kind == "path":
        return f"the name '{'::'.join(literal.value)}'"
    if literal.kind == "list":
        return "a list"
    return f"the {literal.kind} {literal.value!r}"


def _is_constant_type(t: Type) -> bool:
    return isinstance(t, (Primitive, FixedString, DynString, EnumRef))


def _with_offset(f: Field, offset: int, size: int) -> Field:
    return Field(f.name, f.type, f.spelling, f.default, f.unit, f.docs, f.span, offset, size)


def _nested_messages(t: Type) -> list[str]:
    return [r.qualified for r in _refs(t) if isinstance(r, MessageRef)]


def _named_types(t: Type) -> list[str]:
    return [r.qualified for r in _refs(t)]


def _refs(t: Type) -> list[MessageRef | EnumRef]:
    if isinstance(t, (MessageRef, EnumRef)):
        return [t]
    if isinstance(t, (FixedArray, Vec, Optional)):
        return _refs(t.element)
    return []


def _element_label(t: Type) -> str:
    inner = t.element if isinstance(t, Optional) else t
    if isinstance(inner, (FixedArray, Vec)):
        return identity.spelling(inner.element, short=True)
    return ""


def _join_text(parts: list[SummaryPart]) -> tuple[SummaryPart, ...]:
    joined: list[SummaryPart] = []
    for p in parts:
        if p.field is None and not p.text:
            continue
        if p.field is None and joined and joined[-1].field is None:
            joined[-1] = SummaryPart(text=joined[-1].text + p.text)
        else:
            joined.append(p)
    return tuple(joined)
