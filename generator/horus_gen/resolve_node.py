"""Nodes (.hnode): their settings, topics, services and data checked and resolved into model.Node.

Called by the resolver once every message and service is built, so that a node's topics and
services name finished types. Errors are reported and resolution carries on; a node with an error
is left out of the model (its error was reported).
"""
from __future__ import annotations

import re
from typing import TYPE_CHECKING

from . import identity
from .diagnostics import Note, Span, did_you_mean
from .lang import keyword_clash
from .model import (EnumRef, FailurePolicy, Field, Message, MessageRef, Node, NodeService, NodeSettings,
                    NodeTopic, Optional, Vec, FixedArray, base_class_name)
from .names import NODE_RESERVED_MEMBERS
from .resolve_params import ParamResolver
from .syntax import Literal, NodeDecl, NodeEndpointDecl, NodeSettingDecl, TypeExpr
from .values import check_attributes, convert_value

if TYPE_CHECKING:
    from .loader import Unit
    from .resolve import Resolver

# What each setting takes (docs/schema-language.md, "Nodes").
SETTINGS = {"name": "string", "order": "int", "rate": "rate", "budget": "duration", "deadline": "duration",
            "watchdog": "duration", "on_miss": "miss", "failure_policy": "policy", "compute": "bool",
            "async_io": "bool", "on": "string", "priority": "int", "core": "int"}
DURATION_UNITS = {"ns": 1, "us": 1_000, "ms": 1_000_000, "s": 1_000_000_000}
MISS_POLICIES = ("Warn", "Skip", "SafeMode", "Stop")
# Each failure policy's arguments: "count" or "duration" (the runtime's FailurePolicy fields).
FAILURE_POLICIES = {"Fatal": {}, "Restart": {"max_restarts": "count", "initial_backoff": "duration"},
                    "Skip": {"max_failures": "count", "cooldown": "duration"}, "Ignore": {}}
# Settings that each choose the node's execution class: at most one may be given.
EXECUTION_CLASS_SETTINGS = ("on", "compute", "async_io")
ENDPOINT_ATTRIBUTES = {"capacity": "int"}
# The runtime's limits: topic names (shm_segment.cpp, validate_segment_name), SCHED_FIFO priorities,
# and the most slots a topic ring is created with here (2^20; a larger ring is no robot's topic).
TOPIC_NAME = re.compile(r"[A-Za-z0-9_.\-]{1,200}")
MAX_CAPACITY = 1 << 20
PRIORITIES = (1, 99)
MAX_DURATION_NS = (1 << 63) - 1


