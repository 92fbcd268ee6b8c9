"""Golden tests of horus-gen's error messages: every file in tests/golden/diagnostics must fail
`horus-gen check` with exactly the text in its `.stderr` file, and exit status 1.

Refresh after an intended change, then read the diff:
    HORUS_UPDATE_GOLDEN=1 /usr/bin/python3 -m pytest tests/python/test_diagnostics_golden.py
"""
from __future__ import annotations

import os

import pytest

from generator_testing import GOLDEN, run_horus_gen

CASES = sorted(p for p in (GOLDEN / "diagnostics").iterdir() if p.suffix in (".hmsg", ".hsrv", ".haction", ".hnode"))
# Node files name the standard messages (schemas/) and the test schemas (tests/schemas/), as relative paths so
# that the expected text does not depend on where the checkout is.
NODE_INCLUDES = ("-I", "../../../schemas", "-I", "../../schemas")


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_diagnostics_match_golden(case):
    includes = NODE_INCLUDES if case.suffix == ".hnode" else ()
    result = run_horus_gen("check", *includes, case.name, cwd=case.parent)
    expected_path = case.with_suffix(case.suffix + ".stderr")
    if os.environ.get("HORUS_UPDATE_GOLDEN"):
        expected_path.write_text(result.stderr)
    assert result.returncode == 1, f"{case.name}: expected exit 1 (schema errors), got {result.returncode}"
    assert "Traceback" not in result.stderr
    assert result.stderr == expected_path.read_text(), f"{case.name}: diagnostics differ from {expected_path.name}"


def test_every_case_has_a_golden_file():
    missing = [c.name for c in CASES if not c.with_suffix(c.suffix + ".stderr").exists()]
    assert not missing, f"cases without expected output: {missing}"
