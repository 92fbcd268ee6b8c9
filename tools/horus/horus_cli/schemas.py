"""Message types known from schema files or from what a topic's segment stores, for the commands
that decode or build messages (topic echo and pub, service call, msg, record): the schema folders
described as `horus-gen describe` describes them, classes made by horus.typedesc (from the type
description a segment carries, else from its stored schema text, compiled in process), and messages
as plain values read from YAML or JSON and shown as YAML or JSON.
"""
from __future__ import annotations

import json
import os

from horus_cli.common import EXIT_USAGE, CommandFailed, close_names, suggestion

# The installed schemas `horus msg` describes (set by the launcher, as is HORUS_GEN_PROGRAM, where
# horus.typedesc finds the schema compiler).
SCHEMA_DIR = os.environ.get("HORUS_SCHEMA_DIR", "")


def described_types(args) -> list[dict]:
    """Every type of the schema folders (-I, else the installed schemas), as the type description
    lays it out (docs/type-description.md): fingerprint, tier, size, alignment, fields with
    offsets. The installed schemas also resolve what the -I folders' types use (horus.msg.Pose2D)."""
    import pathlib

    from horus import typedesc
    folders = args.include or ([SCHEMA_DIR] if SCHEMA_DIR else [])
    files = sorted(str(path) for folder in folders
                   for pattern in ("*.hmsg", "*.hsrv", "*.haction")
                   for path in pathlib.Path(folder).rglob(pattern))
    if not files:
        raise CommandFailed("no schema files (.hmsg, .hsrv, .haction) in "
                            f"{', '.join(folders) or '(none)'}")
    resolving = folders + ([SCHEMA_DIR] if SCHEMA_DIR and SCHEMA_DIR not in folders else [])
    try:
        return typedesc.describe_files(files, resolving)["types"]
    except typedesc.SchemaError as error:
        raise CommandFailed(str(error)) from None


def described_type(args) -> dict:
    types = described_types(args)
    for described in types:
        if described["name"] == args.type or described["name"].rsplit(".", 1)[-1] == args.type:
            return described
    # Matched on the bare names: qualified ones all share their package's prefix.
    package, _, bare = args.type.rpartition(".")
    close = close_names(bare, [t["name"].rsplit(".", 1)[-1] for t in types])
    if package:
        close = [t["name"] for t in types if t["name"].rsplit(".", 1)[-1] in close]
    where = "the given schemas" if args.include else "the installed schemas"
    hint = "" if args.include else " (your own types: -I DIR, the folder of their .hmsg files)"
    raise CommandFailed(f"no message type '{args.type}' in {where}{suggestion(close)}{hint}")


def message_class(type_name: str, schema: str, fingerprint: int | None, description: bytes = b""):
    """The class of a type from what a segment or recording stores: its type description when it
    carries one, else its schema text; checked to be `type_name` of `fingerprint` (None: the caller
    checks the identity another way). Errors as one line."""
    from horus import typedesc
    try:
        if not description:
            return typedesc.load_type(type_name, schema, fingerprint)
        cls = typedesc.message_class(description)
    except typedesc.SchemaError as error:
        raise CommandFailed(str(error)) from None
    info = cls.__horus__
    if info.name != type_name or (fingerprint is not None and info.fingerprint != fingerprint):
        stated = "" if fingerprint is None else f" (fingerprint {fingerprint:016x})"
        raise CommandFailed(f"the type description stored with {type_name}{stated} describes "
                            f"{info.name} (fingerprint {info.fingerprint:016x})")
    return cls


def used_class(cls, type_name: str):
    """The class of `type_name`, a type `cls` uses (a service frame's payload), from the type
    description `cls` carries."""
    from horus import typedesc
    try:
        return typedesc.message_class(cls.__horus__.description, type_name)
    except typedesc.SchemaError as error:
        raise CommandFailed(str(error)) from None


def parse_value(text: str, what: str):
    """A YAML (or JSON, which YAML reads too) mapping given on the command line."""
    try:
        import yaml
    except ImportError:  # python3-yaml missing: JSON still works
        yaml = None
    try:
        value = yaml.safe_load(text) if yaml is not None else json.loads(text)
    except Exception as error:  # noqa: BLE001 (yaml and json raise their own error types)
        reason = " ".join(str(error).split()) or type(error).__name__
        raise CommandFailed(f"cannot parse the {what} {text!r}: {reason}", EXIT_USAGE) from None
    return {} if value is None else value


# The type of the Python runtime's dict topics: any plain value, as MessagePack in `data`.
# echo shows (and pub takes) that value rather than the bytes.
PLAIN_VALUES = "horus.msg.GenericMessage"


def build_message(cls, value):
    from horus import typedesc
    try:
        if cls.__horus__.name == PLAIN_VALUES:
            import msgpack
            return typedesc.from_plain(cls, {"data": msgpack.packb(value, use_bin_type=True)})
        return typedesc.from_plain(cls, value)
    except (ValueError, TypeError) as error:
        raise CommandFailed(str(error)) from None


def plain(message):
    """What echo and call show of a message: its fields, or a plain-values message's value."""
    from horus import typedesc
    plain = typedesc.to_plain(message)
    if type(message).__horus__.name == PLAIN_VALUES and plain["metadata"] is None:
        import msgpack
        try:
            return msgpack.unpackb(plain["data"], raw=False, strict_map_key=False)
        except (ValueError, msgpack.UnpackException):
            pass  # not one MessagePack value: shown as its fields
    return plain


def plain_field(plain, path: str | None, type_name: str, checking: bool = False):
    """The field `path` (a.b, list elements by index) of a plain message. `checking` a default
    message, whose lists are empty and options None, what lies below them is not checked."""
    if not path:
        return plain
    value = plain
    for part in path.split("."):
        if checking and (value is None or isinstance(value, list)):
            return None
        if isinstance(value, dict) and part in value:
            value = value[part]
        elif isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            known = ", ".join(value) if isinstance(value, dict) else f"indexes 0..{len(value) - 1}" \
                if isinstance(value, list) else "nothing (not a message)"
            raise CommandFailed(f"{type_name} has no field '{path}' ('{part}' is not one of: {known})")
    return value


def jsonable(value):
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, dict):
        return {key: jsonable(item) for key, item in value.items()}
    if isinstance(value, list):
        return [jsonable(item) for item in value]
    return value


def show_message(value, as_json: bool) -> None:
    value = jsonable(value)
    if as_json:
        print(json.dumps(value), flush=True)
    elif not isinstance(value, (dict, list)):
        print(value, flush=True)
    else:
        print(yaml_text(value) + "---", flush=True)


def yaml_text(value) -> str:
    """Block YAML with lists on one line each (as ros2 topic echo prints them, roughly)."""
    try:
        import yaml
    except ImportError:  # python3-yaml missing: JSON is YAML too
        return json.dumps(value, indent=2) + "\n"

    class Dumper(yaml.SafeDumper):
        pass
    Dumper.add_representer(list, lambda dumper, items: dumper.represent_sequence(
        "tag:yaml.org,2002:seq", items, flow_style=True))
    return yaml.dump(value, Dumper=Dumper, sort_keys=False, default_flow_style=False, width=100)

