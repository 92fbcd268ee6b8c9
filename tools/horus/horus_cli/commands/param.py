"""`horus param`: list, read, write, describe, watch, dump and load nodes' parameters.

Reads are the shared-memory store's (horus.Params, no round trip to the node); writes go through
the node that owns the parameter, which may refuse them: a refusal is exit status 1 with the
reason. Values are given as YAML, as `topic pub` takes them (`1.5`, `true`, `Velocity`,
`[1.0, 0.5, 0.0]`).
"""
from __future__ import annotations

import functools
import json
import sys

from horus_cli.common import (EXIT_OK, CommandFailed, did_you_mean, emit, namespace_name,
                              positive_float, positive_int, table)
from horus_cli.schemas import parse_value


def _horus():
    """The horus package, imported on first use (see common.introspection)."""
    import horus
    return horus


def _reporting(handler):
    """The handler with the runtime's refusals (a store that cannot be read, a parameter file's
    mistakes, a value of the wrong type) as one line with exit status 1."""
    @functools.wraps(handler)
    def run(args) -> int:
        try:
            return handler(args)
        except _horus().ParamError as error:
            raise CommandFailed(str(error)) from None
    return run


def _namespace(args) -> str | None:
    return args.namespace or None


def _nodes(args) -> list[str]:
    return _horus().param_nodes(_namespace(args))


def _check_node(args, node: str) -> None:
    """The one error for a node without a store, with the closest names."""
    known = _nodes(args)
    if node not in known:
        raise CommandFailed(f"no node '{node}' with parameters in namespace "
                            f"'{namespace_name(args)}'{did_you_mean(node, known)}")


def _open(args, node: str):
    """The node's parameters (horus.Params)."""
    _check_node(args, node)
    return _horus().Params(node, _namespace(args))


def _info(args, params, name: str):
    known = params.names()
    if name not in known:
        raise CommandFailed(f"node '{params.node}' has no parameter '{name}'"
                            f"{did_you_mean(name, known)}")
    return params.get(name)


