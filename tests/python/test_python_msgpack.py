"""The support module's MessagePack writer and log-summary formatting, against independent
references: msgpack-python for integers, strings, bins and array headers, the rules of msgpack-cxx's
pack_float/pack_double for floats, and glibc's printf("%g") for numbers in summaries."""
from __future__ import annotations

import ctypes
import random
import struct

import msgpack
import pytest

from test_python_mirror import generated_root, import_from


@pytest.fixture(scope="module")
def s(tmp_path_factory):
    return import_from(generated_root(tmp_path_factory), "_horus_gen_support_v1")[0]


def packed(codec, value) -> bytes:
    out: list = []
    codec.pack(out, value)
    return b"".join(out)


EDGES = [0, 1, 31, 32, 127, 128, 255, 256, 65535, 65536, (1 << 32) - 1, 1 << 32, (1 << 63) - 1, 1 << 63,
         (1 << 64) - 1, -1, -32, -33, -128, -129, -32768, -32769, -(1 << 31), -(1 << 31) - 1, -(1 << 63)]


def test_integers_take_their_smallest_form(s):
    rng = random.Random(7)
    values = EDGES + [rng.randrange(-(1 << 63), 1 << 64) >> rng.randrange(64) for _ in range(2000)]
    for v in values:
        codec = s.U64 if v >= 0 else s.I64
        assert packed(codec, v) == msgpack.packb(v), v


def test_integer_ranges_are_checked(s):
    with pytest.raises(s.FieldError, match=r"256 is out of range for u8 \(0..255\)"):
        packed(s.U8, 256)
    with pytest.raises(s.FieldError, match="out of range for i16"):
        packed(s.I16, -32769)
    with pytest.raises(s.FieldError, match="expected an integer, got float"):
        packed(s.I32, 1.0)


def reference_double(d: float) -> bytes:
    """msgpack-cxx pack_double: an integral value within uint64/int64 range as an integer (-0.0 too)."""
    if d == d and 0 <= d < 2.0 ** 64 and d == int(d):
        return msgpack.packb(int(d))
    if d == d and -(2.0 ** 63) <= d < 0 and d == int(d):
        return msgpack.packb(int(d))
    return b"\xcb" + struct.pack(">d", d)


@pytest.mark.parametrize("value, expected", [
    (-0.0, b"\x00"), (3.0, b"\x03"), (-1.0, b"\xff"), (1.5, b"\xcb" + struct.pack(">d", 1.5)),
    (1e20, b"\xcb" + struct.pack(">d", 1e20)), (2.0 ** 64, b"\xcb" + struct.pack(">d", 2.0 ** 64)),
    (2.0 ** 64 - 2048, b"\xcf" + struct.pack(">Q", 2 ** 64 - 2048)), (-(2.0 ** 63), b"\xd3" + struct.pack(">q", -(2 ** 63))),
    (float("nan"), b"\xcb\x7f\xf8\x00\x00\x00\x00\x00\x00"), (float("inf"), b"\xcb\x7f\xf0" + bytes(6)),
])
def test_doubles_follow_msgpack_cxx(s, value, expected):
    assert packed(s.F64, value) == expected


def test_doubles_match_the_reference_rule(s):
    rng = random.Random(11)
    values = [rng.uniform(-1e6, 1e6) for _ in range(500)] + [float(rng.randrange(-(1 << 62), 1 << 62)) for _ in range(500)]
    for v in values:
        assert packed(s.F64, v) == reference_double(v), v


@pytest.mark.parametrize("value, expected", [
    (1e20, b"\xca" + struct.pack(">f", 1e20)), (0.5, b"\xca" + struct.pack(">f", 0.5)),
    (1e-3, b"\xca" + struct.pack(">f", 1e-3)), (3.0, b"\x03"), (-0.0, b"\x00"), (1e19, b"\xcf" + struct.pack(">Q", 9999999980506447872)),
    (float("nan"), b"\xca\x7f\xc0\x00\x00"),
])
def test_floats_are_single_precision_or_integers(s, value, expected):
    assert packed(s.F32, value) == expected


