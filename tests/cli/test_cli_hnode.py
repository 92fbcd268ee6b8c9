"""A program whose two nodes are declared by .hnode files: `horus node list` shows exactly the
topics those files declare (read back with `horus-gen describe --json`), nothing more or less."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

from conftest import run_horus, wait_ready
from processes import wait_until

ROOT = Path(__file__).resolve().parents[2]
NODE_FILES = [ROOT / "tests" / "schemas" / "test_nodes" / name for name in ("talker.hnode", "listener.hnode")]


def declared_nodes() -> dict[str, dict]:
    """The nodes of talker.hnode and listener.hnode as horus-gen describes them."""
    result = subprocess.run(["/usr/bin/python3", str(ROOT / "generator" / "horus-gen"), "describe", "--json",
                             "-I", str(ROOT / "tests" / "schemas"), *map(str, NODE_FILES)],
                            capture_output=True, text=True, check=True)
    return {t["name"]: t for t in json.loads(result.stdout)["types"] if t["kind"] == "node"}


def test_node_list_shows_exactly_the_topics_the_hnode_files_declare(children):
    program = os.environ.get("HORUS_NODE_PAIR")
    assert program, "HORUS_NODE_PAIR names the horus_node_pair program; run this suite through ctest"
    process = children.program(program)
    wait_ready(process)
    running = wait_until(lambda: {n["name"]: n for n in json.loads(run_horus("node", "list", "--json").stdout)}
                         or None, "the program's announcement")
    declared = declared_nodes()
    assert sorted(running) == sorted(declared) == ["listener", "talker"]
    for name, node in declared.items():
        for direction in ("publishers", "subscribers"):
            expected = [{"topic": t["topic"], "type": t["type"]} for t in node[direction]]
            assert running[name][direction] == expected, f"{name} {direction}"
        assert running[name]["pid"] == process.pid
    # What the declarations say, spelled out: a wrong describe would not hide a wrong program.
    assert running["talker"]["publishers"] == [{"topic": "pair.pose", "type": "test_msgs.Pose2"}]
    assert running["listener"]["subscribers"] == [{"topic": "pair.pose", "type": "test_msgs.Pose2"}]
    assert running["talker"]["rate_hz"] == 200.0
