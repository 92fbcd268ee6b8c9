"""horus-gen in process: schema files or stored schema text to the type description
(docs/type-description.md), without running the command.

    tree = horus_gen.describe_files(["msgs/pose.hmsg"], include_dirs=["schemas"])
    carried = horus_gen.describe_schema_text("demo.Pose", stored_text)   # root demo.Pose

Errors are SchemaCompileError, whose message is the report `horus-gen check` would print and whose
`diagnostics` hold each error on its own.
"""
from __future__ import annotations

import os
import re
import tempfile

from . import description
from .diagnostics import Reporter
from .loader import Options
from .model import Model
from .resolve import Resolver

__all__ = ["SchemaCompileError", "describe_files", "describe_schema_text"]


class SchemaCompileError(Exception):
    """Schema files or text that do not compile; str() is the full report (path:line:col, source
    line, caret, hints), `diagnostics` each error's text alone."""

    def __init__(self, report: str, diagnostics: list[str]) -> None:
        super().__init__(report)
        self.diagnostics = diagnostics


def _compile(paths: list[str], include_dirs: list[str]) -> Model:
    for path in paths:
        if not os.path.isfile(path):
            raise SchemaCompileError(f"{path}: no such file", [f"{path}: no such file"])
    reporter = Reporter()
    model = Resolver(reporter, Options(list(include_dirs))).run(list(paths))
    if reporter.has_errors:
        raise SchemaCompileError(reporter.render(), [d.render() for d in reporter.diagnostics])
    return model


def describe_files(paths: list[str], include_dirs: list[str] = ()) -> dict:
    """The description of every message, enum and service the files declare (describe --json
    without the nodes and the DDS names)."""
    return description.model_description(_compile(list(paths), list(include_dirs)))


# A declaration's first line in stored schema text (identity.message_texts, enum_text).
_HEADER = re.compile(r"^(message|enum) ([A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)+)(: [a-z0-9]+)? \{$")


def schema_files(schema_text: str) -> dict[str, str]:
    """Stored schema text (a type's definition, then every type it uses) as schema files, one a
    package: relative path -> source. References stay qualified; they resolve through the folder
    holding the files given as an include folder."""
    packages: dict[str, list[str]] = {}
    lines = schema_text.splitlines()
    index = 0
    while index < len(lines):
        line = lines[index]
        if not line.strip():
            index += 1
            continue
        header = _HEADER.match(line)
        if header is None:
            raise SchemaCompileError(f"schema text line {index + 1}: expected 'message pkg.Name {{' or "
                                     f"'enum pkg.Name: u8 {{', got {line!r}", [])
        kind, qualified, underlying = header.group(1), header.group(2), header.group(3) or ""
        package, short = qualified.rsplit(".", 1)
        body = []
        index += 1
        while index < len(lines) and lines[index] != "}":
            body.append(lines[index])
            index += 1
        if index == len(lines):
            raise SchemaCompileError(f"schema text of {qualified} ends before its closing brace", [])
        index += 1
        opener = f"enum {short}{underlying} {{" if kind == "enum" else f"{short} {{"
        packages.setdefault(package, []).append("\n".join([opener, *body, "}"]) + "\n")
    if not packages:
        raise SchemaCompileError("empty schema text", [])
    return {os.path.join(*package.split("."), "types.hmsg"): f"package {package};\n\n" + "\n".join(sources)
            for package, sources in packages.items()}


def describe_schema_text(type_name: str, schema_text: str) -> dict:
    """The carried description of `type_name` (root and every type it uses) from the schema text a
    segment or recording stores for it."""
    with tempfile.TemporaryDirectory(prefix="horus-gen-describe-") as folder:
        paths = []
        for relative, source in schema_files(schema_text).items():
            path = os.path.join(folder, relative)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as handle:
                handle.write(source)
            paths.append(path)
        model = _compile(paths, [folder])
    if type_name not in model.types:
        declared = ", ".join(sorted(model.types))
        raise SchemaCompileError(f"the schema text declares no type {type_name} (it declares {declared})", [])
    return description.type_description(model, type_name)
