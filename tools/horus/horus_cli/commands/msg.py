"""`horus msg`: the message types of the installed (or given) schemas: list, show, hash."""
from __future__ import annotations

from horus_cli.common import EXIT_OK, emit, table
from horus_cli.schemas import described_type, described_types


def msg_list(args) -> int:
    types = described_types(args)
    emit(types, args.json, lambda rows: [print(t["name"]) for t in rows])
    return EXIT_OK


def _layout_rows(described: dict) -> list[list]:
    """The field table of `msg show`: each field, and for a POD type each hole of padding
    between two fields and after the last (what the fields leave of `size`)."""
    rows, end = [], 0
    for field in described["fields"]:
        offset, size = field.get("offset"), field.get("size")
        if offset is not None and offset > end:
            rows.append(["(padding)", "-", end, offset - end])
        rows.append([field["name"], field["spelling"], "-" if offset is None else offset,
                     "-" if size is None else size])
        if offset is not None and size is not None:
            end = offset + size
    if described.get("size") and all(f.get("offset") is not None for f in described["fields"]) \
            and described["size"] > end:
        rows.append(["(padding)", "-", end, described["size"] - end])
    return rows


def msg_show(args) -> int:
    described = described_type(args)

    def render(t):
        print(f"type: {t['name']} ({t['kind']})")
        print(f"fingerprint: {t['fingerprint']}")
        if "tier" in t:
            size, alignment = t.get("size"), t.get("alignment")
            print(f"tier: {t['tier']}, size {'-' if size is None else size}, alignment "
                  f"{'-' if alignment is None else alignment}")
        if t.get("fields"):
            table(["FIELD", "TYPE", "OFFSET", "SIZE"], _layout_rows(t))
        if t["kind"] == "enum":
            print(f"underlying: {t['underlying']}")
            for value in t["values"]:
                print(f"  {value['name']} = {value['value']}")
        if t["kind"] == "service":
            print(f"request: {t['request']} (topic {t['request_topic']})")
            print(f"response: {t['response']} (topic {t['response_topic']})")
        if t.get("schema"):
            # What a topic's segment stores: the definition, then every type it uses.
            print("schema:")
            for line in t["schema"].splitlines():
                print(f"  {line}")
    emit(described, args.json, render)
    return EXIT_OK


def msg_hash(args) -> int:
    print(described_type(args)["fingerprint"])
    return EXIT_OK


def register(commands) -> None:
    message = commands.group("msg", "message types of the installed (or given) schemas: list, "
                                    "show, hash")
    for name, handler, what in (
            ("list", msg_list, "every message type of the schemas"),
            ("show", msg_show, "a type's fingerprint, tier, size, field layout and schema text"),
            ("hash", msg_hash, "a type's fingerprint")):
        sub = commands.action(message, name, what, handler, json_output=name != "hash")
        if name != "list":
            sub.add_argument("type", help="qualified (horus.msg.CmdVel) or bare (CmdVel) name")
        sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                         help="schema folder to read, like horus-gen's -I: the folder of your "
                              "own .hmsg and .hsrv files (repeatable; default: the installed "
                              "schemas)")
