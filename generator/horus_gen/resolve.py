"""Resolver: syntax trees -> the resolved model (names bound, checks done, layout and identity).
Files are found and parsed by loader.py, literals converted by values.py, summaries parsed by
summary.py; the names of output files are the emitters' (lang/<lang>.py).

Every check reports through the Reporter and carries on, so a run lists all of its errors. A
type whose definition is broken is left out of the model quietly (its error was reported), so
one mistake does not cascade into errors about every type that uses it.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from . import identity, resolve_action
from .diagnostics import Note, Reporter, Source, Span, did_you_mean
from .lang import cpp, keyword_clash, python
from .layout import MAX_POD_SIZE, LayoutTooLarge, counted_size, struct_layout, type_layout
from .loader import Loader, Options, Unit
from .model import (PRIMITIVES, Bytes, Constant, DynString, Enum, EnumRef, Field, FixedArray,
                    FixedString, Message, MessageRef, Mixin, Model, Optional, Padding, Primitive,
                    Service, Type, Variant, Vec)
from .names import RESERVED_MEMBERS
from .summary import summary_parts
from .resolve_node import NodeResolver
from .syntax import ActionDecl, EnumDecl, FieldDecl, Literal, MessageDecl, NodeDecl, ServiceDecl, TypeExpr
from .values import INTEGER_RANGES, check_attributes, check_derives, convert_value, is_constant_type

BUILTIN_NAMES = sorted(list(PRIMITIVES) + ["String", "bytes", "string", "Vec", "Option"])

# Attributes each kind of declaration accepts: "flag" (no value), "string", or "strings" (repeatable).
MESSAGE_ATTRIBUTES = {"topic": "string", "fixed": "flag", "summary": "string", "derive": "list",
                      "cpp_mixin": "string", "cpp_include": "strings", "py_mixin": "string"}
# An action's goal, result and feedback blocks are messages of their own, but carried on the
# action's topics and services rather than on one named by #[topic].
ACTION_BLOCK_ATTRIBUTES = {k: v for k, v in MESSAGE_ATTRIBUTES.items() if k != "topic"}
ENUM_ATTRIBUTES = {"derive": "list"}
FIELD_ATTRIBUTES = {"unit": "string"}
NO_ATTRIBUTES: dict[str, str] = {}
# The language whose emitter names the copy of each kind of mixin file.
MIXIN_LANGUAGES = {"cpp_mixin": cpp, "py_mixin": python}

# How deep messages may hold messages (docs/schema-language.md, "Limits"): a type's schema text
# holds the definition of every type it holds, so a chain of N messages writes N²/2 definitions.
MAX_MESSAGE_DEPTH = 64


@dataclass
class Decl:
    qualified: str
    unit: Unit
    item: MessageDecl | EnumDecl
    service: str | None = None
    action: str | None = None  # the qualified action that declared it


class Resolver:
    def __init__(self, reporter: Reporter, options: Options):
        self.reporter = reporter
        self.model = Model()
        self.loader = Loader(reporter, options, self.model.inputs)
        self.decls: dict[str, Decl] = {}
        self.service_decls: dict[str, tuple[ServiceDecl, Unit]] = {}
        self.node_decls: dict[str, tuple[NodeDecl, Unit]] = {}
        self.action_decls: dict[str, tuple[ActionDecl, Unit]] = {}
        self.service_wire: dict[str, tuple[str, str]] = {}  # action's service -> (wire name, action)
        self.mixin_outputs: dict[str, Mixin] = {}  # output path -> the helper file copied there
        self.broken: set[str] = set()
        self.types: dict[str, dict[str, Type]] = {}  # message -> field name -> resolved type

    def run(self, paths: list[str]) -> Model:
        roots = [u for u in (self.loader.load(p, root=True) for p in paths) if u is not None]
        self.declare_loaded()
        generated: list[str] = []
        for unit in roots:
            for item in unit.syntax.items:
                qualified = f"{unit.package}.{item.name}"
                if isinstance(item, ServiceDecl):
                    generated += [qualified + "Request", qualified + "Response", qualified]
                elif isinstance(item, ActionDecl):
                    generated += [f"{unit.package}.{name}" for name in resolve_action.generated_names(item.name)]
                else:
                    generated.append(qualified)
        self.resolve_all()
        self.model.generated = [q for q in dict.fromkeys(generated) if q in self.model.types or q in self.model.services
                                or q in self.model.actions or q in self.model.nodes]
        self.check_base_names()
        self.check_file_names()
        return self.model

    # -- declarations ----------------------------------------------------------------------------
    def declare_loaded(self) -> None:
        for unit in self.loader.take_loaded():
            self.declare(unit)

    def declare(self, unit: Unit) -> None:
        for item in unit.syntax.items:
            if isinstance(item, NodeDecl):
                qualified = f"{unit.package}.{item.name}"
                if self.check_unique(qualified, item.span):
                    self.node_decls[qualified] = (item, unit)
                continue
            if isinstance(item, ServiceDecl):
                qualified = f"{unit.package}.{item.name}"
                if self.check_unique(qualified, item.span):
                    self.service_decls[qualified] = (item, unit)
                for part in (item.request, item.response):
                    part_name = f"{unit.package}.{part.name}"
                    if self.check_unique(part_name, part.span):
                        self.decls[part_name] = Decl(part_name, unit, part, service=qualified)
                continue
            if isinstance(item, ActionDecl):
                self.declare_action(item, unit)
                continue
            qualified = f"{unit.package}.{item.name}"
            if self.check_unique(qualified, item.span):
                self.decls[qualified] = Decl(qualified, unit, item)

    def declare_action(self, item: ActionDecl, unit: Unit) -> None:
        """Declares an action and every message and service it stands for (resolve_action.py)."""
        qualified = f"{unit.package}.{item.name}"
        if item.name in resolve_action.MEMBERS:
            self.reporter.error(item.span, f"action '{item.name}' is named like a member of the type generated for it",
                                "rename the action (its members: Goal, Result, Feedback, SendGoal, Status, ...)")
        messages, services = resolve_action.expand(item)
        for message in messages:
            part_name = f"{unit.package}.{message.name}"
            if self.check_unique(part_name, message.span):
                self.decls[part_name] = Decl(part_name, unit, message, action=qualified)
        for service, wire_name in services:
            service_name = f"{unit.package}.{service.name}"
            if self.check_unique(service_name, service.span):
                self.service_decls[service_name] = (service, unit)
                self.service_wire[service_name] = (wire_name, qualified)
                # The result message is get_result's response and the result topic's message: it
                # stays a message of the action rather than a part of the service.
                shared = f"{item.name}ResultMessage"
                for part in (service.request, service.response):
                    decl = self.decls.get(f"{unit.package}.{part.name}")
                    if decl is not None and decl.item is part and part.name != shared:
                        decl.service = service_name
        if self.check_unique(qualified, item.span):
            self.action_decls[qualified] = (item, unit)

    def check_unique(self, qualified: str, span: Span) -> bool:
        previous = self.decls.get(qualified)
        previous_span = previous.item.span if previous else None
        if qualified in self.service_decls:
            previous_span = self.service_decls[qualified][0].span
        if qualified in self.node_decls:
            previous_span = self.node_decls[qualified][0].span
        if qualified in self.action_decls:
            previous_span = self.action_decls[qualified][0].span
        if previous_span is None:
            name = qualified.rsplit(".", 1)[-1]
            clash = keyword_clash(name) or ("a name of the generated C++ code" if name in cpp.NAMESPACE_NAMES else None)
            if clash:
                self.reporter.error(span, f"type name '{name}' is {clash}", "rename the type")
            return True
        self.reporter.error(span, f"duplicate type '{qualified.rsplit('.', 1)[-1]}' in package "
                            f"'{qualified.rsplit('.', 1)[0]}'", "type names are unique per package",
                            (Note(previous_span, "first declared here"),))
        return False

    def check_base_names(self) -> None:
        """A node's generated class (<Name>Base) must not take the name of a type of its package."""
        for node in self.model.generated_nodes():
            taken = f"{node.package}.{node.base}"
            declared = (self.decls, self.service_decls, self.action_decls, self.node_decls)
            if any(taken in names for names in declared):
                self.reporter.error(self.node_decls[node.qualified][0].span,
                                    f"node '{node.name}' generates the class '{node.base}', which is also a type "
                                    f"of package '{node.package}'", "rename the node or the type")

    def check_file_names(self) -> None:
        seen: dict[str, str] = {}
        for qualified in self.model.generated:
            name = qualified.rsplit(".", 1)[1]
            header = cpp.header_path(qualified)
            if header in seen:
                decl = self.decls.get(qualified)
                other = self.service_decls.get(qualified) or self.action_decls.get(qualified)
                span = decl.item.span if decl else (other or self.node_decls[qualified])[0].span
                self.reporter.error(span, f"types '{seen[header]}' and '{name}' would both be written to "
                                    f"'{os.path.basename(header)}'", "rename one of them")
            seen[header] = name

    # -- resolution ------------------------------------------------------------------------------
    def preload_referenced_packages(self) -> None:
        """Loads, before anything is resolved, the package folders that names refer to, so that
        every declaration the run needs is known when resolution starts."""
        for item, unit in list(self.node_decls.values()):
            exprs = [e.type for _, _, entries in item.blocks for e in entries]
            exprs += [f.type for f in item.data + item.params]
            for expr in exprs:
                for path in _type_paths(expr):
                    self.preload_path(path, unit)
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
                        self.preload_path(path, decl.unit)

    def preload_path(self, path: tuple[str, ...], unit: Unit) -> None:
        """Loads the package folder that the type name `path`, written in `unit`, refers to."""
        known = self.decls.keys() | self.service_decls.keys()
        if len(path) == 1 and (path[0] in BUILTIN_NAMES or f"{unit.package}.{path[0]}" in known):
            return
        if len(path) > 1 and ".".join(path) in known:
            return
        package = unit.package if len(path) == 1 else ".".join(path[:-1])
        own_folder = os.path.dirname(unit.path) if package == unit.package else None
        self.loader.scan_package_folders(package, own_folder)
        self.declare_loaded()

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
        self.broken |= self.find_too_deep(order)
        for qualified in [q for q in order if q not in self.broken]:
            self.build_message(self.decls[qualified])
        for qualified, (item, unit) in self.service_decls.items():
            request = self.model.types.get(f"{unit.package}.{item.request.name}")
            response = self.model.types.get(f"{unit.package}.{item.response.name}")
            if isinstance(request, Message) and isinstance(response, Message):
                text = identity.service_text(qualified, (request.qualified, request.fingerprint),
                                             (response.qualified, response.fingerprint))
                wire_name, action = self.service_wire.get(qualified, (item.name, None))
                self.model.services[qualified] = Service(
                    package=unit.package, name=item.name, request=request, response=response, docs=item.docs,
                    source=unit.path, fingerprint=identity.fingerprint(text), wire_name=wire_name, action=action)
        for qualified, (item, unit) in self.action_decls.items():
            action = resolve_action.build(self.model, item, unit.package, unit.path)
            if action is not None:
                self.model.actions[qualified] = action
        nodes = NodeResolver(self)
        for item, unit in self.node_decls.values():
            nodes.build(item, unit)

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
            if capacity.kind == "int" and capacity.value > MAX_POD_SIZE:
                self.reporter.error(capacity.span, f"string capacity {capacity.value} is more than {MAX_POD_SIZE}",
                                    "use String for long text")
                return None
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
        if literal.value > MAX_POD_SIZE:
            self.reporter.error(literal.span, f"array length {literal.value} is more than {MAX_POD_SIZE}",
                                "use Vec<T> or bytes for bulk data")
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
        """Reports each message that contains itself. Depth-first with an explicit stack: a chain of
        declarations may be longer than Python's recursion limit."""
        cyclic: set[str] = set()
        state: dict[str, int] = {}
        path: list[tuple[str, str]] = []  # (message, field) on the way to the message being visited

        for root in sorted(self.types):
            if root in state:
                continue
            state[root] = 1
            frames = [(root, iter(self.message_edges(root)))]
            while frames:
                qualified, edges = frames[-1]
                edge = next(edges, None)
                if edge is None:
                    state[qualified] = 2
                    frames.pop()
                    if path:
                        path.pop()
                    continue
                field_name, nested = edge
                if state.get(nested) == 1:
                    loop = path[next(i for i, (q, _) in enumerate(path + [(qualified, "")]) if q == nested):] + \
                        [(qualified, field_name)]
                    self.report_cycle(nested, loop, cyclic)
                elif state.get(nested) is None:
                    path.append((qualified, field_name))
                    state[nested] = 1
                    frames.append((nested, iter(self.message_edges(nested))))
        return cyclic

    def field_span(self, qualified: str, field_name: str):
        """Where message `qualified` declares its field `field_name`."""
        return next(f.span for f in self.decls[qualified].item.fields if f.name == field_name)

    def report_cycle(self, nested: str, loop: list[tuple[str, str]], cyclic: set[str]) -> None:
        cyclic.update(q for q, _ in loop)
        path = " -> ".join(f"{q.rsplit('.', 1)[-1]}.{f}" for q, f in loop)
        owner, owner_field = loop[-1]
        self.reporter.error(self.field_span(owner, owner_field), f"message '{nested.rsplit('.', 1)[-1]}' contains itself "
                            f"({path} -> {nested.rsplit('.', 1)[-1]})",
                            "a message cannot hold itself, even through Vec or Option; "
                            "refer to the other item by an id instead")

    def find_too_deep(self, order: list[str]) -> set[str]:
        """Reports each message that holds messages more than MAX_MESSAGE_DEPTH levels deep, at the
        field where the chain first passes the limit; returns every message past it."""
        depth: dict[str, tuple[int, str]] = {}  # message -> (levels, the field of the deepest chain)
        too_deep: set[str] = set()
        for qualified in order:  # every message after those it holds
            levels, through = 1, ""
            for field_name, nested in self.message_edges(qualified):
                if nested in depth and depth[nested][0] + 1 > levels:
                    levels, through = depth[nested][0] + 1, field_name
            depth[qualified] = (levels, through)
            if levels > MAX_MESSAGE_DEPTH:
                too_deep.add(qualified)
                if levels == MAX_MESSAGE_DEPTH + 1:
                    self.reporter.error(self.field_span(qualified, through),
                                        f"message '{qualified.rsplit('.', 1)[-1]}' holds messages more than {MAX_MESSAGE_DEPTH} "
                                        f"levels deep (through '{through}')",
                                        "flatten the chain: each type's schema text holds those of every "
                                        "type it holds")
        return too_deep

    def topological_order(self) -> list[str]:
        """Every message after those it holds (iteratively, like find_cycles)."""
        order: list[str] = []
        done: set[str] = set()
        for root in self.types:
            if root in self.broken or root in done:
                continue
            done.add(root)
            frames = [(root, iter(self.message_edges(root)))]
            while frames:
                qualified, edges = frames[-1]
                edge = next(edges, None)
                if edge is None:
                    order.append(qualified)
                    frames.pop()
                elif edge[1] in self.types and edge[1] not in done:
                    done.add(edge[1])
                    frames.append((edge[1], iter(self.message_edges(edge[1]))))
        return [q for q in order if q not in self.broken]

    # -- enums ---------------------------------------------------------------------------------
    def build_enum(self, decl: Decl) -> None:
        item = decl.item
        assert isinstance(item, EnumDecl)
        attributes = check_attributes(self.reporter, item.attributes, ENUM_ATTRIBUTES, f"enum '{item.name}'")
        check_derives(self.reporter, attributes.get("derive", []), f"enum '{item.name}'", is_enum=True, is_pod=True)
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
        self.model.types[decl.qualified] = Enum(
            package=decl.unit.package, name=item.name, underlying=underlying, variants=tuple(variants),
            docs=item.docs, source=decl.unit.path, canonical=text, definition=text, schema=text,
            fingerprint=identity.fingerprint(text))

    # -- messages --------------------------------------------------------------------------------
    def build_message(self, decl: Decl) -> None:
        item = decl.item
        assert isinstance(item, MessageDecl)
        if decl.action is not None and decl.service is None:
            attributes = check_attributes(self.reporter, item.attributes, ACTION_BLOCK_ATTRIBUTES, f"'{item.name}'")
        elif decl.service is None:
            attributes = check_attributes(self.reporter, item.attributes, MESSAGE_ATTRIBUTES, f"message '{item.name}'")
        else:
            attributes = check_attributes(self.reporter, item.attributes, NO_ATTRIBUTES, f"'{item.name}'")
        types = self.types[decl.qualified]
        fields: list[Field] = []
        for f in item.fields:
            field_attributes = check_attributes(self.reporter, f.attributes, FIELD_ATTRIBUTES, f"field '{f.name}'")
            t = types.get(f.name)
            if t is None or self.is_missing(t):
                continue
            default = convert_value(self.reporter, self.model.types, f.default, t, f"field '{f.name}'") if f.default is not None else None
            fields.append(Field(f.name, t, identity.spelling(t), default, field_attributes.get("unit", ""),
                                f.docs, f.span))
        constants: list[Constant] = []
        for c in item.constants:
            check_attributes(self.reporter, c.attributes, NO_ATTRIBUTES, f"constant '{c.name}'")
            t = self.resolve_type(c.type, decl.unit)
            if t is None:
                continue
            if not is_constant_type(t):
                self.reporter.error(c.type.span, f"constant '{c.name}' has type '{identity.spelling(t)}'",
                                    "constants are numbers, bool, enums or strings")
                continue
            value = convert_value(self.reporter, self.model.types, c.value, t, f"constant '{c.name}'")
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
        if not is_pod and not all([self.arrays_fit(f.type, f.span, f"field '{f.name}' of '{item.name}'")
                                   for f in fields]):
            return
        size = alignment = None
        padding: tuple[Padding, ...] = ()
        if is_pod:
            try:
                layouts = [type_layout(f.type, self.nested_layout, self.enum_underlying) for f in fields]
                offsets, size, alignment, padding = struct_layout(layouts)
            except LayoutTooLarge as error:
                self.reporter.error(item.span, f"message '{item.name}' is too large: {error}",
                                    "use Vec<T> or bytes for bulk data, which are serialized instead")
                return
            fields = [_with_offset(f, o, lay[0]) for f, o, lay in zip(fields, offsets, layouts)]

        fingerprints = {q: t.fingerprint for q, t in self.model.types.items()}
        canonical, readable = identity.message_texts(decl.qualified, [(f.name, f.type) for f in fields], fingerprints)
        uses = list(dict.fromkeys(q for f in fields for q in _named_types(f.type)))
        schema = readable + "".join(self.model.types[q].definition for q in self.schema_dependencies(uses))
        check_derives(self.reporter, attributes.get("derive", []), f"message '{item.name}'", is_enum=False,
                      is_pod=is_pod)
        summary = summary_parts(self.reporter, item, fields, attributes.get("summary"))
        directory = os.path.dirname(decl.unit.path)
        self.model.types[decl.qualified] = Message(
            package=decl.unit.package, name=item.name, fields=tuple(fields), constants=tuple(constants),
            docs=item.docs, source=decl.unit.path, is_pod=is_pod, size=size, alignment=alignment,
            padding=padding, canonical=canonical, definition=readable, schema=schema,
            fingerprint=identity.fingerprint(canonical), summary=summary, topic=attributes.get("topic"),
            cpp_mixin=self.mixin(attributes, "cpp_mixin", directory, decl.unit.package, item),
            cpp_includes=tuple(attributes.get("cpp_include", ())),
            py_mixin=self.mixin(attributes, "py_mixin", directory, decl.unit.package, item),
            uses=tuple(uses), service=decl.service, action=decl.action)

    def is_missing(self, t: Type) -> bool:
        return any(q not in self.model.types for q in _named_types(t))

    def schema_dependencies(self, uses: list[str]) -> list[str]:
        """Every type reachable from `uses`, each once, in first-use (depth-first) order; with an
        explicit stack, as a chain of declarations may be longer than Python's recursion limit."""
        seen: dict[str, None] = {}
        pending = list(reversed(uses))
        while pending:
            qualified = pending.pop()
            if qualified in seen:
                continue
            seen[qualified] = None
            found = self.model.types[qualified]
            if isinstance(found, Message):
                pending.extend(reversed(found.uses))
        return list(seen)

    def is_pod(self, t: Type) -> bool:
        if isinstance(t, (Primitive, FixedString, EnumRef)):
            return True
        if isinstance(t, FixedArray):
            return self.is_pod(t.element)
        if isinstance(t, MessageRef):
            found = self.model.types.get(t.qualified)
            return isinstance(found, Message) and found.is_pod
        return False

    def arrays_fit(self, t: Type, span: Span, what: str) -> bool:
        """Reports a fixed-size array past MAX_POD_SIZE inside a type that has no POD layout (whose
        layout would have reported it): in Vec<…>, Option<…>, a serialized message or node data."""
        try:
            counted_size(t, lambda leaf: type_layout(leaf, self.nested_layout, self.enum_underlying)[0]
                         if self.is_pod(leaf) else None)
        except LayoutTooLarge as error:
            self.reporter.error(span, f"{what} is too large: {error}",
                                "use Vec<T> or bytes for bulk data; a fixed-size array holds at most "
                                f"{MAX_POD_SIZE} bytes wherever it is")
            return False
        return True

    def nested_layout(self, qualified: str) -> tuple[int, int, tuple[Padding, ...]]:
        message = self.model.message(qualified)
        assert message.size is not None and message.alignment is not None
        return message.size, message.alignment, message.padding

    def enum_underlying(self, qualified: str) -> Primitive:
        found = self.model.types[qualified]
        assert isinstance(found, Enum)
        return found.underlying

    def mixin(self, attributes: dict, key: str, directory: str, package: str, item: MessageDecl) -> Mixin | None:
        relative = attributes.get(key)
        if relative is None:
            return None
        span = next(a.span for a in item.attributes if a.name == key)
        normalized = os.path.normpath(relative)
        if os.path.isabs(relative) or normalized.startswith(".."):
            self.reporter.error(span, f"#[{key}] path '{relative}' must stay inside the schema's folder",
                                "keep helper files in a folder beside the schema, e.g. 'mixins/name.inc'")
            return None
        source = os.path.join(directory, normalized)
        if not os.path.isfile(source):
            self.reporter.error(span, f"#[{key}] file '{relative}' not found (looked for '{source}')")
            return None
        self.model.inputs.append(source)
        output = MIXIN_LANGUAGES[key].mixin_path(package, normalized)
        mixin = Mixin(os.path.abspath(source), normalized)
        previous = self.mixin_outputs.setdefault(output, mixin)
        if previous.source_path != mixin.source_path:
            self.reporter.error(span, f"#[{key}] file '{relative}' would be written to '{output}', "
                                f"like '{previous.source_path}'", "give the two helper files different names")
            return None
        return mixin


def _type_paths(expr: TypeExpr) -> list[tuple[str, ...]]:
    if expr.element is not None:
        return _type_paths(expr.element)
    nested = [p for arg in expr.args if isinstance(arg, TypeExpr) for p in _type_paths(arg)]
    return [expr.path] + nested


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
