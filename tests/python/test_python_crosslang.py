"""Cross-language tests, both directions, for every type of tests/schemas.

The C++ tools in tests/generated/crosslang are built by CMake against the generated headers; ctest
passes their paths in HORUS_CROSSLANG_TOOL and HORUS_CROSSLANG_ECHO, a plain `pytest` finds them
in the build tree (generator_testing.crosslang_tools: missing tools fail the suite, never skip it).

- horus_crosslang writes one fixed value of every test-schema type; Python reads those bytes, compares
  them with the same values built here, and must write the very same bytes, log summary and
  fingerprints; then the tool decodes what Python wrote and compares it field by field in C++.
- horus_crosslang_echo covers every message of the test schemas and of the standard library with
  values made here from each type's fields: C++ decodes Python's bytes and writes them back; the
  bytes, the log summary and the fingerprint must come back unchanged.
"""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from generator_testing import ROOT, crosslang_tools, generate_python, import_from

TOOL, ECHO = crosslang_tools()

NAN, INF = float("nan"), float("inf")


def fixtures(m, o) -> dict:
    """The values crosslang_tool.cpp builds, type for type (keep the two in step)."""
    arrays = m.Arrays(small=[1, 65535, 300], ranges=np.arange(360, dtype=np.float32) * np.float32(0.25) - 10,
                      grid=[[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 255]], name="twelve bytes",
                      names=["eight ch", "x"],
                      poses=[m.Pose2(position=m.Point2(x=1.0, y=2.0), theta=0.5),
                             m.Pose2(position=m.Point2(x=-1.0, y=-2.0), theta=-0.5)],
                      flags=[True, False, True, True, False])
    imu = m.ImuLike(orientation=[0.0, 0.0, 0.7071067811865476, 0.7071067811865476],
                    orientation_covariance=[0.01 * i for i in range(9)],
                    angular_velocity=[0.1, -0.2, 0.3],
                    angular_velocity_covariance=[-0.5 * i for i in range(9)],
                    linear_acceleration=[0.0, 0.0, 9.81],
                    linear_acceleration_covariance=[1e-9 * (i + 1) for i in range(9)],
                    timestamp_ns=1700000000123456789)
    serialized = m.Serialized(
        text="héllo wörld ✓", data=bytes((i * 7) & 0xFF for i in range(300)),
        values=[0.0, -0.0, 1.5, 3.0, 1e20, -1e20, NAN, INF, -INF, 18446744073709551616.0,
                -9223372036854775808.0, 1234565.0, 1e-7, -2.5, 9007199254740993.0],
        counts=[0, 127, 128, 255, 256, 65535, 65536, 4294967295], small=b"\x01\x02\x03", maybe=-33,
        maybe_text="opt",
        poses=[m.Pose2(position=m.Point2(x=1.25, y=-0.0), theta=3.0),
               m.Pose2(position=m.Point2(x=1e20, y=-7.0), theta=1e-3)],
        tags=["a", "x" * 40, ""], fixed=[0.5, -1.0, 1e-3], mode=m.Mode.Fault, label="sixteen-bytes-ok",
        nested=[m.Point2(x=1.0, y=2.0), m.Point2(x=-3.5, y=4.0)])
    return {
        "test_msgs.Point2": m.Point2(x=1.5, y=-2.25),
        "test_msgs.Pose2": m.Pose2(position=m.Point2(x=3.0, y=4.0), theta=0.1),
        "other_pkg.Stamp": o.Stamp(sec=1700000000, nanosec=5, source=301),
        "test_msgs.Primitives": m.Primitives(flag=True, u64_value=(1 << 64) - 1, u8_value=255, u16_value=65535,
                                             i8_value=-128, u32_value=4294967295, i16_value=-32768,
                                             i32_value=-(1 << 31), i64_value=-(1 << 63), f32_value=1e20,
                                             f64_value=-0.0),
        "test_msgs.Arrays": arrays,
        "test_msgs.Defaults": m.Defaults(speed=1.5, count=4000000001, offset=-30000, mode=m.Mode.Fault,
                                         enabled=False, label="ab", gains=[0.1, 0.2, 0.3],
                                         stamp=o.Stamp(sec=-7, nanosec=999999999, source=o.Source.Ptp)),
        "test_msgs.Empty": m.Empty(),
        "test_msgs.ImuLike": imu,
        "test_msgs.Serialized": serialized,
        "test_msgs.Blob": m.Blob(seq=(1 << 64) - 1, payload=bytes((i * 7) & 0xFF for i in range(70000))),
        "test_msgs.GetRobotPoseRequest": m.GetRobotPoseRequest(robot_name="robot-7"),
        "test_msgs.GetRobotPoseResponse": m.GetRobotPoseResponse(x=1.0, y=2.0, theta=-3.14159, timestamp_ns=42),
        "test_msgs.AddIntsRequest": m.AddIntsRequest(a=-5, b=(1 << 63) - 1),
        "test_msgs.AddIntsResponse": m.AddIntsResponse(sum=9223372036854775802),
    }


