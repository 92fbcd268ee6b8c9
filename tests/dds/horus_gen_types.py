"""A type's DDS type name and XTypes type information the way a DDS program gets them, from
horus-gen (`describe`, `generate --lang idl`) on its schema text and idlc on that IDL: what
test_dds_module.py checks the C++ bridge's own spelling of the IDL against."""
from __future__ import annotations

import json
import os
import re
import subprocess
import tempfile

from horus_gen.api import schema_files


class HorusGenTypes:
    """DDS type names and type information of HORUS types, from their schema texts."""

    def __init__(self) -> None:
        self._dds_names: dict[tuple[str, str], str] = {}
        self._type_info: dict[tuple[str, str], dict] = {}

    def dds_name(self, type_name: str, schema: str) -> str:
        key = (type_name, schema)
        if key not in self._dds_names:
            with tempfile.TemporaryDirectory(prefix="horus-gen-types-") as folder:
                files = _write_schema_files(schema, folder)
                described = _horus_gen("describe", "--json", "-I", folder, *files)
            self._dds_names[key] = next(entry["dds_type"]
                                        for entry in json.loads(described)["types"]
                                        if entry["name"] == type_name)
        return self._dds_names[key]

    def type_info(self, type_name: str, schema: str) -> dict:
        """type_info and type_map (horus._core.dds.Writer's and Reader's keywords) of the IDL
        `horus-gen --lang idl` writes for the type."""
        key = (type_name, schema)
        if key not in self._type_info:
            dds_type = self.dds_name(type_name, schema)
            with tempfile.TemporaryDirectory(prefix="horus-gen-types-") as folder:
                files = _write_schema_files(schema, folder)
                out = os.path.join(folder, "out")
                _horus_gen("generate", "--lang", "idl", "--out", out, "-I", folder, *files)
                self._type_info[key] = _idlc_type_info(os.path.join(out, "idl"), dds_type,
                                                       folder)
        return self._type_info[key]


def _write_schema_files(schema: str, folder: str) -> list[str]:
    """The stored schema text as schema files under `folder` (horus-gen's own split of it)."""
    paths = []
    for relative, source in schema_files(schema).items():
        path = os.path.join(folder, relative)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(source)
        paths.append(path)
    return paths


def _horus_gen(*arguments: str) -> str:
    """What the horus-gen command prints (HORUS_GEN_PROGRAM, as a DDS user would run it)."""
    return subprocess.run([os.environ["HORUS_GEN_PROGRAM"], *arguments], capture_output=True,
                          text=True, check=True).stdout


def _idlc_type_info(idl_root: str, dds_type: str, output: str) -> dict:
    """type_info and type_map of `dds_type` (horus::msg::dds_::CmdVel_), from the C idlc makes
    (in `output`) of its IDL file under `idl_root` (horus/msg/CmdVel.idl)."""
    *modules, name = [part for part in dds_type.split("::") if part != "dds_"]
    idl = os.path.join(idl_root, *modules, name[:-1] + ".idl")
    subprocess.run(["idlc", "-I", idl_root, "-o", output, idl], capture_output=True, text=True,
                   check=True)
    with open(os.path.join(output, name[:-1] + ".c"), encoding="utf-8") as handle:
        text = handle.read()
    mangled = dds_type.replace("::", "_")
    found = {}
    for key, macro in (("type_info", "TYPE_INFO_CDR_"), ("type_map", "TYPE_MAP_CDR_")):
        match = re.search(
            rf"#define {macro}{re.escape(mangled)} \(unsigned char \[\]\)\{{(.*?)\}}", text, re.S)
        assert match is not None, f"idlc gave no {macro}{mangled} for {dds_type}"
        found[key] = bytes(int(byte, 16) for byte in re.findall(r"0x([0-9a-f]{2})", match[1]))
    return found
