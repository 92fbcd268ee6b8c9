"""horus-check on tests/check/fixture and on the warehouse_agv demo (ctest `horus_check`).

The fixture's lines that must be reported carry `// expect: <check>`; every finding must be one
of them and each of them must be found, so a finding at the wrong line fails either way.
"""
import json
import os
import re
import subprocess
from pathlib import Path

import pytest

CHECK = os.environ["HORUS_CHECK"]
BUILD = Path(os.environ["HORUS_CHECK_BUILD_DIR"])
FIXTURE = Path(os.environ["HORUS_CHECK_FIXTURE"])
GENERATED = Path(os.environ["HORUS_CHECK_FIXTURE_GENERATED"])
DEMO = Path(os.environ["HORUS_CHECK_DEMO"])


def database_files(predicate):
    entries = json.loads((BUILD / "compile_commands.json").read_text())
    return sorted({str(Path(e["directory"], e["file"]).resolve()) for e in entries
                   if predicate(Path(e["directory"], e["file"]).resolve())})


def fixture_files(*names):
    generated = database_files(lambda p: GENERATED.parent in p.parents and p.name == "_nodes.cpp")
    assert generated, "the fixture's generated _nodes.cpp is not in compile_commands.json"
    return [str(FIXTURE / name) for name in names] + generated


def run(files, *options):
    result = subprocess.run([CHECK, "-p", str(BUILD), *options, *files],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode in (0, 1), result.stderr
    return result


def expectations(*names):
    expected = set()
    for name in names:
        for number, line in enumerate((FIXTURE / name).read_text().splitlines(), start=1):
            for check in re.findall(r"expect: (horus-[a-z-]+)", line):
                expected.add((name, number, check))
    return expected


FIXTURE_SOURCES = ("worker.cpp", "clean.cpp", "rogue.cpp")


@pytest.fixture(scope="module")
def fixture_run():
    """One run over every fixture source (Clang parses each: slow), which several tests read."""
    return run(fixture_files(*FIXTURE_SOURCES), "--json")


def test_findings_at_their_lines(fixture_run):
    assert fixture_run.returncode == 1
    report = json.loads(fixture_run.stdout)
    found = {(Path(f["file"]).name, f["line"], f["check"]) for f in report["findings"]}
    assert found == expectations(*FIXTURE_SOURCES)


def test_tick_findings_name_node_and_call_chain(fixture_run):
    report = json.loads(fixture_run.stdout)
    by_check = {}
    for finding in (f for f in report["findings"] if Path(f["file"]).name == "worker.cpp"):
        assert finding["node"] in ("Worker", "Logger")
        if finding["node"] == "Logger":
            assert finding["check"] == "horus-rt-io" and "std::cout" in finding["message"]
            continue
        by_check.setdefault(finding["check"], []).append(finding)
    sleep = by_check["horus-rt-sleep"][0]
    assert sleep["chain"][:2] == ["Worker::tick", "settle"]
    assert sleep["chain"][-1] == "std::this_thread::sleep_for"
    # remember() is reached from tick() directly, through settle() and through journal(): its
    # lock is one finding per call site, whatever the path.
    guards = [f for f in by_check["horus-rt-lock"] if "std::lock_guard" in f["message"]]
    assert len(guards) == 1, guards
    assert [f["chain"] for f in by_check["horus-rt-block"] if "ServiceClient" in f["message"]] \
        == [["Worker::tick", "journal", "horus::ServiceClient::call"]]


def test_compiler_style_text_and_exit_status():
    result = run(fixture_files("rogue.cpp"))
    assert result.returncode == 1
    lines = result.stdout.splitlines()
    assert len(lines) == 4
    for line in lines:
        assert re.match(r"^/.*/rogue\.cpp:\d+:\d+: warning: .* \[horus-node-[a-z-]+\]$", line), line
    assert any('opens topic "fixture.debug" (member debug_)' in line for line in lines)
    assert any('opens topic "fixture.command" as struct check_fixture::Wheels but declares it as '
               'struct check_fixture::Odometry' in line for line in lines)


def test_clean_node_is_silent():
    result = run(fixture_files("clean.cpp"), "--target", "aarch64-linux-gnu")
    assert (result.returncode, result.stdout, result.stderr.strip()) == (0, "", "")


def test_layout_that_differs_on_i686():
    files = fixture_files("clean.cpp")
    assert run(files, "--target", "aarch64-linux-gnu", "--target", "armv7-linux-gnueabihf").returncode == 0
    report = json.loads(run(files, "--json", "--target", "i686-linux-gnu").stdout)
    layout = [f for f in report["findings"] if f["check"] == "horus-layout"]
    assert len(layout) == 1, layout
    header = GENERATED / "check_fixture" / "odometry.hpp"
    field_line = next(number for number, line in enumerate(header.read_text().splitlines(), 1)
                      if "stamp_ns" in line)
    assert (Path(layout[0]["file"]).resolve(), layout[0]["line"]) == (header.resolve(), field_line)
    message = layout[0]["message"]
    assert "'check_fixture.Odometry'" in message and "i686-linux-gnu" in message
    assert "field 'stamp_ns' at offset 4 instead of 8" in message and "size 12 instead of 16" in message


def test_nodes_inventory(fixture_run):
    report = json.loads(fixture_run.stdout)
    nodes = {node["name"]: node for node in report["nodes"]}
    worker = nodes["check_fixture::WorkerBase"]
    assert worker["realtime"] == "rate"
    assert {t["name"] for t in worker["topics"]} == {"fixture.wheels", "fixture.odom"}
    assert [p["name"] for p in worker["publishers"]] == ["fixture.odom"]
    assert nodes["Logger"]["realtime"] == "rate"  # .rate() where it is added
    rogue = nodes["Rogue"]
    assert rogue["realtime"] == ""
    assert {t["name"] for t in rogue["topics"]} == {"fixture.odom", "fixture.debug", "fixture.command"}


def test_demo_is_clean():
    files = database_files(lambda p: DEMO in p.parents or (
        "warehouse_agv" in p.parts and BUILD in p.parents and p.suffix == ".cpp"))
    assert any(f.endswith("main.cpp") for f in files) and any(f.endswith("_nodes.cpp") for f in files)
    result = run(files, "--target", "aarch64-linux-gnu")
    assert (result.returncode, result.stdout) == (0, ""), result.stdout