def same(a, b) -> bool:
    """Field-by-field equality with NaN equal to NaN (the C++ tool compares the same way)."""
    if hasattr(type(a), "__horus__") and hasattr(type(a), "log_summary"):
        return type(a) is type(b) and all(same(getattr(a, f), getattr(b, f)) or codec.eq(getattr(a, f), getattr(b, f))
                                          for f, codec in zip(a.__horus__.fields, a.__horus__.codecs))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=np.asarray(a).dtype.kind == "f"))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return a == b


@pytest.fixture(scope="module")
def packages(test_schemas_root):
    return import_from(test_schemas_root, "test_msgs", "other_pkg")


@pytest.fixture(scope="module")
def shapes(test_schemas_root):
    return import_from(test_schemas_root, "crosslang_msgs")[0]


@pytest.fixture(scope="module")
def cpp_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("from_cpp")
    result = subprocess.run([TOOL, "write", str(out)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return out


def all_types(m, o) -> dict:
    return {t.__horus__.name: t for t in (getattr(m, n) for n in m.__all__) if hasattr(t, "log_summary")} | \
        {"other_pkg.Stamp": o.Stamp}


def test_fixtures_cover_every_message_type(packages):
    m, o = packages
    assert set(fixtures(m, o)) == set(all_types(m, o))


@pytest.mark.parametrize("name", sorted([
    "test_msgs.Point2", "test_msgs.Pose2", "other_pkg.Stamp", "test_msgs.Primitives", "test_msgs.Arrays",
    "test_msgs.Defaults", "test_msgs.Empty", "test_msgs.ImuLike", "test_msgs.Serialized", "test_msgs.Blob",
    "test_msgs.GetRobotPoseRequest", "test_msgs.GetRobotPoseResponse", "test_msgs.AddIntsRequest",
    "test_msgs.AddIntsResponse"]))
def test_python_reads_and_writes_the_bytes_cpp_writes(packages, cpp_dir, name):
    m, o = packages
    expected = fixtures(m, o)[name]
    T = type(expected)
    cpp_bytes = (cpp_dir / f"{name}.bin").read_bytes()
    got = T.from_bytes(cpp_bytes)
    if name == "test_msgs.Serialized":
        # -0.0 travels as the integer 0 in MessagePack (msgpack-cxx does so): compare values, not signs
        assert got.poses[0].position.y == 0.0 and got.values[1] == 0.0
    assert same(got, expected), f"{got!r}\n!=\n{expected!r}"
    assert expected.to_bytes() == cpp_bytes, "Python must write exactly the bytes C++ writes"
    assert got.to_bytes() == cpp_bytes
    assert expected.log_summary() == (cpp_dir / f"{name}.txt").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", ["test_msgs.Primitives", "test_msgs.Arrays", "test_msgs.Defaults",
                                  "test_msgs.ImuLike", "other_pkg.Stamp", "test_msgs.Pose2"])