def test_strings_bins_and_arrays_use_the_standard_headers(s):
    for n in (0, 31, 32, 255, 256, 65535, 65536):
        text = "x" * n
        assert packed(s.STR, text) == msgpack.packb(text)
        assert packed(s.BYTES, b"y" * n) == msgpack.packb(b"y" * n, use_bin_type=True)
    for n in (0, 15, 16, 65535, 65536):
        assert packed(s.Vec(s.U8), [1] * n) == msgpack.packb([1] * n)
    assert packed(s.Option(s.I32), None) == b"\xc0" and packed(s.BOOL, True) == b"\xc3"
    assert packed(s.NumArray(s.U8, (3,)), [1, 2, 3]) == b"\xc4\x03\x01\x02\x03"  # std::array<uint8_t, N>: bin
    assert packed(s.NumArray(s.U8, (2, 2)), [[1, 2], [3, 4]]) == b"\x92\xc4\x02\x01\x02\xc4\x02\x03\x04"


def test_decoding_accepts_integers_for_floats_and_rejects_wrong_types(s):
    assert s.F64.unpack(3) == 3.0 and type(s.F64.unpack(3)) is float
    assert s.F32.unpack(0.1) == struct.unpack("<f", struct.pack("<f", 0.1))[0]
    with pytest.raises(s.FieldError, match="expected a number"):
        s.F64.unpack("1")
    with pytest.raises(s.FieldError, match="expected bool"):
        s.BOOL.unpack(1)
    with pytest.raises(s.FieldError, match="expected an integer"):
        s.U8.unpack(True)


LIBC = ctypes.CDLL(None)


def printf_g(x: float) -> str:
    out = ctypes.create_string_buffer(64)
    LIBC.snprintf(out, 64, b"%g", ctypes.c_double(x))
    return out.value.decode()


def test_numbers_print_as_glibc_printf_g(s):
    rng = random.Random(3)
    specials = [0.0, -0.0, 1234565.0, 1234575.0, 0.5, 1e-5, 1e-4, 123456.5, 999999.5, 1e16, 1e20,
                float("inf"), float("-inf"), float("nan"), -float("nan"), 5e-324, 1.7976931348623157e308]
    randoms = [struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0] for _ in range(3000)]
    randoms += [rng.uniform(-1000, 1000) for _ in range(3000)] + [float(rng.randrange(10 ** 9)) for _ in range(1000)]
    for x in specials + randoms:
        assert s.fmt_g(x) == printf_g(x), repr(x)


def test_sequence_summaries_follow_the_cpp_loop(s):
    numbers = s.Vec(s.F64)
    assert numbers.summary([], "f64") == "[]"
    assert numbers.summary([1.0, 2.5], "f64") == "[1, 2.5]"
    # NaN first: every comparison with it is false, so it stays min and max, as in C++
    assert numbers.summary([float("nan")] + [1.0] * 8, "f64") == "[9 x f64, min nan, max nan]"
    assert numbers.summary([0.0, -0.0] + [1.0] * 7, "f64") == "[9 x f64, min 0, max 1]"
    assert s.Vec(s.U64).summary([(1 << 64) - 1] * 9, "u64") == "[9 x u64, min 1.84467e+19, max 1.84467e+19]"
    assert s.Vec(s.BOOL).summary([True] * 4, "bool") == "[true, true, true, true]"
    assert s.Vec(s.BOOL).summary([True] * 5, "bool") == "[5 x bool]"
    assert s.Vec(s.STR).summary(["a"], "String") == '["a"]'
    assert s.Option(s.Vec(s.F32)).summary(None, "f32") == "none"
    assert s.Vec(s.Vec(s.F64)).summary([[1.0] * 9], "Vec<f64>") == "[[9 x , min 1, max 1]]"
