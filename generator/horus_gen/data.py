"""Where horus-gen finds the files it renders and copies: the template root (`templates/<lang>/`)
and the Python support module (`runtime/python/_horus_gen_support_v1.py`).

Each launcher states them once: `generator/horus-gen` for a checkout (the repository's own
folders), the installed `bin/horus-gen` as configured from `cmake/horus-gen.in` at install time.
HORUS_GEN_TEMPLATES overrides the template root (to try edited templates without reinstalling).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

TEMPLATES_OVERRIDE = "HORUS_GEN_TEMPLATES"


@dataclass(frozen=True)
class DataPaths:
    templates: str  # holds one folder of templates per language: cpp/, python/
    python_support: str  # the support module copied into every Python output root
    launcher: str  # the script that started this run: part of the generator, listed in depfiles

    @staticmethod
    def for_launcher(launcher: str, templates: str, python_support: str) -> "DataPaths":
        return DataPaths(os.path.normpath(os.environ.get(TEMPLATES_OVERRIDE) or templates),
                         os.path.normpath(python_support), os.path.realpath(launcher))