def test_numpy_views_read_and_write_cpp_bytes_in_place(packages, cpp_dir, name):
    m, o = packages
    expected = fixtures(m, o)[name]
    T = type(expected)
    cpp_bytes = (cpp_dir / f"{name}.bin").read_bytes()
    record = np.frombuffer(cpp_bytes, T.__horus__.dtype)[0]
    view = T.view(cpp_bytes)
    for field, codec in zip(T.__horus__.fields, T.__horus__.codecs):
        value = getattr(expected, field)
        if hasattr(type(value), "log_summary") or isinstance(value, list):
            continue  # nested messages and lists of them: compared through the view below
        assert codec.eq(getattr(view, field), value), field
        if isinstance(value, str):
            assert record[field] == value.encode()
        else:
            assert codec.eq(record[field], value), field
    assert same(view.to_message(), expected)
    slot = bytearray(len(cpp_bytes))  # write every field through a view: the bytes C++ wrote appear
    write_through_view(T.view(slot), expected)
    assert bytes(slot) == cpp_bytes


def write_through_view(view, value) -> None:
    """Sets every field of `view` from `value`, descending into nested messages' views."""
    for field in value.__horus__.fields:
        item = getattr(value, field)
        if hasattr(type(item), "log_summary"):
            write_through_view(getattr(view, field), item)
        elif isinstance(item, list) and item and hasattr(type(item[0]), "log_summary"):
            for inner_view, inner in zip(getattr(view, field), item):
                write_through_view(inner_view, inner)
        else:
            setattr(view, field, item)


