"""`horus shm list` / `clean` and a namespace's log ring and presence folder: shown with the live
processes that use them, kept while one does, removed once the last one died."""
from __future__ import annotations

import json
import os

from conftest import run_horus, wait_ready
from processes import wait_until

LOGGING_SCHEDULER = """
import horus
def tick(node):
    node.log_info("ticking")
    print("ready", flush=True)
horus.run(horus.Node(name="talker", tick=tick, rate=50), tick_rate=50)
"""


def shm_objects() -> dict[str, dict]:
    """The non-topic rows of `horus shm list --json`, by name."""
    rows = json.loads(run_horus("shm", "list", "--json").stdout)
    return {r["name"]: r for r in rows if r["name"] in ("@logs", "@presence")}


def test_the_log_ring_and_presence_folder_are_listed_and_cleaned_once_their_users_died(
        children, namespace):
    talker = children.python(LOGGING_SCHEDULER)
    wait_ready(talker)
    wait_until(lambda: len(shm_objects()) == 2, "the ring and the presence folder")
    listed = shm_objects()
    assert listed["@logs"]["path"].endswith(f"/@logs/{namespace}")
    assert listed["@presence"]["path"].endswith(f"/@presence/{namespace}")
    assert listed["@logs"]["in_use"] and listed["@presence"]["in_use"]
    # The talker holds both (a lock each): the only user of each.
    talker_user = [{"pid": talker.pid, "program": "python3"}]
    assert listed["@logs"]["users"] == talker_user and listed["@presence"]["users"] == talker_user
    assert listed["@logs"]["size"] > 0
    table = {line.split()[0]: line.split() for line in run_horus("shm", "list").stdout.splitlines()}
    assert table["@logs"][2] == table["@presence"][2] == f"{talker.pid}(python3)"

    assert run_horus("shm", "clean").returncode == 0
    assert {name: row["in_use"] for name, row in shm_objects().items()} == \
        {"@logs": True, "@presence": True}, "a live process's ring or folder was touched"

    talker.kill()  # no destructor: its announcement stays, its locks go
    talker.wait()
    assert {name: (row["in_use"], row["users"]) for name, row in shm_objects().items()} == \
        {"@logs": (False, []), "@presence": (False, [])}
    table = {line.split()[0]: line.split() for line in run_horus("shm", "list").stdout.splitlines()}
    assert table["@logs"][2] == table["@presence"][2] == "-"

    cleaned = run_horus("shm", "clean", "--json")
    assert cleaned.returncode == 0, cleaned.stderr
    assert json.loads(cleaned.stdout)["announcements"] == 1
    assert shm_objects() == {}
    assert not os.path.exists(listed["@logs"]["path"])
    assert not os.path.exists(listed["@presence"]["path"])
