"""The horus-gen command line: generate, check, describe, list-outputs.

Exit status: 0 success, 1 schema errors (all of them on stderr), 2 usage errors.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import sys

from . import description, graph
from .data import DataPaths
from .diagnostics import Reporter
from .lang import LANGUAGES, emitter, idl
from .lang.common import template_files
from .loader import Options
from .model import Action, Enum, EnumValue, Message, Model, Node, NodeParam, Service
from .output import write_depfile, write_outputs, touch
from .parser import FILE_KINDS
from .resolve import Resolver


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="horus-gen", description="The HORUS schema compiler.")
    commands = parser.add_subparsers(dest="command", required=True)

    def common(sub: argparse.ArgumentParser) -> None:
        sub.add_argument("files", nargs="+", metavar="FILE", help=".hmsg, .hsrv, .haction or .hnode schema files")
        sub.add_argument("-I", dest="include_dirs", action="append", default=[], metavar="DIR",
                         help="folder to resolve imports and qualified names in (repeatable)")
        sub.add_argument("--package", help="package of files that declare none (default: their folder's name)")

    def outputs(sub: argparse.ArgumentParser) -> None:
        sub.add_argument("--lang", default="cpp", help="comma-separated languages: " + ",".join(LANGUAGES))
        sub.add_argument("--out", required=True, metavar="OUT", help="output folder (OUT/cpp, OUT/python)")

    generate = commands.add_parser("generate", help="write C++ headers and Python modules")
    common(generate)
    outputs(generate)
    generate.add_argument("--depfile", help="write a Makefile-style list of every file read")
    generate.add_argument("--stamp", help="file to touch on success (the depfile's target)")
    common(commands.add_parser("check", help="parse and resolve only: report errors, write nothing; "
                                "with .hnode files, also warn about topics nobody publishes or reads"))
    describe = commands.add_parser("describe", help="tier, size, alignment, fingerprint, offsets, padding "
                                   "(--json: the type description, docs/type-description.md)")
    common(describe)
    describe.add_argument("--json", action="store_true", help="machine-readable output")
    describe.add_argument("--graph", action="store_true",
                          help="the graph of the .hnode files' nodes, topics and services (Graphviz dot, or JSON)")
    listing = commands.add_parser("list-outputs", help="print the files generate would write")
    common(listing)
    outputs(listing)
    return parser


def main(data: DataPaths, argv: list[str] | None = None) -> int:
    """Runs one command; `data` is where the launcher keeps the templates and the support module."""
    args = build_parser().parse_args(argv)
    usage = check_usage(args)
    if usage:
        print(f"horus-gen: error: {usage}", file=sys.stderr)
        return 2
    try:
        return run(args, data)
    except KeyboardInterrupt:
        return 130
    except Exception as error:  # a bug in horus-gen, not in the schema: say so without a traceback
        print(f"horus-gen: internal error: {type(error).__name__}: {error}\n"
              "This is a bug in horus-gen; please report it with the schema that triggered it.", file=sys.stderr)
        return 1


def check_usage(args: argparse.Namespace) -> str | None:
    for path in args.files:
        if os.path.splitext(path)[1] not in FILE_KINDS:
            return f"{path}: not a schema file (expected .hmsg, .hsrv, .haction or .hnode)"
        if not os.path.isfile(path):
            return f"{path}: no such file"
    for folder in args.include_dirs:
        if not os.path.isdir(folder):
            return f"-I {folder}: no such folder"
    if hasattr(args, "lang"):
        unknown = [lang for lang in args.lang.split(",") if lang not in LANGUAGES]
        if unknown:
            return f"unknown language '{unknown[0]}' (known: {', '.join(LANGUAGES)})"
    if getattr(args, "depfile", None) and not getattr(args, "stamp", None):
        return "--depfile needs --stamp (the file the dependencies belong to)"
    return None


def run(args: argparse.Namespace, data: DataPaths) -> int:
    reporter = Reporter()
    model = Resolver(reporter, Options(args.include_dirs, args.package)).run(args.files)
    graph.check(model, reporter, warn=args.command == "check")
    if reporter.has_errors or reporter.warnings:
        sys.stderr.write(reporter.render())
    if reporter.has_errors:
        return 1
    if args.command == "check":
        return 0
    if args.command == "describe":
        if args.graph:
            print(graph.graph_json(model) if args.json else graph.graph_dot(model), end="")
        else:
            print(describe_json(model) if args.json else describe_text(model), end="")
        return 0
    languages = args.lang.split(",")
    files: dict[str, str] = {}
    for language in languages:
        files.update(emitter(language)(model, data))
    if args.command == "list-outputs":
        for relative in sorted(files):
            print(os.path.abspath(os.path.join(args.out, relative)))
        return 0
    try:
        write_outputs(args.out, files)
    except OSError as error:
        print(f"horus-gen: error: cannot write the output to '{args.out}': {error}", file=sys.stderr)
        return 1
    if args.depfile:
        write_depfile(args.depfile, args.stamp, model.inputs + template_files(data, languages) + generator_sources(data)
                      + ([data.python_support] if "python" in languages else []))
    if args.stamp:
        touch(args.stamp)
    return 0


def generator_sources(data: DataPaths) -> list[str]:
    """The generator's own files: a change to any of them may change every output."""
    package = os.path.dirname(os.path.abspath(__file__))
    return sorted(glob.glob(os.path.join(package, "**", "*.py"), recursive=True)) + \
        [data.launcher]


