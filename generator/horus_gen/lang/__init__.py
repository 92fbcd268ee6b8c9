"""The output languages. Each is one module here (its spelling filters, naming rules, output file
names and `emit(model, data)`) paired with the template folder of the same name under the
template root (`templates/<lang>/`). Adding a language is one module listed in LANGUAGES plus one
template folder.

A language module provides: DISPLAY_NAME, KEYWORDS (names its code cannot use), reserved(name)
(why a name it does not reserve as a keyword is still taken, or None) and emit().
"""
from __future__ import annotations

from types import ModuleType
from typing import Callable

from ..data import DataPaths
from ..model import Model
from . import cpp, idl, jsonschema, python

LANGUAGES: dict[str, ModuleType] = {"cpp": cpp, "python": python, "jsonschema": jsonschema,
                                   "idl": idl}

Emitter = Callable[[Model, DataPaths], dict[str, str]]


def emitter(language: str) -> Emitter:
    return LANGUAGES[language].emit


def keyword_clash(name: str) -> str | None:
    """Which language reserves `name`, if one does: every generated name must suit them all."""
    keyword_of = [module.DISPLAY_NAME for module in LANGUAGES.values() if name in module.KEYWORDS]
    if keyword_of:
        return f"a {' and '.join(keyword_of)} keyword"
    return next((reason for reason in (module.reserved(name) for module in LANGUAGES.values()) if reason), None)
