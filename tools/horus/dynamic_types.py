"""Message classes for types known only from the schema text a topic's segment stores.

A segment records its type's name, fingerprint and readable schema text (the type's definition
followed by every type it uses, docs/schema-language.md "Identity"). This module turns that text
back into schema files, compiles them with horus-gen into Python (the very code a generated
package holds, so bytes are exactly C++'s: POD layout and MessagePack), caches the result and
imports it privately, without disturbing packages of the same name that the
process already uses (horus.msg included).

    cls = load_type("demo.Pose", schema_text, 0x72b8e8dd8bd50428)
    message = cls.from_bytes(payload)          # generated class: from_bytes / to_bytes
    plain = to_plain(message)                  # dicts, lists, numbers, strings, enum names
    payload = from_plain(cls, {"x": 1.0}).to_bytes()

The types the runtime spells itself (docs/recording.md, "Types the runtime defines") decode the
same way, compiled under the package `horus_runtime` (horus-gen keeps `horus` for the runtime): a
plain value (`value [f32; 3]`) as a message `PlainValue` of one field `value`, a service frame
(`horus.ServiceRequest<demo.AddRequest>`) as a message `ServiceRequest` (or `ServiceResponse`) of
its fields, and `horus.ServiceRegistration` as `ServiceRegistration`; their
fingerprint is the FNV-1a hash of the stored text, as the runtime computes it, where every other
type's is the SHA-256 of its canonical text that horus-gen computes.

Errors are `SchemaError` (the text cannot be compiled or gives another fingerprint) and
`ValueError` (a value that does not fit the type), each one line naming the problem.

The cache is $XDG_CACHE_HOME/horus/types/<hash of name and schema text> (default
~/.cache/horus/types), made by the user alone (mode 0700); horus-gen is $HORUS_GEN_PROGRAM, else `horus-gen` on PATH.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import os
import re
import subprocess
import sys
import tempfile
import threading

__all__ = ["SchemaError", "load_type", "to_plain", "from_plain", "parse_schema", "cache_root",
           "run_generator", "write_schema_files", "type_declarations", "runtime_fingerprint"]

# Bump when the way classes are produced changes, so stale cache entries are not reused.
_CACHE_FORMAT = "v1"
_SUPPORT = "_horus_gen_support_v1"

_HEADER = re.compile(r"^(message|enum) ([A-Za-z_][A-Za-z0-9_.]*)(: [a-z0-9]+)? \{$")
# The identities the runtime spells itself (runtime/include/horus/plain_value.hpp,
# detail/service_frame.hpp): the runtime's own package `horus` (not a generated one such as
# horus.msg), a service frame's name with its payload's in angle brackets, a plain value.
_RUNTIME_NAME = re.compile(r"^horus\.([A-Za-z_][A-Za-z0-9_]*)(<[A-Za-z0-9_.]+>)?$")
_PLAIN_VALUE = "value "
# The package they are compiled under: horus-gen keeps the package `horus` for the runtime itself.
_RUNTIME_PACKAGE = "horus_runtime"
_loaded: dict[tuple[str, int], type] = {}
_importing = threading.Lock()


class SchemaError(Exception):
    """A stored schema text that cannot become a class (one line, names the type)."""


def cache_root() -> str:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "horus", "types")


def parse_schema(text: str) -> list[tuple[str, str, str]]:
    """The declarations of a readable schema text: (kind, qualified name, declaration source as
    horus-gen reads it inside that package). Raises SchemaError on text of another shape."""
    declarations = []
    lines = text.splitlines()
    index = 0
    while index < len(lines):
        line = lines[index]
        if not line.strip():
            index += 1
            continue
        header = _HEADER.match(line)
        if header is None or "." not in header.group(2):
            raise SchemaError(f"unexpected schema line {line!r}")
        kind, qualified, underlying = header.group(1), header.group(2), header.group(3) or ""
        short = qualified.rsplit(".", 1)[1]
        body = []
        index += 1
        while index < len(lines) and lines[index] != "}":
            body.append(lines[index])
            index += 1
        if index == len(lines):
            raise SchemaError(f"schema of {qualified} ends before its closing brace")
        index += 1
        opener = f"enum {short}{underlying} {{" if kind == "enum" else f"{short} {{"
        declarations.append((kind, qualified, "\n".join([opener, *body, "}"]) + "\n"))
    if not declarations:
        raise SchemaError("empty schema text")
    return declarations


def runtime_fingerprint(text: str) -> int:
    """The FNV-1a hash (64 bits) the runtime gives the identities it spells itself."""
    value = 0xCBF29CE484222325
    for byte in text.encode():
        value = ((value ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return value


def _runtime_spelled(type_name: str, schema_text: str) -> bool:
    return schema_text.startswith(_PLAIN_VALUE) or _RUNTIME_NAME.match(type_name) is not None


def type_declarations(type_name: str, schema_text: str) -> tuple[str, list[tuple[str, str, str]]]:
    """(the name horus-gen compiles the type under, its declarations as parse_schema gives them)
    for a type as a segment stores it, the runtime's own identities included (a frame's name is
    not one horus-gen accepts: the frame is compiled as horus_runtime.ServiceRequest, the payload
    under its own name). Raises SchemaError."""
    if schema_text.startswith(_PLAIN_VALUE):
        value_type = schema_text[len(_PLAIN_VALUE):].strip()
        if value_type != type_name:
            raise SchemaError(f"the stored schema describes {value_type}, not {type_name}")
        compiled = f"{_RUNTIME_PACKAGE}.PlainValue"
        return compiled, [("message", compiled, f"PlainValue {{\n  value: {value_type},\n}}\n")]
    runtime = _RUNTIME_NAME.match(type_name)
    compiled = f"{_RUNTIME_PACKAGE}.{runtime.group(1)}" if runtime else type_name
    if runtime:
        schema_text = schema_text.replace(f"message {type_name} {{", f"message {compiled} {{", 1)
    declarations = parse_schema(schema_text)
    if declarations[0][1] != compiled:
        raise SchemaError(f"the stored schema describes {declarations[0][1]}, not {type_name}")
    return compiled, declarations


def _schema_files(declarations) -> dict[str, str]:
    """One schema file per package: relative path -> text. References stay qualified, which
    horus-gen resolves through the -I folder holding these files."""
    packages: dict[str, list[str]] = {}
    for _kind, qualified, source in declarations:
        packages.setdefault(qualified.rsplit(".", 1)[0], []).append(source)
    return {os.path.join(*package.split("."), "types.hmsg"): f"package {package};\n\n" + "\n".join(sources)
            for package, sources in packages.items()}


def run_generator(arguments: list[str], failure: str) -> str:
    """horus-gen's output for `arguments`; SchemaError "<failure>: <its first error line>" when
    it fails, or naming the program when it cannot run."""
    command = [os.environ.get("HORUS_GEN_PROGRAM") or "horus-gen", *arguments]
    try:
        result = subprocess.run(command, capture_output=True, text=True)
    except OSError as error:
        raise SchemaError(f"cannot run {command[0]}: {error.strerror}") from None
    if result.returncode != 0:
        first = (result.stderr.strip().splitlines() or ["(no message)"])[0]
        raise SchemaError(f"{failure}: {first}")
    return result.stdout


def write_schema_files(declarations, folder: str) -> list[str]:
    """Writes the schema files of `declarations` (parse_schema) under `folder`, for horus-gen
    with `-I folder`; their paths."""
    files = []
    for relative, text in _schema_files(declarations).items():
        path = os.path.join(folder, relative)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(text)
        files.append(path)
    return files


def _compile(type_name: str, declarations, destination: str) -> None:
    """Writes the Python of `declarations` to destination/python, atomically (a concurrent run
    compiling the same type leaves one complete copy)."""
    parent = os.path.dirname(destination)
    with tempfile.TemporaryDirectory(dir=parent, prefix=".build-") as work:
        sources = os.path.join(work, "schemas")
        files = write_schema_files(declarations, sources)
        output = os.path.join(work, "out")
        run_generator(["generate", "--lang", "python", "--out", output, "-I", sources, *files],
                      f"the stored schema of {type_name} does not compile")
        try:
            os.rename(output, destination)
        except OSError:
            if not os.path.isdir(os.path.join(destination, "python")):
                raise
            # Another process cached the same type meanwhile: its copy is as good.


class _CacheFinder:
    """Finds the top-level packages of one cache entry there, ahead of every other path entry."""

    def __init__(self, root: str, top_names: set[str]) -> None:
        self.root, self.top_names = root, top_names

    def find_spec(self, name, path=None, target=None):
        if "." in name or name not in self.top_names:
            return None
        return importlib.machinery.PathFinder.find_spec(name, [self.root])


def _import_private(root: str, module_name: str, top_names: set[str]):
    """Imports `module_name` from `root` with the modules of the same top-level names that this
    process already has set aside meanwhile, then puts them back: the classes imported keep
    their own modules, the process keeps its own."""
    top_names = top_names | {_SUPPORT}

    def ours(name: str) -> bool:
        return name.split(".", 1)[0] in top_names
    saved = {name: module for name, module in sys.modules.items() if ours(name)}
    for name in saved:
        del sys.modules[name]
    finder = _CacheFinder(root, top_names)
    sys.meta_path.insert(0, finder)
    try:
        return importlib.import_module(module_name)
    finally:
        sys.meta_path.remove(finder)
        for name in [name for name in sys.modules if ours(name)]:
            del sys.modules[name]
        sys.modules.update(saved)


def load_type(type_name: str, schema_text: str, fingerprint: int | None) -> type:
    """The generated class of `type_name` compiled from `schema_text` (as a segment stores it),
    checked to have `fingerprint` (None: the caller checks the identity another way). Cached on
    disk and in the process. Raises SchemaError."""
    key = (type_name, schema_text)
    with _importing:
        cls = _loaded.get(key)
        if cls is None:
            cls = _loaded[key] = _compiled_class(type_name, schema_text)
    if fingerprint is None:
        return cls
    actual = (runtime_fingerprint(schema_text) if _runtime_spelled(type_name, schema_text)
              else cls.__horus__.fingerprint)
    if actual != fingerprint:
        raise SchemaError(f"the stored schema of {type_name} gives fingerprint "
                          f"{actual:016x}, the segment says {fingerprint:016x}")
    return cls


def _trusted_cache_root() -> str:
    """The cache folder, made if missing; SchemaError unless only this user can write it (its
    code is imported: another user's files there would run as this one)."""
    root = cache_root()
    try:
        os.makedirs(root, mode=0o700, exist_ok=True)
        status = os.stat(root)
    except OSError as error:
        raise SchemaError(f"cannot use the type cache {root}: {error.strerror}") from None
    if status.st_uid != os.geteuid() or status.st_mode & 0o022:
        raise SchemaError(f"the type cache {root} is not this user's alone (owner uid "
                          f"{status.st_uid}, mode {status.st_mode & 0o777:o}); remove it")
    return root


def _compiled_class(type_name: str, schema_text: str) -> type:
    compiled, declarations = type_declarations(type_name, schema_text)
    digest = hashlib.sha256(f"{type_name}\n{schema_text}".encode()).hexdigest()[:24]
    root = _trusted_cache_root()
    entry = os.path.join(root, f"{digest}-{_CACHE_FORMAT}")
    if not os.path.isdir(os.path.join(entry, "python")):
        _compile(type_name, declarations, entry)
    package, short = compiled.rsplit(".", 1)
    top_names = {qualified.split(".", 1)[0] for _kind, qualified, _source in declarations}
    try:
        module = _import_private(os.path.join(entry, "python"), package, top_names)
        return getattr(module, short)
    except (ImportError, AttributeError, SyntaxError) as error:
        raise SchemaError(f"cannot load the compiled {type_name} from {entry} ({error}); "
                          "remove that folder to rebuild it") from None


# -- plain values ---------------------------------------------------------------------------------

def to_plain(message):
    """The message as plain values: a dict per message, lists for arrays and Vec, None for an
    empty Option, enum member names, bytes for bytes fields. An f32 is the shortest decimal that
    reads back as the same f32 (0.1, not 0.10000000149011612)."""
    info = type(message).__horus__
    return {name: _plain(codec, getattr(message, name))
            for name, codec in zip(info.fields, info.codecs)}


def _plain(codec, value):
    kind = type(codec).__name__  # the support module is the compiled type's private copy
    if value is None:
        return None
    if kind == "Nested":
        return to_plain(value)
    if kind == "Enum":
        return value.name if hasattr(value, "name") else int(value)
    if kind == "Float" and codec.single:
        return _short_f32(value)
    if kind == "NumArray":
        values = value.tolist()
        return _map_nested(values, _short_f32) if codec.kind == "f" and codec.element.single else values
    if kind in ("Vec", "ListArray"):
        return [_plain(codec.element, item) for item in value]
    if kind == "Option":
        return _plain(codec.element, value)
    return value


def _short_f32(value: float) -> float:
    import numpy
    return float(repr(numpy.float32(value)).removeprefix("np.float32(").removesuffix(")"))


def _map_nested(values, convert):
    return [_map_nested(v, convert) if isinstance(v, list) else convert(v) for v in values]


def from_plain(cls, value, path: str = ""):
    """An instance of the generated class `cls` from plain values (a dict of some or all of its
    fields; those left out keep their defaults). Enum fields take a member name or its integer.
    ValueError names the field and the problem: an unknown field, a value of the wrong kind."""
    message = cls()
    _fill(message, value, path or cls.__horus__.name)
    # Encoding checks every value against its type (range, length, kind) and names the field.
    message.to_bytes()
    return message


def _fill(message, value, path: str) -> None:
    info = type(message).__horus__
    if not isinstance(value, dict):
        raise ValueError(f"{path}: expected a mapping of the fields of {info.name}, got {_kind(value)}")
    for name, item in value.items():
        if name not in info.fields:
            raise ValueError(f"{path}: no field '{name}' (fields: {', '.join(info.fields)})")
        codec = info.codecs[info.fields.index(name)]
        setattr(message, name, _convert(codec, item, f"{path}.{name}", getattr(message, name)))


def _convert(codec, value, path: str, current):
    kind = type(codec).__name__  # the support module is the compiled type's private copy
    if kind == "Nested":
        _fill(current, value, path)
        return current
    if kind == "Enum":
        if isinstance(value, str):
            member = codec.cls.__members__.get(value)
            if member is None:
                raise ValueError(f"{path}: '{value}' is not a value of {codec.cls.__horus__.name} "
                                 f"({', '.join(codec.cls.__members__)})")
            return member
        return value
    if kind == "Option":
        return None if value is None else _convert(codec.element, value, path, codec.element.default())
    if kind in ("Vec", "ListArray"):
        if not isinstance(value, list):
            raise ValueError(f"{path}: expected a list, got {_kind(value)}")
        return [_convert(codec.element, item, f"{path}[{index}]", codec.element.default())
                for index, item in enumerate(value)]
    if kind == "NumArray":
        try:
            return codec.coerce(value)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{path}: {error}") from None
    if kind == "Bytes" and isinstance(value, list):
        try:
            return bytes(value)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{path}: {error}") from None
    return value


def _kind(value) -> str:
    return type(value).__name__
