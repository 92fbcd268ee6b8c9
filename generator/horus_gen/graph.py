"""The node graph of the nodes a run generates: who publishes and subscribes to which topic, who
calls and serves which service. Checked across nodes (one type per topic: an error; a topic
nobody publishes or nobody reads, a service nobody serves: warnings) and printed for
`horus-gen describe --graph` as Graphviz dot or JSON.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from .diagnostics import Note, Reporter
from . import description
from .model import Model, Node, NodeParam, NodeService, NodeTopic


@dataclass
class TopicEnds:
    publishers: list[tuple[Node, NodeTopic]] = field(default_factory=list)
    subscribers: list[tuple[Node, NodeTopic]] = field(default_factory=list)

    def all(self) -> list[tuple[Node, NodeTopic]]:
        return self.publishers + self.subscribers


def topics(model: Model) -> dict[str, TopicEnds]:
    """Every topic the generated nodes name, sorted, with the nodes at each end."""
    found: dict[str, TopicEnds] = {}
    for node in model.generated_nodes():
        for t in node.pubs:
            found.setdefault(t.topic, TopicEnds()).publishers.append((node, t))
        for t in node.subs:
            found.setdefault(t.topic, TopicEnds()).subscribers.append((node, t))
    return dict(sorted(found.items()))


def services(model: Model) -> dict[str, tuple[list[tuple[Node, NodeService]], list[tuple[Node, NodeService]]]]:
    """Every service the generated nodes name: (clients, servers)."""
    found: dict[str, tuple[list, list]] = {}
    for node in model.generated_nodes():
        for s in node.clients:
            found.setdefault(s.service, ([], []))[0].append((node, s))
        for s in node.servers:
            found.setdefault(s.service, ([], []))[1].append((node, s))
    return dict(sorted(found.items()))


def check(model: Model, reporter: Reporter, warn: bool) -> None:
    """Errors for a topic that two nodes give two types; with `warn`, warnings for loose ends."""
    for name, ends in topics(model).items():
        reference_node, reference = ends.all()[0]
        for node, t in ends.all()[1:]:
            if node is not reference_node and t.message != reference.message:
                role = "publishes" if t in [p for _, p in ends.publishers] else "subscribes to"
                reporter.error(t.span, f"node '{node.node_name}' {role} topic '{name}' as '{t.message}', but node "
                               f"'{reference_node.node_name}' has it as '{reference.message}'",
                               "a topic carries one type: make both sides name the same message",
                               (Note(reference.span, f"'{reference_node.node_name}' declares it here"),))
        if not warn:
            continue
        if not ends.publishers:
            for node, t in ends.subscribers:
                reporter.warning(t.span, f"node '{node.node_name}' subscribes to topic '{name}', which no node "
                                 "of these files publishes")
        if not ends.subscribers:
            for node, t in ends.publishers:
                reporter.warning(t.span, f"node '{node.node_name}' publishes topic '{name}', which no node of "
                                 "these files subscribes to")
    if warn:
        for service, (clients, servers) in services(model).items():
            if not servers:
                for node, s in clients:
                    reporter.warning(s.span, f"node '{node.node_name}' calls service '{service}', which no node of "
                                     "these files serves")
            for node, s in servers[1:]:
                reporter.error(s.span, f"service '{service}' is served by two nodes: '{servers[0][0].node_name}' "
                               f"and '{node.node_name}'", "a service has one server",
                               (Note(servers[0][1].span, "first served here"),))


def node_json(node: Node) -> dict:
    """A node as `describe --json` and `describe --graph --json` print it."""
    s = node.settings
    policy = None
    if s.failure_policy is not None:
        policy = {"kind": s.failure_policy.kind,
                  **{k if k.startswith("max_") else k + "_ns": v for k, v in s.failure_policy.arguments}}
    settings = {"order": s.order, "rate_hz": s.rate_hz, "budget_ns": s.budget_ns, "deadline_ns": s.deadline_ns,
                "watchdog_ns": s.watchdog_ns, "on_miss": s.on_miss, "failure_policy": policy,
                "compute": s.compute, "async_io": s.async_io, "on": s.on, "priority": s.priority, "core": s.core}
    return {
        "name": node.node_name, "class": node.qualified, "base_class": f"{node.package}.{node.base}",
        "source": node.source,
        "publishers": [_topic_json(t) for t in node.pubs],
        "subscribers": [_topic_json(t) for t in node.subs],
        "clients": [{"member": c.member, "service": c.service} for c in node.clients],
        "servers": [{"member": c.member, "service": c.service} for c in node.servers],
        "data": [{"member": f.name, "type": f.spelling} for f in node.data],
        "params": [param_json(p) for p in node.params],
        "settings": {k: v for k, v in settings.items() if v is not None and v is not False},
    }


def param_json(param: NodeParam) -> dict:
    """A parameter as horus::ParamDeclaration holds it: values as the type description's VALUE."""
    return {"name": param.name, "type": description.type_tree(param.type), "spelling": param.spelling,
            "default": description.value_tree(param.default), "min": param.minimum, "max": param.maximum,
            "choices": [description.value_tree(c) for c in param.choices], "unit": param.unit,
            "doc": "\n".join(param.docs), "read_only": param.read_only}


