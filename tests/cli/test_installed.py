"""The installed `horus` command: `cmake --install` of this build into a scratch prefix, then its
bin/horus run against a live process with nothing of the build tree on its paths, and its bash
completion file sourced; the Cyclone DDS set-up it installs in share/horus."""
from __future__ import annotations

import json
import os
import pathlib
import subprocess

from conftest import wait_ready

REPOSITORY = pathlib.Path(__file__).resolve().parents[2]

PUBLISHER = """
import horus, time
from horus.msg import CmdVel
topic = horus.Topic(CmdVel, "installed_cmd")
topic.send(CmdVel(linear=4.0, angular=1.0))
print("ready", flush=True)
while True:
    time.sleep(1)
"""


def test_the_installed_command_lists_and_echoes_a_live_topic(children, tmp_path):
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", os.environ["HORUS_BUILD_DIR"], "--prefix", str(prefix)],
                   check=True, capture_output=True)
    installed = str(prefix / "bin" / "horus")
    # Only the prefix: no build-tree package, generator or schema folder may help it.
    environment = {key: value for key, value in os.environ.items()
                   if key not in ("PYTHONPATH", "HORUS_GEN_PROGRAM", "HORUS_SCHEMA_DIR",
                                  "HORUS_BLACKBOX_PROGRAM")}

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([installed, *args], capture_output=True, text=True, timeout=60,
                              env=environment)

    helped = run("--help")
    assert helped.returncode == 0 and helped.stdout.startswith("usage: horus"), helped.stderr

    wait_ready(children.python(PUBLISHER))  # the build tree's runtime, as another program
    listed = run("topic", "list")
    assert listed.returncode == 0, listed.stderr
    assert listed.stdout.split() == ["installed_cmd"]
    echoed = run("topic", "echo", "installed_cmd", "--once", "--json", "--timeout", "10")
    assert echoed.returncode == 0, echoed.stderr
    assert json.loads(echoed.stdout) == {"stamp_nanos": 0, "linear": 4.0, "angular": 1.0}
    shown = run("msg", "show", "CmdVel", "--json")
    assert shown.returncode == 0 and json.loads(shown.stdout)["size"] == 16, shown.stderr

    # The installed completion file, sourced as bash-completion does, with the installed
    # command on the PATH: subcommands, and live topic names from the command itself.
    script = prefix / "share" / "bash-completion" / "completions" / "horus"
    path_environment = dict(environment, PATH=f"{prefix / 'bin'}:{os.environ['PATH']}")

    def complete(*words: str) -> list[str]:
        line = " ".join(f"'{word}'" for word in ("horus", *words))
        program = f"source '{script}'\nCOMP_WORDS=({line}); COMP_CWORD={len(words)}; _horus; " \
                  'printf "%s\\n" "${COMPREPLY[@]}"'
        result = subprocess.run(["bash", "-c", program], capture_output=True, text=True,
                                timeout=60, env=path_environment)
        assert result.returncode == 0, result.stderr
        return sorted(result.stdout.split())
    assert complete("se") == ["service"]
    assert complete("topic", "e") == ["echo"]
    assert complete("topic", "echo", "inst") == ["installed_cmd"]

    # The Cyclone DDS set-up for one machine that docs/dds-bridge.md points CYCLONEDDS_URI at.
    loopback = prefix / "share" / "horus" / "cyclonedds-loopback.xml"
    assert loopback.read_text() == (REPOSITORY / "docs" / "cyclonedds-loopback.xml").read_text()
