"""Python mirror types against LCM's generated Python, and the import time of a 35-type package.

Measures, in µs per operation (best of several timeit repeats):
  - construct (all fields given) + to_bytes() + from_bytes() of test_msgs.ImuLike (304-byte POD) and
    test_msgs.Blob (a 1 MiB bytes payload, MessagePack), each step alone and the three together;
  - the same with lcm-gen's Python for the same messages (encode()/decode(); it needs only struct);
  - the import time of a generated 35-type package, in a fresh interpreter each time.
Usage: /usr/bin/python3 bench/python/bench_mirror.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import timeit
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HORUS_GEN = ROOT / "generator" / "horus-gen"
SCHEMAS = ROOT / "tests" / "schemas"

LCM_SCHEMA = """package horus_bench;
struct imu_like {
    double orientation[4];
    double orientation_covariance[9];
    double angular_velocity[3];
    double angular_velocity_covariance[9];
    double linear_acceleration[3];
    double linear_acceleration_covariance[9];
    int64_t timestamp_ns;
}
struct blob {
    int64_t seq;
    int32_t payload_size;
    byte payload[payload_size];
}
"""


def package_of_35_types() -> str:
    """5 enums and 30 messages: POD ones with arrays and nested types, serialized ones with Vec/Option."""
    lines = ["package bench35;", ""]
    for e in range(5):
        lines.append(f"enum Kind{e}: u8 {{ A = 0, B = 1, C = {e + 2} }}")
    for i in range(30):
        lines.append(f"/// Message {i}.")
        fields = ["stamp_ns: u64", f"kind: Kind{i % 5}", f"value: f64 = {i}.5", f"values: [f32; {4 + i}]",
                  "name: string<16>", "flag: bool"]
        if i > 0:
            fields.append(f"previous: Msg{i - 1}" if i % 3 else f"items: Vec<Msg{i - 1}>")
        if i % 4 == 0:
            fields += ["note: String", "maybe: Option<i32>", "blob: bytes"]
        lines.append(f"Msg{i} {{ " + ", ".join(fields) + " }")
    return "\n".join(lines) + "\n"


def run(cmd, **kw):
    result = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if result.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed:\n{result.stderr}")
    return result.stdout


def best_us(stmt, number: int, repeat: int) -> float:
    return min(timeit.repeat(stmt, number=number, repeat=repeat)) / number * 1e6


def bench_codecs(work: Path, quick: bool) -> list[tuple[str, str, float, float]]:
    run(["/usr/bin/python3", str(HORUS_GEN), "generate", "--lang", "python", "--out", str(work / "horus"),
         "-I", str(SCHEMAS), *[str(p) for p in sorted((SCHEMAS / "test_msgs").glob("*.hmsg"))],
         str(SCHEMAS / "other_pkg" / "stamp.hmsg")])
    (work / "bench.lcm").write_text(LCM_SCHEMA)
    run(["lcm-gen", "-p", "--ppath", str(work / "lcm"), str(work / "bench.lcm")])
    sys.path[:0] = [str(work / "horus" / "python"), str(work / "lcm")]
    import test_msgs  # noqa: E402  (generated above)
    from horus_bench import blob, imu_like  # noqa: E402

    vectors = {"orientation": [0.0, 0.0, 0.7, 0.7], "orientation_covariance": [0.01 * i for i in range(9)],
               "angular_velocity": [0.1, -0.2, 0.3], "angular_velocity_covariance": [0.02 * i for i in range(9)],
               "linear_acceleration": [0.0, 0.0, 9.81], "linear_acceleration_covariance": [0.03 * i for i in range(9)]}
    stamp = 1700000000123456789
    payload = bytes(range(256)) * 4096  # 1 MiB

    def horus_imu():
        return test_msgs.ImuLike(timestamp_ns=stamp, **vectors)

    def lcm_imu():
        m = imu_like()
        for k, v in vectors.items():
            setattr(m, k, v)
        m.timestamp_ns = stamp
        return m

    def horus_blob():
        return test_msgs.Blob(seq=7, payload=payload)

    def lcm_blob():
        m = blob()
        m.seq, m.payload_size, m.payload = 7, len(payload), payload
        return m

    cases = [
        ("ImuLike (304 B POD)", horus_imu, lambda m: m.to_bytes(), test_msgs.ImuLike.from_bytes,
         lcm_imu, lambda m: m.encode(), imu_like.decode, 5000),
        ("Blob (1 MiB bytes)", horus_blob, lambda m: m.to_bytes(), test_msgs.Blob.from_bytes,
         lcm_blob, lambda m: m.encode(), blob.decode, 50),
    ]
    rows = []
    repeat = 3 if quick else 15
    for label, h_make, h_enc, h_dec, l_make, l_enc, l_dec, number in cases:
        number = max(1, number // (10 if quick else 1))
        h_msg, l_msg = h_make(), l_make()
        h_bytes, l_bytes = h_enc(h_msg), l_enc(l_msg)
        assert h_dec(h_bytes) == h_msg
        rows.append((label, "construct", best_us(h_make, number, repeat), best_us(l_make, number, repeat)))
        rows.append((label, "to_bytes / encode", best_us(lambda: h_enc(h_msg), number, repeat),
                     best_us(lambda: l_enc(l_msg), number, repeat)))
        rows.append((label, "from_bytes / decode", best_us(lambda: h_dec(h_bytes), number, repeat),
                     best_us(lambda: l_dec(l_bytes), number, repeat)))
        rows.append((label, "all three", best_us(lambda: h_dec(h_enc(h_make())), number, repeat),
                     best_us(lambda: l_dec(l_enc(l_make())), number, repeat)))
    return rows


def import_ms(root: Path, statement: str, runs: int, env: dict) -> float:
    probe = ("import time\nt = time.perf_counter()\n" + statement +
             "\nprint((time.perf_counter() - t) * 1000)")
    times = [float(run(["/usr/bin/python3", "-c", probe], cwd=root, env=env)) for _ in range(runs)]
    return statistics.median(times)


def bench_imports(work: Path, quick: bool) -> list[tuple[str, float]]:
    schema = work / "bench35" / "bench35.hmsg"
    schema.parent.mkdir(parents=True)
    schema.write_text(package_of_35_types())
    out = work / "gen35"
    run(["/usr/bin/python3", str(HORUS_GEN), "generate", "--lang", "python", "--out", str(out), str(schema)])
    root = out / "python"
    count = run(["/usr/bin/python3", "-c", "import bench35; print(len(bench35.__all__))"], cwd=root,
                env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}).strip()
    fresh = work / "gen35-fresh"
    shutil.copytree(root, fresh)
    assert count == "35", count
    runs = 5 if quick else 21
    cached = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    run(["/usr/bin/python3", "-c", "import bench35"], cwd=root, env=cached)  # write __pycache__
    nocache = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    rows = [
        ("import bench35 (35 types), bytecode cached", import_ms(root, "import bench35", runs, cached)),
        ("import bench35, numpy already imported", import_ms(root, "import numpy\nt = time.perf_counter()\nimport bench35",
                                                             runs, cached)),
        ("import bench35 + first message with arrays (imports numpy)",
         import_ms(root, "import bench35\nbench35.Msg29()", runs, cached)),
        ("import numpy alone (reference)", import_ms(root, "import numpy", runs, cached)),
        ("import typing alone (reference for the machine's speed)", import_ms(root, "import typing", runs, cached)),
    ]
    rows.append(("import bench35, no bytecode (compiles every module)",
                 import_ms(fresh, "import bench35", runs, nocache)))
    std = ROOT / "schemas"
    files = sorted(str(p) for p in (std / "horus" / "msg").glob("*.hmsg"))
    if files:
        run(["/usr/bin/python3", str(HORUS_GEN), "generate", "--lang", "python", "--out", str(work / "std"),
             "-I", str(std), *files])
        std_root = work / "std" / "python"
        n = run(["/usr/bin/python3", "-c", "import horus.msg as m; print(len(m.__all__))"], cwd=std_root, env=cached)
        rows.append((f"import horus.msg (standard library, {n.strip()} types), bytecode cached",
                     import_ms(std_root, "import horus.msg", runs, cached)))
        rows.append(("import horus.msg, numpy already imported (its mixins import numpy)",
                     import_ms(std_root, "import numpy\nt = time.perf_counter()\nimport horus.msg", runs, cached)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="horus-bench-python-") as tmp:
        work = Path(tmp)
        codec_rows = bench_codecs(work, args.quick)
        import_rows = bench_imports(work, args.quick)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"{_cpu_model()}; Python {platform.python_version()}")
    print("\n| message | operation | horus-gen Python (µs) | lcm-gen Python (µs) |")
    print("|---|---|---:|---:|")
    for label, op, h, l in codec_rows:
        print(f"| {label} | {op} | {h:.2f} | {l:.2f} |")
    print("\n| import | median (ms) |")
    print("|---|---:|")
    for label, ms in import_rows:
        print(f"| {label} | {ms:.1f} |")


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


if __name__ == "__main__":
    main()
