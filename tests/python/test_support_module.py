"""runtime/python/_horus_gen_support_v1.py imported as it is in the repository, without running the
generator: the encoding rules it shares with horus/codec.hpp and horus/msgpack.hpp, one by one."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

SUPPORT = Path(__file__).resolve().parents[2] / "runtime" / "python" / "_horus_gen_support_v1.py"


@pytest.fixture(scope="module")
def support():
    spec = importlib.util.spec_from_file_location("_horus_gen_support_v1", SUPPORT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def packed(codec, value) -> bytes:
    out: list = []
    codec.pack(out, value)
    return b"".join(out)


@pytest.mark.parametrize("value, expected", [
    (0, b"\x00"), (127, b"\x7f"), (128, b"\xcc\x80"), (65535, b"\xcd\xff\xff"),
    (1 << 32, b"\xcf\x00\x00\x00\x01\x00\x00\x00\x00"), (-1, b"\xff"), (-32, b"\xe0"), (-33, b"\xd0\xdf"),
    (-(1 << 63), b"\xd3\x80\x00\x00\x00\x00\x00\x00\x00"),
])
def test_integers_take_their_smallest_msgpack_form(support, value, expected):
    assert packed(support.I64 if value < 0 else support.U64, value) == expected


def test_integral_floats_are_written_as_integers_as_msgpack_cxx_does(support):
    assert packed(support.F64, 3.0) == b"\x03"
    assert packed(support.F32, -1.0) == b"\xff"
    assert packed(support.F32, 0.5) == b"\xca\x3f\x00\x00\x00"
    assert packed(support.F64, 0.5) == b"\xcb\x3f\xe0\x00\x00\x00\x00\x00\x00"
    assert packed(support.F64, 2.0 ** 64)[:1] == b"\xcb", "beyond uint64 a float stays a float"


def test_integer_ranges_are_checked_with_the_type_in_the_message(support):
    with pytest.raises(support.FieldError, match=r"256 is out of range for u8 \(0\.\.255\)"):
        packed(support.U8, 256)
    with pytest.raises(support.FieldError, match="expected an integer"):
        packed(support.I32, 1.5)
    with pytest.raises(support.FieldError, match="out of range for f32"):
        support.F32.value(1e39)


def test_fixed_strings_hold_at_most_their_capacity_and_no_nul(support):
    codec = support.FixedStr(4)
    assert codec.raw("abcd") == b"abcd"
    assert codec.from_raw(b"ab\0\0") == "ab"
    with pytest.raises(support.FieldError, match="string<4> holds at most 4"):
        codec.raw("abcde")
    with pytest.raises(support.FieldError, match="NUL"):
        codec.raw("a\0b")


def test_summaries_print_numbers_as_printf_g(support):
    assert support.fmt_g(0.1) == "0.1"
    assert support.fmt_g(1e20) == "1e+20"
    assert support.fmt_g(-math.nan) == "-nan"
    assert support.F32.summary(0.1, "") == "0.1"
    assert support.BOOL.summary(True, "") == "true"
