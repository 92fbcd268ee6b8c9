"""Every standard message, built in Python with the deterministic value that
tests/unit/msg_roundtrip_test.cpp builds in C++, has the same wire bytes as C++'s (size and
FNV-1a 64 pinned in tests/golden/msg_roundtrip.json) and survives to_bytes/from_bytes: the
C++ <-> Python round trip of every type, without a shared-memory run."""
from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = json.loads((ROOT / "tests" / "golden" / "msg_roundtrip.json").read_text())
SCHEMAS = sorted((ROOT / "schemas" / "horus" / "msg").glob("*.hmsg"))


def describe() -> dict:
    result = subprocess.run(["/usr/bin/python3", str(ROOT / "generator" / "horus-gen"), "describe", "--json",
                             "-I", str(ROOT / "schemas"), *map(str, SCHEMAS)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return {t["name"]: t for t in json.loads(result.stdout)["types"]}


TYPES = describe()
MESSAGES = sorted(name for name, t in TYPES.items() if t["kind"] == "message")


def test_every_message_has_a_pinned_wire_form():
    short = {name.rsplit(".", 1)[-1] for name in MESSAGES}
    assert short == set(GOLDEN) - {"_about"}, "refresh with HORUS_UPDATE_GOLDEN=1 msg_roundtrip_test"


class Filler:
    """The value of msg_roundtrip_test.cpp: one counter step per leaf, depth first."""

    def __init__(self, msg):
        self.msg = msg
        self.k = 1

    def take(self) -> int:
        k, self.k = self.k, self.k + 1
        return k

    def value(self, spelling: str):
        if spelling in ("bytes", "Vec<u8>"):  # one C++ type, std::vector<std::uint8_t>: one rule
            k = self.take()
            return bytes([k % 256, (k + 1) % 256, (k + 2) % 256])
        if m := re.fullmatch(r"\[(.+); (\d+)\]", spelling):
            return [self.value(m.group(1)) for _ in range(int(m.group(2)))]
        if m := re.fullmatch(r"string<(\d+)>", spelling):
            return f"s{self.take()}"[:int(m.group(1))]
        if m := re.fullmatch(r"Vec<(.+)>", spelling):
            return [self.value(m.group(1)) for _ in range(2)]
        if m := re.fullmatch(r"Option<(.+)>", spelling):
            return self.value(m.group(1))
        if spelling == "String":
            return f"text{self.take()}"
        if spelling == "bool":
            return self.take() % 2 == 1
        if spelling in ("f32", "f64"):
            return self.take() + 0.25
        if m := re.fullmatch(r"([ui])(8|16|32|64)", spelling):
            bits, k = int(m.group(2)), self.take()
            return k % (1 << bits) if m.group(1) == "u" else -(k % (1 << (bits - 1)))
        described = TYPES[spelling]
        cls = getattr(self.msg, spelling.rsplit(".", 1)[-1])
        if described["kind"] == "enum":
            self.take()
            return cls(described["values"][0]["value"])
        return self.message(spelling)

    def message(self, qualified: str):
        cls = getattr(self.msg, qualified.rsplit(".", 1)[-1])
        return cls(**{f["name"]: self.value(f["spelling"]) for f in TYPES[qualified]["fields"]})


def fnv1a64(data: bytes) -> int:
    h = 0xcbf29ce484222325
    for b in data:
        h = ((h ^ b) * 0x100000001b3) & 0xFFFFFFFFFFFFFFFF
    return h


@pytest.mark.parametrize("qualified", MESSAGES)
def test_python_writes_the_bytes_cpp_writes_and_reads_them_back(msg, qualified):
    value = Filler(msg).message(qualified)
    data = value.to_bytes()
    pinned = GOLDEN[qualified.rsplit(".", 1)[-1]]
    assert len(data) == pinned["size"]
    assert f"0x{fnv1a64(data):016x}" == pinned["fnv1a64"], "Python's bytes differ from C++'s"
    assert type(value).from_bytes(data) == value