def test_cpp_reads_what_python_writes(packages, cpp_dir, tmp_path):
    m, o = packages
    for name, value in fixtures(m, o).items():
        (tmp_path / f"{name}.bin").write_bytes(value.to_bytes())
        (tmp_path / f"{name}.txt").write_text(value.log_summary(), encoding="utf-8")
    types = [m.Point2, m.Pose2, o.Stamp, m.Primitives, m.Arrays, m.Defaults, m.Empty, m.ImuLike, m.Serialized,
             m.Blob, m.GetRobotPoseRequest, m.GetRobotPoseResponse, m.AddIntsRequest, m.AddIntsResponse, m.Mode,
             o.Source]
    lines = [f"{t.__horus__.name} 0x{t.__horus__.fingerprint:016x}\n" for t in types]
    lines += [f"test_msgs.{s.name} 0x{s.fingerprint:016x}\n" for s in (m.GetRobotPose, m.AddInts)]
    (tmp_path / "fingerprints.txt").write_text("".join(lines))
    assert (tmp_path / "fingerprints.txt").read_text() == (cpp_dir / "fingerprints.txt").read_text()
    result = subprocess.run([TOOL, "check", str(tmp_path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_cpp_reports_a_python_value_that_differs(packages, tmp_path):
    """The check direction can fail: a changed field is named by the C++ tool."""
    m, o = packages
    for name, value in fixtures(m, o).items():
        if name == "test_msgs.Serialized":
            value.nested[1].y = 5.0
        (tmp_path / f"{name}.bin").write_bytes(value.to_bytes())
        (tmp_path / f"{name}.txt").write_text(value.log_summary(), encoding="utf-8")
    result = subprocess.run([TOOL, "check", str(tmp_path)], capture_output=True, text=True)
    assert result.returncode == 1
    assert "test_msgs.Serialized.nested[1].y: 5 != 4" in result.stderr


# -- every message, standard library included, through the echo tool ----------------------------

def sample(codec, seed: int):
    """A value of the codec's type that exercises it: extremes, fractions, text, lengths vary."""
    import _horus_gen_support_v1 as s
    if isinstance(codec, s.Bool):
        return seed % 2 == 0
    if isinstance(codec, s.Int):
        choices = [codec.hi, codec.lo, seed % (codec.hi + 1), codec.hi // 3]
        return choices[seed % len(choices)]
    if isinstance(codec, s.Float):
        choices = [seed * 0.37 - 5.0, float(seed * 3), -0.0, 1e20, 1e-3 * seed]
        return choices[seed % len(choices)]
    if isinstance(codec, s.Enum):
        members = list(codec.cls)
        return members[seed % len(members)]
    if isinstance(codec, s.FixedStr):
        return ("é" + "abcdefghijklmnopqrstuvwxyz" * 10)[:max(0, min(codec.size - 1, seed % 12))]
    if isinstance(codec, s.Str):
        return f"text {seed} ✓"
    if isinstance(codec, s.Bytes):
        return bytes((seed + i) & 0xFF for i in range(seed % 40 + 1))
    if isinstance(codec, s.NumArray):
        flat = [sample(codec.element, seed + i) for i in range(codec.count)]
        return np.array(flat, codec.dtype).reshape(codec.shape)
    if isinstance(codec, s.ListArray):
        return [sample(codec.element, seed + i) for i in range(codec.length)]
    if isinstance(codec, s.Vec):
        return [sample(codec.element, seed + i) for i in range(seed % 4 + 1)]
    if isinstance(codec, s.Option):
        return None if seed % 3 == 0 else sample(codec.element, seed)
    if isinstance(codec, s.Nested):
        return sample_message(codec.cls, seed)
    raise AssertionError(f"no sample for {codec!r}")


def sample_message(cls, seed: int):
    return cls(**{name: sample(codec, seed * 3 + 7 * i) for i, (name, codec) in enumerate(zip(cls.__horus__.fields, cls.__horus__.codecs))})


@pytest.fixture(scope="module")
def std_package(tmp_path_factory):
    std = ROOT / "schemas"
    files = sorted(str(p) for p in (std / "horus" / "msg").glob("*.hmsg"))
    root = generate_python(tmp_path_factory.mktemp("std"), *files, extra=("-I", str(std)))
    return import_from(root, "horus.msg")[0]


def test_every_message_round_trips_through_cpp(packages, shapes, std_package, tmp_path):
    m, o = packages
    types = list(all_types(m, o).values()) + [t for package in (shapes, std_package)
                                               for t in (getattr(package, n) for n in package.__all__)
                                               if hasattr(t, "log_summary")]
    assert len(types) > 80
    sent = {}
    for seed, T in enumerate(types):
        value = sample_message(T, seed)
        sent[T.__horus__.name] = value
        (tmp_path / f"{T.__horus__.name}.bin").write_bytes(value.to_bytes())
    result = subprocess.run([ECHO, str(tmp_path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    fingerprints = dict(line.split() for line in (tmp_path / "fingerprints.echo.txt").read_text().splitlines())
    assert set(fingerprints) == set(sent), "the echo tool and Python see the same types"
    problems = []
    for name, value in sent.items():
        T = type(value)
        echoed = (tmp_path / f"{name}.echo.bin").read_bytes()
        if echoed != value.to_bytes():
            problems.append(f"{name}: C++ re-encoded different bytes")
        elif not same(T.from_bytes(echoed), T.from_bytes(value.to_bytes())):
            problems.append(f"{name}: Python reads different values from C++'s bytes")
        summary = (tmp_path / f"{name}.echo.txt").read_text(encoding="utf-8")
        if summary != T.from_bytes(echoed).log_summary():
            problems.append(f"{name}: log_summary differs\n  C++:    {summary}\n  Python: "
                            f"{T.from_bytes(echoed).log_summary()}")
        if int(fingerprints[name], 16) != T.__horus__.fingerprint:
            problems.append(f"{name}: fingerprint differs")
    assert not problems, "\n".join(problems)
