"""Run by test_type_description.py in a process of its own per schema set (generated packages of
different sets may share names): checks every message and enum of the set against the generated
Python classes and prints one line per type that disagrees, nothing when all agree.

    type_description_check.py TYPEDESC_PY DESCRIBED_JSON PACKAGE...

with the generated output roots on PYTHONPATH; DESCRIBED_JSON is describe --json of the packages
and of every type they use. For each type: the carried bytes decode to the
describe --json tree for it; a POD message's size and offsets are the generated class's struct
layout; a value made by the generated class, encoded, decodes through typedesc to the same plain
value, and typedesc encodes that plain value to the same bytes; the zero messages agree too.
"""
from __future__ import annotations

import importlib
import importlib.util
import json
import sys

import msgpack


def load_typedesc(path: str):
    spec = importlib.util.spec_from_file_location("typedesc_under_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Filler:
    """A value in every field: one counter step per leaf, two elements per Vec, Options present."""

    def __init__(self, entries: dict) -> None:
        self.entries = entries
        self.k = 0

    def take(self) -> int:
        self.k += 1
        return self.k

    def value(self, t: dict):
        kind = t["kind"]
        if kind == "primitive":
            name, k = t["name"], self.take()
            if name == "bool":
                return k % 2 == 1
            if name[0] == "f":
                return k + 0.25
            bits = int(name[1:])
            return k % (1 << bits) if name[0] == "u" else -(k % (1 << (bits - 1)))
        if kind == "string":
            return f"s{self.take()}"[:t.get("capacity", 64)]
        if kind == "bytes":
            k = self.take()
            return bytes([k % 256, (k + 1) % 256])
        if kind == "array":
            return [self.value(t["element"]) for _ in range(t["length"])]
        if kind == "vec":
            return [self.value(t["element"]) for _ in range(2)]
        if kind == "optional":
            return self.value(t["element"])
        if kind == "enum":
            values = self.entries[t["name"]]["values"]
            return values[self.take() % len(values)]["name"] if values else 0
        return self.message(t["name"])

    def message(self, name: str) -> dict:
        return {f["name"]: self.value(f["type"]) for f in self.entries[name]["fields"]}


def problems(typedesc, described: dict, packages: list[str]) -> list[str]:
    entries = {e["name"]: e for e in described["types"] if e["kind"] in ("message", "enum")}
    modules = {p: importlib.import_module(p) for p in packages}
    found = []
    for name, entry in entries.items():
        package, short = name.rsplit(".", 1)
        if package not in modules:
            continue
        cls = getattr(modules[package], short)
        carried = cls.__horus__["description"]
        expected = typedesc.carried(described, name)
        for e in expected["types"]:
            e.pop("dds_type", None)
        if msgpack.unpackb(carried, raw=False) != expected:
            found.append(f"{name}: the carried description is not describe --json's")
        if entry["kind"] == "enum":
            made = typedesc.message_class(carried)
            if [(m.name, m.value) for m in made] != [(m.name, m.value) for m in cls]:
                found.append(f"{name}: typedesc's enum has other values")
            continue
        info = cls.__horus__
        if entry["tier"] == "pod":
            if (entry["size"], entry["alignment"]) != (info.size, info.alignment) or \
                    [f["offset"] for f in entry["fields"]] != list(info.offsets) or info.dtype.itemsize != info.size:
                found.append(f"{name}: layout {entry['size']}/{entry['alignment']} "
                             f"{[f['offset'] for f in entry['fields']]} is not the class's {info.size}/"
                             f"{info.alignment} {list(info.offsets)}")
        made = typedesc.message_class(carried)
        for label, message in (("zero", cls()), ("filled", typedesc.from_plain(cls, Filler(entries).message(name)))):
            data = message.to_bytes()
            plain = typedesc.to_plain(message)
            decoded = typedesc.decode(made, data)
            if decoded != plain:
                found.append(f"{name} ({label}): typedesc decodes {decoded!r}, the class holds {plain!r}")
            if typedesc.encode(made, plain) != data:
                found.append(f"{name} ({label}): typedesc encodes other bytes than the generated class")
        if made().to_bytes() != cls().to_bytes():
            found.append(f"{name}: typedesc's zero message is not the generated class's")
        if made().log_summary() != cls().log_summary():
            found.append(f"{name}: typedesc's log summary {made().log_summary()!r} is not {cls().log_summary()!r}")
    return found


def main() -> int:
    typedesc = load_typedesc(sys.argv[1])
    with open(sys.argv[2], encoding="utf-8") as handle:
        described = json.load(handle)
    for line in problems(typedesc, described, sys.argv[3:]):
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
