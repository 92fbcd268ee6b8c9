"""schemas/README.md lists every standard message with the tier and size horus-gen describes; these
tests fail when that table no longer matches the schemas (fix: /usr/bin/python3 schemas/update-readme)."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
UPDATE_README = ROOT / "schemas" / "update-readme"


def run_update(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["/usr/bin/python3", str(UPDATE_README), *args], capture_output=True, text=True)


def test_the_schemas_readme_type_table_matches_the_schemas():
    result = run_update("--check")
    assert result.returncode == 0, result.stderr


def test_the_check_fails_on_a_stale_table_and_the_update_repairs_it(tmp_path):
    readme = tmp_path / "README.md"
    shutil.copy(ROOT / "schemas" / "README.md", readme)
    text = readme.read_text()
    row = next(line for line in text.splitlines() if line.startswith("| `CmdVel` | geometry.hmsg |"))
    assert "| 16 |" in row, row
    readme.write_text(text.replace(row, row.replace("| 16 |", "| 17 |")))

    stale = run_update("--check", "--readme", str(readme))
    assert stale.returncode == 1
    assert "stale" in stale.stderr

    assert run_update("--readme", str(readme)).returncode == 0
    assert readme.read_text() == text


def test_the_table_lists_at_least_seventy_messages():
    text = (ROOT / "schemas" / "README.md").read_text()
    messages = [line for line in text.splitlines() if line.startswith("| `") and "| message |" in line]
    assert len(messages) >= 70, f"{len(messages)} messages listed"
