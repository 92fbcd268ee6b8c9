"""Fixtures of the recording suite: those of the `horus` command's suite (tests/cli/conftest.py:
a namespace per test, the command, child processes), a recordings folder per test, and the check
of a file's CRCs and indexes that tests/python/runtime uses."""
from __future__ import annotations

import importlib.util
import os

import pytest



def _load(name: str, *path: str):
    spec = importlib.util.spec_from_file_location(name, os.path.join(os.path.dirname(__file__), *path))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


cli_fixtures = _load("cli_fixtures", "..", "cli", "conftest.py")
namespace = cli_fixtures.namespace
children = cli_fixtures.children
# Every CRC (the summary's too) and index of a file, read by PyPI mcap (tests/python/runtime).
check_file = _load("mcap_check", "..", "python", "runtime", "mcap_check.py").check_file


@pytest.fixture(autouse=True)
def recordings(monkeypatch, tmp_path):
    folder = tmp_path / "recordings"
    folder.mkdir()
    monkeypatch.setenv("HORUS_RECORDINGS", str(folder))
    return folder
