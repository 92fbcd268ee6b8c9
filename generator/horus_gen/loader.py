"""Loading schema files: reading and parsing them, following imports through the import roots
(-I), and loading the folder of a package that a qualified name refers to.

The loader only finds and parses files; the resolver declares what they hold. `take_loaded()`
hands over the files loaded since the last call in declaration order: a file after everything
it imports.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

from .diagnostics import Reporter, Source, Span
from .lexer import MAX_NAME_LENGTH
from .lang import cpp, keyword_clash
from .parser import FILE_KINDS, parse
from .syntax import FileSyntax


@dataclass
class Options:
    include_dirs: list[str] = field(default_factory=list)
    package: str | None = None


@dataclass
class Unit:
    """One schema file: its syntax and the package its items live in."""
    path: str
    syntax: FileSyntax
    package: str


class Loader:
    def __init__(self, reporter: Reporter, options: Options, inputs: list[str]):
        self.reporter = reporter
        self.options = options
        self.inputs = inputs  # every file read, for the depfile
        self.units: dict[str, Unit] = {}  # real path -> unit
        self.scanned_folders: set[str] = set()
        self.loaded: list[Unit] = []

    def take_loaded(self) -> list[Unit]:
        loaded, self.loaded = self.loaded, []
        return loaded

    def load(self, path: str, import_span: Span | None = None, root: bool = False) -> Unit | None:
        real = os.path.realpath(path)
        if real in self.units:
            return self.units[real]
        kind = FILE_KINDS.get(os.path.splitext(path)[1])
        if kind is None or (import_span and kind == "node"):
            if import_span:
                self.reporter.error(import_span, f"cannot import '{path}': not a .hmsg, .hsrv or .haction file",
                                    "a node file (.hnode) declares no type to import; list it among the files instead"
                                    if path.endswith(".hnode") else None)
            return None
        try:
            with open(path, encoding="utf-8") as handle:
                text = handle.read()
        except (OSError, UnicodeDecodeError) as error:
            if import_span:
                self.reporter.error(import_span, f"cannot read '{path}': {error}")
            else:
                self.reporter.error(Span(Source(path, ""), 1, 1), f"cannot read file: {error}")
            return None
        source = Source(path, text)
        self.inputs.append(path)
        syntax = parse(source, self.reporter, kind)
        package = self.package_of(syntax, path, root)
        unit = Unit(path, syntax, package)
        self.units[real] = unit
        for target, span in syntax.imports:
            found = self.find_import(target, os.path.dirname(path))
            if found is None:
                searched = [os.path.dirname(path) or "."] + self.options.include_dirs
                self.reporter.error(span, f"cannot find imported file '{target}'",
                                    "searched " + ", ".join(f"'{d}'" for d in searched)
                                    + "; add the folder that holds it with -I (INCLUDE_DIRS in CMake)")
            else:
                self.load(found, span)
        self.loaded.append(unit)
        return unit

    def package_of(self, syntax: FileSyntax, path: str, root: bool) -> str:
        """The file's own `package`, else --package for the files being compiled, else the
        name of the file's folder (so a library reached through -I keeps its own package)."""
        if syntax.package is not None:
            name, span = syntax.package
        else:
            given = self.options.package if root else None
            name = given or os.path.basename(os.path.dirname(os.path.abspath(path)))
            span = Span(syntax.source, 1, 1)
        # A folder's or --package's name is checked as a declared one is by the lexer: it becomes
        # file names and identifiers too.
        for part in name.split("."):
            clash = keyword_clash(part)
            why = (f": '{part}' is {clash}" if clash else
                   f": '{part}' is not ASCII" if not part.isascii() else
                   f": '{part[:20]}...' is longer than {MAX_NAME_LENGTH} characters" if len(part) > MAX_NAME_LENGTH else "")
            if not part.isidentifier() or why:
                self.reporter.error(span, f"package name '{name}' cannot be a C++ namespace and a Python package" + why,
                                    "use lowercase identifiers separated by '.', such as 'my_robot.msg'")
                break
        else:
            if cpp.reserved_package(name):
                self.reporter.error(span, f"package name '{name}' is a C++ namespace of the horus runtime, "
                                    "msgpack-cxx or the standard library",
                                    "use a package of your own, such as 'my_robot.msg'")
        return name

    def find_import(self, target: str, base: str) -> str | None:
        for folder in [base] + self.options.include_dirs:
            candidate = os.path.join(folder, target)
            if os.path.isfile(candidate):
                return candidate
        return None

    def scan_package_folders(self, package: str, near: str | None) -> None:
        """Loads the schema files of `package`'s folder in every include dir, so that a qualified
        name resolves without an explicit import. Their errors are reported like any other: a
        package the schema uses is part of what it compiles against."""
        relative = package.replace(".", os.sep)
        folders = [os.path.join(d, relative) for d in self.options.include_dirs] + ([near] if near else [])
        for folder in folders:
            real = os.path.realpath(folder)
            if real in self.scanned_folders or not os.path.isdir(folder):
                continue
            self.scanned_folders.add(real)
            for name in sorted(os.listdir(folder)):
                # Types only: a node declares nothing another schema can name.
                if FILE_KINDS.get(os.path.splitext(name)[1]) in ("message", "service", "action"):
                    self.load(os.path.join(folder, name))