def _topic_json(t: NodeTopic) -> dict:
    entry = {"member": t.member, "topic": t.topic, "type": t.message}
    if t.capacity is not None:
        entry["capacity"] = t.capacity
    return entry


def graph_json(model: Model) -> str:
    graph = {
        "nodes": [node_json(n) for n in model.generated_nodes()],
        "topics": [{"name": name, "type": ends.all()[0][1].message,
                    "publishers": [n.node_name for n, _ in ends.publishers],
                    "subscribers": [n.node_name for n, _ in ends.subscribers]}
                   for name, ends in topics(model).items()],
        "services": [{"name": name, "clients": [n.node_name for n, _ in clients],
                      "servers": [n.node_name for n, _ in servers]}
                     for name, (clients, servers) in services(model).items()],
    }
    return json.dumps(graph, indent=2) + "\n"


def graph_dot(model: Model) -> str:
    """Graphviz: nodes are boxes, topics ellipses (publisher -> topic -> subscriber), services
    diamonds (client -> service -> server, dashed)."""
    lines = ["digraph horus {", "  rankdir=LR;", "  node [fontname=\"Helvetica\"];"]
    for node in model.generated_nodes():
        rate = f"\\n{node.settings.rate_hz:g} Hz" if node.settings.rate_hz else (
            f"\\non {node.settings.on}" if node.settings.on else "")
        lines.append(f"  {_quote('node:' + node.node_name)} [shape=box, label={_quote(node.node_name, rate)}];")
    for name, ends in topics(model).items():
        label = _quote(name, "\\n" + ends.all()[0][1].message)
        lines.append(f"  {_quote('topic:' + name)} [shape=ellipse, label={label}];")
        for node, _ in ends.publishers:
            lines.append(f"  {_quote('node:' + node.node_name)} -> {_quote('topic:' + name)};")
        for node, _ in ends.subscribers:
            lines.append(f"  {_quote('topic:' + name)} -> {_quote('node:' + node.node_name)};")
    for name, (clients, servers) in services(model).items():
        lines.append(f"  {_quote('service:' + name)} [shape=diamond, label={_quote(name)}];")
        for node, _ in clients:
            lines.append(f"  {_quote('node:' + node.node_name)} -> {_quote('service:' + name)} [style=dashed];")
        for node, _ in servers:
            lines.append(f"  {_quote('service:' + name)} -> {_quote('node:' + node.node_name)} [style=dashed];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _quote(text: str, raw_suffix: str = "") -> str:
    """A dot string; `raw_suffix` is already escaped (holds \\n line breaks)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + raw_suffix + '"'
