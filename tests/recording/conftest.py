"""Fixtures of the recording suite: those of the `horus` command's suite (tests/cli/conftest.py:
a namespace per test, the command, child processes), and a recordings folder per test."""
from __future__ import annotations

import importlib.util
import os

import pytest

_spec = importlib.util.spec_from_file_location(
    "cli_fixtures", os.path.join(os.path.dirname(__file__), "..", "cli", "conftest.py"))
cli_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cli_fixtures)
namespace = cli_fixtures.namespace
children = cli_fixtures.children
wait_until = cli_fixtures.wait_until


@pytest.fixture(autouse=True)
def recordings(monkeypatch, tmp_path):
    folder = tmp_path / "recordings"
    folder.mkdir()
    monkeypatch.setenv("HORUS_RECORDINGS", str(folder))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return folder