def _text(value) -> str:
    """A value as YAML spells it on one line (what `param set` takes back)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_text(item) for item in value) + "]"
    return str(value)


def _row(params, info) -> dict:
    """A parameter as listings show it: its declaration, value and version, and its owner."""
    row = info.as_dict()
    row["owner_alive"], row["owner_pid"] = params.owner_alive, params.owner_pid
    return row


def _owner(row: dict) -> str:
    return f"pid {row['owner_pid']}" if row["owner_alive"] else "not running"


@_reporting
def param_list(args) -> int:
    if args.node is None:
        nodes = _nodes(args)
    else:
        _check_node(args, args.node)
        nodes = [args.node]
    rows = []
    for node in nodes:
        with _horus().Params(node, _namespace(args)) as params:
            rows += [_row(params, info) for info in params.list()]
    if args.names:  # for completion: the nodes, or the parameters of the one given
        for name in nodes if args.node is None else [row["name"] for row in rows]:
            print(name)
        return EXIT_OK

    def render(found):
        table(["NODE", "NAME", "TYPE", "VALUE", "UNIT", "VERSION", "OWNER"],
              [[r["node"], r["name"], r["type"], _text(r["value"]), r["unit"] or "-",
                r["version"], _owner(r)]
               for r in found])
    emit(rows, args.json, render)
    return EXIT_OK


@_reporting
def param_get(args) -> int:
    with _open(args, args.node) as params:
        row = _row(params, _info(args, params, args.name))
    emit(row, args.json, lambda r: print(_text(r["value"])))
    return EXIT_OK


@_reporting
def param_describe(args) -> int:
    with _open(args, args.node) as params:
        row = _row(params, _info(args, params, args.name))

    def render(r):
        print(f"parameter: {r['node']}.{r['name']}")
        print(f"type: {r['type']}" + (f" ({', '.join(r['enumerators'])})"
                                      if r["enumerators"] else ""))
        print(f"value: {_text(r['value'])} (version {r['version']})")
        print(f"default: {_text(r['default'])}")
        if r["min"] is not None or r["max"] is not None:
            low = "-inf" if r["min"] is None else f"{r['min']:g}"
            high = "inf" if r["max"] is None else f"{r['max']:g}"
            print(f"range: [{low}, {high}]")
        if r["choices"]:
            print(f"choices: {_text(r['choices'])}")
        if r["unit"]:
            print(f"unit: {r['unit']}")
        if r["read_only"]:
            print("read-only: true")
        if r["doc"]:
            print(f"doc: {r['doc']}")
        print(f"owner: {_owner(r)}")
    emit(row, args.json, render)
    return EXIT_OK


def _value_for(info, text: str):
    """The value a command line gives, parsed as YAML; for a String parameter the text itself
    when YAML reads something else (`set cam label 42` sets "42", `set cam label 'a: b'` "a: b")."""
    what = f"value of {info.node}.{info.name}"
    if info.type == "String":
        try:
            value = parse_value(text, what)
        except CommandFailed:
            return text
        return value if isinstance(value, str) else text
    return parse_value(text, what)


@_reporting
def param_set(args) -> int:
    with _open(args, args.node) as params:
        info = _info(args, params, args.name)
        value = _value_for(info, args.value)
        try:
            result = params.set(args.name, value, persist=args.persist, timeout=args.timeout,
                                source="horus param")
        except _horus().ParamError as error:
            raise CommandFailed(f"cannot set {args.node}.{args.name}: {error}") from None
        # A value kept for the next start is not the store's value yet: show what was kept.
        kept = result.accepted and args.persist and not params.owner_alive
        row = {"node": args.node, "name": args.name, "accepted": result.accepted,
               "reason": result.reason, "version": result.version, "kept_for_next_start": kept,
               "value": value if kept else params.get(args.name).value}
    if args.json:
        emit(row, True, None)
    if not result.accepted:
        raise CommandFailed(f"{args.node}.{args.name} refused: {result.reason}")
    if kept and not args.json:
        print(f"{args.node}.{args.name} = {_text(row['value'])} (kept for the next start of "
              f"{args.node})")
    elif not args.json:
        print(f"{args.node}.{args.name} = {_text(row['value'])} (version {row['version']})")
    return EXIT_OK


@_reporting
def param_watch(args) -> int:
    with _open(args, args.node) as params:
        if args.name is not None:
            _info(args, params, args.name)
        seen = 0
        while args.count is None or seen < args.count:
            for info in params.watch(timeout=1.0):
                if args.name is not None and info.name != args.name:
                    continue
                seen += 1
                if args.json:
                    print(json.dumps({"node": info.node, "name": info.name, "value": info.value,
                                      "version": info.version}, sort_keys=True))
                else:
                    print(f"{info.node}.{info.name} = {_text(info.value)} "
                          f"(version {info.version})")
                sys.stdout.flush()
    return EXIT_OK


@_reporting
def param_dump(args) -> int:
    horus = _horus()
    nodes = args.nodes or None
    for node in nodes or ():
        _check_node(args, node)
    if args.json:
        dumped = {}
        for node in nodes or _nodes(args):
            with horus.Params(node, _namespace(args)) as params:
                dumped[node] = {info.name: info.value for info in params.list()}
        emit(dumped, True, None)
    else:
        sys.stdout.write(horus.dump_params(nodes, _namespace(args)))
    return EXIT_OK


@_reporting
def param_load(args) -> int:
    horus = _horus()
    results = horus.load_params(args.file, _namespace(args), persist=args.persist,
                                timeout=args.timeout)
    refused = [result for result in results if not result.accepted]
    if args.json:
        emit([{"accepted": r.accepted, "reason": r.reason, "version": r.version}
              for r in results], True, None)
    elif not refused:
        print(f"set {len(results)} parameter{'s' if len(results) != 1 else ''} from {args.file}")
    if refused:
        raise CommandFailed(f"{args.file}: {len(refused)} of {len(results)} values refused: "
                            + "; ".join(r.reason for r in refused))
    return EXIT_OK


def register(commands) -> None:
    param = commands.group("param", "nodes' parameters: list, get, set, describe, watch, dump, "
                                    "load")
    sub = commands.action(param, "list", "the parameters of every node (or of one) with their "
                                         "values", param_list)
    sub.add_argument("node", nargs="?", help="only this node's")
    sub.add_argument("--names", action="store_true",
                     help="only the names: of the nodes, or of NODE's parameters")

    sub = commands.action(param, "get", "one parameter's current value", param_get)
    sub.add_argument("node")
    sub.add_argument("name")

    sub = commands.action(param, "set", "write a parameter through its node, which may refuse "
                                        "it (exit status 1 with the reason)", param_set)
    sub.add_argument("node")
    sub.add_argument("name")
    sub.add_argument("value", help="the value as YAML: 1.5, true, Velocity, '[1.0, 0.5, 0.0]'")
    sub.add_argument("--persist", action="store_true",
                     help="when the node does not run, keep the value for its next start")
    sub.add_argument("--timeout", type=positive_float, default=5.0, metavar="SECONDS",
                     help="how long to wait for the node's answer (default 5)")

    sub = commands.action(param, "describe", "one parameter's declaration and value",
                          param_describe)
    sub.add_argument("node")
    sub.add_argument("name")

    sub = commands.action(param, "watch", "print each change of a node's parameters (or one) "
                                          "until Ctrl+C", param_watch)
    sub.add_argument("node")
    sub.add_argument("name", nargs="?")
    sub.add_argument("--count", type=positive_int, default=None, metavar="N",
                     help="stop after N changes")

    sub = commands.action(param, "dump", "the current values as a YAML parameter file (of every "
                                         "node, or those named)", param_dump)
    sub.add_argument("nodes", nargs="*", metavar="NODE")

    sub = commands.action(param, "load", "write every value of a YAML parameter file through "
                                         "the nodes (nothing when any value is wrong)", param_load)
    sub.add_argument("file")
    sub.add_argument("--persist", action="store_true",
                     help="keep values for nodes that do not run now for their next start")
    sub.add_argument("--timeout", type=positive_float, default=5.0, metavar="SECONDS",
                     help="how long to wait for each node's answer (default 5)")