def describe_text(model: Model) -> str:
    out: list[str] = []
    for item in model.generated_items():
        if isinstance(item, Node):
            out.append(describe_node(item))
        elif isinstance(item, Service):
            called = f"  called {item.wire_name}" if item.wire_name != item.name else ""
            out.append(f"{item.qualified}  service  request {item.request.qualified}  "
                       f"response {item.response.qualified}{called}  fingerprint 0x{item.fingerprint:016x}\n")
        elif isinstance(item, Action):
            out.append(f"{item.qualified}  action  goal {item.goal.qualified}  result {item.result.qualified}  "
                       f"feedback {item.feedback.qualified}  fingerprint 0x{item.fingerprint:016x}\n")
            out.extend(f"    service {s.wire_name}: {s.qualified}\n" for s in item.services)
            out.extend(f"    topic {topic}: {m.qualified}\n" for topic, m in item.topics)
        elif isinstance(item, Enum):
            out.append(f"{item.qualified}  enum {item.underlying.name}  fingerprint 0x{item.fingerprint:016x}\n")
            out.extend(f"    {v.name} = {v.value}\n" for v in item.variants)
        else:
            tier = f"POD  size {item.size}  align {item.alignment}" if item.is_pod else "serialized (MessagePack)"
            out.append(f"{item.qualified}  message  {tier}  fingerprint 0x{item.fingerprint:016x}\n")
            if item.is_pod:
                out.append("    offset  size  field\n")
                rows = [(f.offset, f.size, f"{f.name}: {f.spelling}") for f in item.fields]
                rows += [(p.offset, p.size, "(padding)") for p in item.padding]
                out.extend(f"    {o:6d}  {s:4d}  {text}\n" for o, s, text in sorted(rows))
            else:
                out.extend(f"    {f.name}: {f.spelling}\n" for f in item.fields)
        out.append("\n")
    return "".join(out)


def describe_node(node: Node) -> str:
    settings = graph.node_json(node)["settings"]
    lines = [f"{node.qualified}  node '{node.node_name}'  class {node.base}"
             + "".join(f"  {k} {_setting_text(v)}" for k, v in settings.items()) + "\n"]
    lines += [f"    sub {t.member}: {t.message} -> \"{t.topic}\"\n" for t in node.subs]
    lines += [f"    pub {t.member}: {t.message} -> \"{t.topic}\"\n" for t in node.pubs]
    lines += [f"    client {s.member}: {s.service}\n" for s in node.clients]
    lines += [f"    server {s.member}: {s.service}\n" for s in node.servers]
    lines += [f"    data {f.name}: {f.spelling}\n" for f in node.data]
    lines += [f"    param {p.name}: {p.spelling} = {_param_value(p.default)}{_param_limits(p)}\n" for p in node.params]
    return "".join(lines)


def _param_value(value) -> str:
    """A value as a YAML parameter file spells it: an enumerator by its name, the rest as JSON."""
    return value.variant if isinstance(value, EnumValue) else json.dumps(description.value_tree(value))


def _param_limits(param: NodeParam) -> str:
    """`  min 0.0  max 2.0  choices ["eco", "sport"]  unit m/s  read-only`: what is declared."""
    parts = []
    if param.minimum is not None:
        parts.append(f"min {param.minimum}")
    if param.maximum is not None:
        parts.append(f"max {param.maximum}")
    if param.choices:
        parts.append("choices [" + ", ".join(_param_value(c) for c in param.choices) + "]")
    if param.unit:
        parts.append(f"unit {param.unit}")
    if param.read_only:
        parts.append("read-only")
    return "".join(f"  {p}" for p in parts)


def _setting_text(value) -> str:
    if isinstance(value, dict):
        return value["kind"] + ("{" + ", ".join(f"{k}: {v}" for k, v in value.items() if k != "kind") + "}"
                                if len(value) > 1 else "")
    return str(value).lower() if isinstance(value, bool) else str(value)


def describe_json(model: Model) -> str:
    """The type description (docs/type-description.md) of every type of the inputs, each message
    also with its DDS type name, and the nodes of the inputs (kind "node", as in the graph)."""
    dds_types = {m.qualified: {"dds_type": idl.dds_type_name(model, m.qualified)}
                 for m in model.generated_items() if isinstance(m, Message)}
    tree = description.model_description(model, dds_types)
    tree["types"] += [{"kind": "node", "package": n.package, **graph.node_json(n)} for n in model.generated_nodes()]
    return json.dumps(tree, indent=2) + "\n"
