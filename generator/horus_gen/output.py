"""Writing generated files: all or nothing, and only what changed.

Files are first written to a temporary folder beside OUT; only when every file has been produced
are they moved into place, and a file whose content is unchanged is left alone so its timestamp
(and everything compiled from it) stays as it was. A manifest records what the last run wrote, so
files of types that were removed from the schemas are deleted.
"""
from __future__ import annotations

import os
import shutil
import tempfile

MANIFEST = ".horus-gen-outputs"


def write_outputs(out_dir: str, files: dict[str, str]) -> list[str]:
    """Writes `files` (relative path -> content) under out_dir; returns the paths it changed."""
    os.makedirs(out_dir, exist_ok=True)
    staging = tempfile.mkdtemp(prefix=".horus-gen-staging-", dir=out_dir)
    changed: list[str] = []
    try:
        for relative, content in sorted(files.items()):
            staged = os.path.join(staging, relative)
            os.makedirs(os.path.dirname(staged), exist_ok=True)
            with open(staged, "w", encoding="utf-8", newline="\n") as handle:
                handle.write(content)
        for relative, content in sorted(files.items()):
            target = os.path.join(out_dir, relative)
            if _read(target) == content:
                continue
            os.makedirs(os.path.dirname(target), exist_ok=True)
            os.replace(os.path.join(staging, relative), target)
            changed.append(target)
        manifest = os.path.join(out_dir, MANIFEST)
        previous = set((_read(manifest) or "").split("\n")) - {""}
        for stale in sorted(previous - set(files)):
            path = os.path.join(out_dir, stale)
            if os.path.isfile(path):
                os.remove(path)
                changed.append(path)
        listing = "".join(f"{relative}\n" for relative in sorted(files))
        if _read(manifest) != listing:
            with open(manifest, "w", encoding="utf-8") as handle:
                handle.write(listing)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return changed


def _read(path: str) -> str | None:
    try:
        with open(path, encoding="utf-8") as handle:
            return handle.read()
    except (OSError, UnicodeDecodeError):
        return None


def write_depfile(path: str, target: str, inputs: list[str]) -> None:
    def escape(p: str) -> str:
        return os.path.abspath(p).replace("\\", "\\\\").replace(" ", "\\ ").replace("#", "\\#").replace("$", "$$")

    body = f"{escape(target)}: " + " \\\n  ".join(escape(p) for p in sorted(set(inputs))) + "\n"
    if _read(path) != body:
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(body)


def touch(path: str) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "a", encoding="utf-8"):
        pass
    os.utime(path, None)