class NodeResolver:
    def __init__(self, resolver: "Resolver"):
        self.resolver = resolver
        self.reporter = resolver.reporter
        self.model = resolver.model

    def build(self, item: NodeDecl, unit: "Unit") -> None:
        errors_before = len(self.reporter.diagnostics)
        check_attributes(self.reporter, item.attributes, {}, f"node '{item.name}'")
        values = self.settings(item)
        members: dict[str, Span] = {}
        blocks: dict[str, list] = {"sub": [], "pub": [], "client": [], "server": []}
        for kind, _, entries in item.blocks:
            for entry in entries:
                self.check_member(item, entry.name, entry.span, members)
                if kind in ("sub", "pub"):
                    topic = self.topic(item, kind, entry, unit)
                    if topic is not None:
                        blocks[kind].append(topic)
                else:
                    service = self.service(item, kind, entry, unit)
                    if service is not None:
                        blocks[kind].append(service)
        self.check_topics(item, blocks["sub"], blocks["pub"])
        data = []
        for f in item.data:
            self.check_member(item, f.name, f.span, members)
            check_attributes(self.reporter, f.attributes, {}, f"data field '{f.name}'")
            t = self.resolver.resolve_type(f.type, unit)
            if t is None or not self.resolver.arrays_fit(t, f.span, f"data field '{f.name}'"):
                continue
            default = None
            if f.default is not None:
                default = convert_value(self.reporter, self.model.types, f.default, t, f"data field '{f.name}'")
            data.append(Field(f.name, t, identity.spelling(t), default, "", f.docs, f.span))
        params = []
        param_resolver = ParamResolver(self.resolver)
        for f in item.params:
            self.check_member(item, f.name, f.span, members)
            param = param_resolver.build(item.name, f, unit)
            if param is not None:
                params.append(param)
        for server in blocks["server"]:
            starter = f"serve_{server.member}"
            if starter in members:
                self.reporter.error(members[starter], f"member name '{starter}' is taken by the method that starts "
                                    f"server '{server.member}'", "rename it")
        on = values.get("on")
        if on is not None and on[0] not in {t.topic for t in blocks["sub"]}:
            self.reporter.error(on[1], f"node '{item.name}' ticks on topic '{on[0]}', which it does not subscribe to",
                                did_you_mean(on[0], [t.topic for t in blocks["sub"]])
                                or f"add it to the sub block: sub {{ {on[0].replace('.', '_').replace('-', '_')}: Type -> \"{on[0]}\" }}")
        if len(self.reporter.diagnostics) > errors_before:
            return
        uses: list[str] = []
        for t in blocks["sub"] + blocks["pub"]:
            uses.append(t.message)
        for s in blocks["client"] + blocks["server"]:
            uses.append(s.service)
        for f in data + params:
            uses.extend(_named(f.type))
        name = values.get("name")
        self.model.nodes[f"{unit.package}.{item.name}"] = Node(
            package=unit.package, name=item.name, node_name=name[0] if name else item.name,
            subs=tuple(blocks["sub"]), pubs=tuple(blocks["pub"]), clients=tuple(blocks["client"]),
            servers=tuple(blocks["server"]), data=tuple(data), settings=self.node_settings(values),
            docs=item.docs, source=unit.path, uses=tuple(dict.fromkeys(uses)), params=tuple(params))

    # -- settings ----------------------------------------------------------------------------------
    def settings(self, item: NodeDecl) -> dict[str, tuple[object, Span]]:
        """Every valid setting as (value, span): ns for durations, Hz for rates."""
        found: dict[str, tuple[object, Span]] = {}
        seen: dict[str, Span] = {}
        for setting in item.settings:
            kind = SETTINGS.get(setting.name)
            if kind is None:
                self.reporter.error(setting.span, f"unknown setting '{setting.name}' in node '{item.name}'",
                                    did_you_mean(setting.name, list(SETTINGS))
                                    or "known settings: " + ", ".join(SETTINGS))
                continue
            if setting.name in seen:
                self.reporter.error(setting.span, f"setting '{setting.name}' is given twice in node '{item.name}'",
                                    notes=(Note(seen[setting.name], "first given here"),))
                continue
            seen[setting.name] = setting.span
            value = self.setting_value(setting, kind)
            if value is not None:
                found[setting.name] = (value, setting.value.span)
        chosen = [s for s in EXECUTION_CLASS_SETTINGS if s in found and found[s][0] not in (False,)]
        if len(chosen) > 1:
            self.reporter.error(found[chosen[1]][1], f"node '{item.name}' sets both '{chosen[0]}' and '{chosen[1]}'",
                                "each chooses how the node runs (event, compute pool, own I/O thread): keep one")
        budget, deadline = found.get("budget"), found.get("deadline")
        if budget and deadline and budget[0] > deadline[0]:
            self.reporter.error(budget[1], f"budget of node '{item.name}' is longer than its deadline",
                                "the budget is what a tick should take, the deadline when it must have ended")
        if "on" in found and "rate" in found:
            self.reporter.error(found["rate"][1], f"node '{item.name}' ticks on topic '{found['on'][0]}', "
                                "so it cannot also have a rate", "remove the rate, or 'on'")
        return found

    def setting_value(self, setting: NodeSettingDecl, kind: str) -> object | None:
        literal, name = setting.value, setting.name
        if kind not in ("rate", "duration") and setting.unit is not None:
            self.reporter.error(setting.unit[1], f"setting '{name}' takes no unit")
            return None
        if kind != "policy" and setting.arguments is not None:
            self.reporter.error(literal.span, f"setting '{name}' takes no arguments")
            return None
        if kind == "string":
            if literal.kind != "string":
                return self.wrong(setting, 'a quoted string: name: "motor"')
            if name == "on" and not TOPIC_NAME.fullmatch(literal.value):
                return self.bad_topic_name(literal)
            if name == "name" and not literal.value:
                return self.wrong(setting, "a non-empty name")
            return literal.value
        if kind == "bool":
            return literal.value if literal.kind == "bool" else self.wrong(setting, "true or false")
        if kind == "int":
            if literal.kind != "int":
                return self.wrong(setting, "a whole number")
            low, high = {"priority": PRIORITIES, "core": (0, 4095), "order": (-(1 << 31), (1 << 31) - 1)}[name]
            if not low <= literal.value <= high:
                self.reporter.error(literal.span, f"{name} {literal.value} is out of range ({low}..{high})")
                return None
            return literal.value
        if kind == "rate":
            if literal.kind not in ("int", "float") or literal.value <= 0:
                return self.wrong(setting, "a positive number of hertz: rate: 100 hz")
            if setting.unit is not None and setting.unit[0] != "hz":
                self.reporter.error(setting.unit[1], f"unknown rate unit '{setting.unit[0]}'", "write hz: rate: 100 hz")
                return None
            return float(literal.value)
        if kind == "duration":
            ns = self.duration(setting)
            if ns == 0:
                self.reporter.error(literal.span, f"{name} must be longer than zero")
                return None
            return ns
        if kind == "miss":
            variant = literal.value[-1] if literal.kind == "path" else None
            if variant not in MISS_POLICIES or (len(literal.value) > 1 and literal.value[:-1] != ("Miss",)):
                return self.wrong(setting, "one of " + ", ".join(MISS_POLICIES), did_you_mean(str(variant), MISS_POLICIES))
            return variant
        return self.policy(setting)

    def duration(self, setting: NodeSettingDecl) -> int | None:
        literal = setting.value
        if literal.kind not in ("int", "float") or literal.value < 0 or setting.unit is None:
            return self.wrong(setting, f"a duration with its unit: {setting.name}: 300 us (ns, us, ms or s)")
        factor = DURATION_UNITS.get(setting.unit[0])
        if factor is None:
            self.reporter.error(setting.unit[1], f"unknown duration unit '{setting.unit[0]}'",
                                did_you_mean(setting.unit[0], list(DURATION_UNITS)) or "use ns, us, ms or s")
            return None
        ns = round(literal.value * factor)
        if ns > MAX_DURATION_NS:
            self.reporter.error(literal.span, f"{setting.name} is longer than a std::chrono::nanoseconds holds")
            return None
        return ns

    def policy(self, setting: NodeSettingDecl) -> FailurePolicy | None:
        literal = setting.value
        variant = literal.value[-1] if literal.kind == "path" else None
        if variant not in FAILURE_POLICIES or (len(literal.value) > 1 and literal.value[:-1] != ("FailurePolicy",)):
            return self.wrong(setting, "one of " + ", ".join(FAILURE_POLICIES) + " (Restart and Skip take arguments: "
                              "Restart { max_restarts: 3, initial_backoff: 10 ms })",
                              did_you_mean(str(variant), list(FAILURE_POLICIES)))
        allowed = FAILURE_POLICIES[variant]
        arguments: list[tuple[str, int]] = []
        for argument in setting.arguments or ():
            kind = allowed.get(argument.name)
            if kind is None:
                self.reporter.error(argument.span, f"failure policy {variant} has no argument '{argument.name}'",
                                    did_you_mean(argument.name, list(allowed))
                                    or (f"it takes {', '.join(allowed)}" if allowed else f"{variant} takes no arguments"))
                return None
            if any(argument.name == a for a, _ in arguments):
                self.reporter.error(argument.span, f"argument '{argument.name}' is given twice")
                return None
            if kind == "count":
                low = 1 if argument.name == "max_failures" else 0
                if argument.value.kind != "int" or not low <= argument.value.value <= 0xFFFFFFFF or argument.unit:
                    return self.wrong(argument, f"a whole number from {low} to 4294967295")
                arguments.append((argument.name, argument.value.value))
            else:
                ns = self.duration(argument)
                if ns is None:
                    return None
                arguments.append((argument.name, ns))
        return FailurePolicy(variant, tuple(sorted(arguments, key=lambda a: list(allowed).index(a[0]))))

    def wrong(self, setting: NodeSettingDecl, expected: str, hint: str | None = None) -> None:
        found = setting.value
        shown = "::".join(found.value) if found.kind == "path" else (
            "a list" if found.kind == "list" else repr(found.value) if found.kind == "string" else str(found.value).lower()
            if found.kind == "bool" else str(found.value))
        unit = f" {setting.unit[0]}" if setting.unit else ""
        self.reporter.error(found.span, f"setting '{setting.name}' needs {expected}, found {shown}{unit}", hint)
        return None

    def bad_topic_name(self, literal: Literal) -> None:
        self.reporter.error(literal.span, f"topic name '{literal.value}' is not valid",
                            "use 1 to 200 of A-Z a-z 0-9 _ . - (a topic is a file in shared memory)")
        return None

    @staticmethod
    def node_settings(values: dict[str, tuple[object, Span]]) -> NodeSettings:
        def get(key: str):
            return values[key][0] if key in values else None
        return NodeSettings(order=get("order"), rate_hz=get("rate"), budget_ns=get("budget"),
                            deadline_ns=get("deadline"), watchdog_ns=get("watchdog"), on_miss=get("on_miss"),
                            failure_policy=get("failure_policy"), compute=bool(get("compute")),
                            async_io=bool(get("async_io")), on=get("on"), priority=get("priority"),
                            core=get("core"))

    # -- members -----------------------------------------------------------------------------------
    def check_member(self, item: NodeDecl, name: str, span: Span, members: dict[str, Span]) -> None:
        if name in members:
            self.reporter.error(span, f"duplicate member '{name}' in node '{item.name}'",
                                "topic, service, data and params members share one namespace (self.<name> in Python)",
                                (Note(members[name], "first declared here"),))
            return
        members[name] = span
        clash = keyword_clash(name)
        if clash:
            self.reporter.error(span, f"member name '{name}' is {clash}", "rename it")
        elif name.startswith("_"):
            self.reporter.error(span, f"member name '{name}' starts with '_'",
                                "horus.Node keeps its own state in such attributes; rename it")
        elif name in NODE_RESERVED_MEMBERS:
            self.reporter.error(span, f"member name '{name}' is taken by the generated node class "
                                "(a horus::Node / horus.Node member)", "rename it")
        elif name in (item.name, base_class_name(item.name)):
            self.reporter.error(span, f"member '{name}' has the name of its node class", "rename it")

    def topic(self, item: NodeDecl, kind: str, entry: NodeEndpointDecl, unit: "Unit") -> NodeTopic | None:
        attributes = self.endpoint_attributes(entry)
        t = self.resolver.resolve_type(entry.type, unit)
        if t is None:
            return None
        if not isinstance(t, MessageRef):
            self.reporter.error(entry.type.span, f"topic member '{entry.name}' has type '{identity.spelling(t)}'",
                                "a topic carries a message type (declare one in a .hmsg file)")
            return None
        message = self.model.types.get(t.qualified)
        if not isinstance(message, Message):
            return None  # its definition is broken: reported there
        if entry.topic is not None:
            topic = entry.topic.value
            if not TOPIC_NAME.fullmatch(topic):
                return self.bad_topic_name(entry.topic)
        else:
            topic = message.topic or entry.name
        return NodeTopic(entry.name, topic, message.qualified, attributes.get("capacity"), entry.docs, entry.span)

    def endpoint_attributes(self, entry: NodeEndpointDecl) -> dict[str, int]:
        found: dict[str, int] = {}
        for attribute in entry.attributes:
            if attribute.name not in ENDPOINT_ATTRIBUTES:
                self.reporter.error(attribute.span, f"unknown attribute '{attribute.name}' on '{entry.name}'",
                                    did_you_mean(attribute.name, list(ENDPOINT_ATTRIBUTES))
                                    or "known here: #[capacity = N]")
                continue
            value = attribute.value
            if value is None or value.kind != "int" or not 1 <= value.value <= MAX_CAPACITY:
                self.reporter.error(value.span if value else attribute.span,
                                    f"#[capacity] needs a whole number of slots from 1 to {MAX_CAPACITY}",
                                    "write #[capacity = 16]")
                continue
            found[attribute.name] = value.value
        return found

    def service(self, item: NodeDecl, kind: str, entry: NodeEndpointDecl, unit: "Unit") -> NodeService | None:
        if entry.attributes:
            self.reporter.error(entry.attributes[0].span, f"'{kind}' entries take no attributes")
        expr: TypeExpr = entry.type
        if expr.args or expr.element is not None:
            self.reporter.error(expr.span, f"'{entry.name}' must name a service (a .hsrv item)")
            return None
        name = ".".join(expr.path)
        candidates = [f"{unit.package}.{name}"] if len(expr.path) == 1 else [name]
        found = next((c for c in candidates if c in self.resolver.service_decls), None)
        if found is None:
            known = {q.replace(".", "::") for q in self.resolver.service_decls}
            known |= {q.rsplit(".", 1)[1] for q in self.resolver.service_decls if q.startswith(unit.package + ".")}
            what = "a message, not a service" if any(c in self.resolver.decls for c in candidates) else None
            self.reporter.error(expr.span, f"unknown service '{'::'.join(expr.path)}'" + (f": it is {what}" if what else ""),
                                did_you_mean("::".join(expr.path), known)
                                or "a client or server names a service declared in a .hsrv file")
            return None
        if found not in self.model.services:
            return None  # broken: reported where it is declared
        return NodeService(entry.name, found, entry.docs, entry.span)

    def check_topics(self, item: NodeDecl, subs: list[NodeTopic], pubs: list[NodeTopic]) -> None:
        """A topic is declared once per direction, and with one type in both."""
        for kind, entries in (("sub", subs), ("pub", pubs)):
            seen: dict[str, NodeTopic] = {}
            for t in entries:
                if t.topic in seen:
                    self.reporter.error(t.span, f"node '{item.name}' declares topic '{t.topic}' twice in its "
                                        f"'{kind}' block", "one member per topic and direction",
                                        (Note(seen[t.topic].span, "first declared here"),))
                seen.setdefault(t.topic, t)
        published = {t.topic: t for t in pubs}
        for t in subs:
            other = published.get(t.topic)
            if other is not None and other.message != t.message:
                self.reporter.error(t.span, f"node '{item.name}' subscribes to topic '{t.topic}' as '{t.message}' "
                                    f"but publishes it as '{other.message}'", "a topic carries one type",
                                    (Note(other.span, "published here"),))


def _named(t) -> list[str]:
    if isinstance(t, (MessageRef, EnumRef)):
        return [t.qualified]
    if isinstance(t, (FixedArray, Vec, Optional)):
        return _named(t.element)
    return []
