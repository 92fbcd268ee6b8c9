"""The layout of the `horus` command's package (tools/horus/horus_cli/), read with `ast`: it uses
the horus package through public names only, and its command modules (commands/, one per noun)
stand alone: none imports another, and the shared modules import none of them."""
from __future__ import annotations

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "tools" / "horus" / "horus_cli"
COMMANDS = PACKAGE / "commands"
# The modules that assemble the commands (the parser, and `python3 -m horus_cli`).
ASSEMBLY = {PACKAGE / "main.py", PACKAGE / "__main__.py"}


def imported(path: pathlib.Path) -> list[tuple[str, str | None, int]]:
    """(module, name imported from it or None, line) of every import of a module, relative
    imports resolved against its package."""
    package = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1])
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, None, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                module = ".".join([*base, *([module] if module else [])])
            found += [(module, alias.name, node.lineno) for alias in node.names]
    return found


def modules() -> list[pathlib.Path]:
    found = sorted(PACKAGE.rglob("*.py"))
    assert len(found) > 10, f"expected the command's modules in {PACKAGE}, found {found}"
    return found


def command_of(module: str, name: str | None) -> str | None:
    """The command module an import names (horus_cli.commands.topic, or topic from
    horus_cli.commands), else None."""
    parts = module.split(".")
    if parts[:2] != ["horus_cli", "commands"]:
        return None
    if len(parts) > 2:
        return parts[2]
    return name


def test_no_module_of_the_command_imports_a_private_name_of_horus():
    private = []
    for path in modules():
        for module, name, line in imported(path):
            parts = module.split(".")
            if parts[0] != "horus":
                continue
            names = parts[1:] + ([name] if name else [])
            if any(part.startswith("_") and part != "__future__" for part in names):
                private.append(f"{path.relative_to(PACKAGE)}:{line}: {module}"
                               f"{'' if name is None else ' import ' + name}")
    assert private == [], "imports of private names of the horus package:\n" + "\n".join(private)


def test_no_command_module_imports_another_and_shared_modules_import_none():
    crossing = []
    for path in modules():
        if path in ASSEMBLY or path.name == "__init__.py":
            continue
        own = path.stem if path.parent == COMMANDS else None
        for module, name, line in imported(path):
            command = command_of(module, name)
            if command is not None and command != own:
                crossing.append(f"{path.relative_to(PACKAGE)}:{line}: imports the command "
                                f"module {command}")
    assert crossing == [], "\n".join(crossing)


def test_every_command_module_is_registered_by_main():
    registered = {command_of(module, name) for module, name, _ in imported(PACKAGE / "main.py")}
    present = {path.stem for path in COMMANDS.glob("*.py") if path.name != "__init__.py"}
    assert present <= registered, f"command modules main.py does not assemble: {present - registered}"


def test_messages_are_made_through_horus_typedesc_alone():
    # Types the command was never built with become classes through horus.typedesc (in process),
    # never through the bridge's dynamic_types (schema files compiled by a horus-gen subprocess).
    found = []
    for path in modules():
        for module, name, line in imported(path):
            if module == "dynamic_types":
                found.append(f"{path.relative_to(PACKAGE)}:{line}: imports {module}")
    assert found == [], "\n".join(found)
