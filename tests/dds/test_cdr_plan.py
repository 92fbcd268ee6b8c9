"""horus._core.dds.CdrPlan (the bridge's C++ conversion of POD types, planned from the type
description's offsets) writes the same CDR as dds_cdr.CdrCodec and reads it back to the same
struct bytes, for every POD type of the test schemas and of horus.msg."""
from __future__ import annotations

import struct

import numpy
import pytest

import dds_cdr
import horus.msg
from horus._core import dds as _dds


def value_of(codec, seed: int):
    """A value of the field `codec` describes that differs from its default (seed varies it)."""
    kind = type(codec).__name__
    if kind == "Bool":
        return seed % 2 == 0
    if kind == "Int":
        return codec.hi - seed * 7 % 100 if seed % 2 else codec.lo + seed * 3 % 100
    if kind == "Float":
        return -1.5 * (seed + 1) + 0.25
    if kind == "Enum":
        members = list(codec.cls)
        return members[seed % len(members)]
    if kind == "FixedStr":  # full (no NUL) for an even seed, one byte short for an odd one
        accent = "é" if codec.size >= 4 else ""
        return accent + ("abcdefgh" * 8)[:codec.size - seed % 2 - len(accent.encode())]
    if kind == "NumArray":
        count, element = codec.count, codec.element
        values = [value_of(element, seed + index) for index in range(count)]
        return numpy.array(values, codec.dtype).reshape(codec.shape)
    if kind == "ListArray":
        return [value_of(codec.element, seed + index) for index in range(codec.length)]
    if kind == "Nested":
        return message_of(codec.cls, seed)
    raise AssertionError(f"{kind} is not a POD field")


def message_of(cls, seed: int = 1):
    info = cls.__horus__
    return cls(**{name: value_of(codec, seed + index)
                  for index, (name, codec) in enumerate(zip(info.fields, info.codecs))})


def plan_of(cls):
    info = cls.__horus__
    return _dds.CdrPlan.from_description(info.description)


def pod_classes(module):
    return [value for value in vars(module).values()
            if isinstance(value, type) and getattr(getattr(value, "__horus__", None), "is_pod",
                                                   False)]


def standard_pod_types():
    classes = pod_classes(horus.msg)
    assert {"CmdVel", "Imu", "Pose2D"} <= {cls.__name__ for cls in classes}
    return classes


def assert_same_both_ways(cls, message) -> None:
    plan, codec = plan_of(cls), dds_cdr.CdrCodec(cls)
    cdr = codec.encode(message)
    assert plan.encode(message.to_bytes()) == cdr, cls.__horus__.name
    pod = plan.decode(cdr)
    assert pod == message.to_bytes(), cls.__horus__.name
    assert cls.from_bytes(pod) == codec.decode(cdr)


def test_every_pod_type_of_the_test_schemas_converts_as_the_codec_does(kinds_class):
    import dds_test
    classes = pod_classes(dds_test)
    assert {"Pods", "Wheel", "Blank", "Inner", "Empty"} <= {cls.__name__ for cls in classes}
    for cls in classes:
        for seed in (1, 2, 5):
            assert_same_both_ways(cls, message_of(cls, seed))
        assert_same_both_ways(cls, cls())


@pytest.mark.parametrize("cls", standard_pod_types(), ids=lambda cls: cls.__name__)
def test_every_standard_pod_type_converts_as_the_codec_does(cls):
    assert_same_both_ways(cls, message_of(cls))
    assert_same_both_ways(cls, cls())


def test_a_string_moves_what_follows_it_and_neighbouring_numbers_are_one_step(kinds_class):
    from dds_test import Pods
    steps = plan_of(Pods).steps
    assert steps[0] == ("copy", 0, 8, 1) and steps[1] == ("bool", 8, 1, 1)
    assert ("string", 44, 12, 1) in steps and ("copy", 64, 4, 3) in steps  # direction: one step
    short = Pods(label="", full="abcd", names=["", "x"])
    long = Pods(label="twelve bytes", full="abcd", names=["", "x"])
    assert len(plan_of(Pods).encode(long.to_bytes())) > len(plan_of(Pods).encode(short.to_bytes()))
    assert_same_both_ways(Pods, short)
    assert_same_both_ways(Pods, long)


def test_big_endian_cdr_decodes_to_the_same_struct():
    from horus.msg import CmdVel
    body = struct.pack(">Qff", 7, 2.5, -1.0)
    pod = plan_of(CmdVel).decode(b"\x00\x00\x00\x00" + body)
    assert pod == CmdVel(stamp_nanos=7, linear=2.5, angular=-1.0).to_bytes()


def test_samples_that_do_not_fit_are_value_errors_naming_the_type(kinds_class):
    from dds_test import Pods
    plan = plan_of(Pods)
    cdr = plan.encode(message_of(Pods).to_bytes())
    with pytest.raises(ValueError, match="does not decode as dds_test.Pods: .* bytes wanted"):
        plan.decode(cdr[:40])
    with pytest.raises(ValueError, match="bytes are left over"):
        plan.decode(cdr + bytes(8))
    with pytest.raises(ValueError, match="encapsulation 0007 is XCDR2, and the bridge reads XCDR1"):
        plan.decode(b"\x00\x07\x00\x00" + cdr[4:])
    with pytest.raises(ValueError, match="encapsulation 0009 is XCDR2, and the bridge reads XCDR1"):
        plan.decode(b"\x00\x09\x00\x00" + cdr[4:])
    with pytest.raises(ValueError, match="encapsulation 0003 is not plain CDR"):
        plan.decode(b"\x00\x03\x00\x00" + cdr[4:])
    with pytest.raises(ValueError, match="no encapsulation header"):
        plan.decode(b"\x00")
    # label is string<12>: a 13-byte string in its place does not fit
    short = dds_cdr.CdrCodec(Pods).encode(Pods(label="ab"))
    label = struct.pack("<I", 3) + b"ab\0"
    assert short.count(label) == 1
    too_long = short.replace(label, struct.pack("<I", 14) + b"x" * 13 + b"\0")
    with pytest.raises(ValueError, match=r"13 bytes does not fit in string<12>"):
        plan.decode(too_long)
    with pytest.raises(ValueError, match="is 168 bytes, not 3"):
        plan.encode(b"abc")


def test_a_serialized_type_has_no_plan(kinds_class):
    from dds_test import Kinds
    with pytest.raises(ValueError, match="dds_test.Kinds is a serialized message: it has no POD "
                                         "layout"):
        _dds.CdrPlan.from_description(Kinds.__horus__.description)
    with pytest.raises(RuntimeError):
        _dds.CdrPlan.from_description(b"not a description")


def test_a_plan_reaching_outside_the_struct_is_refused():
    with pytest.raises(ValueError, match="does not fit a 16-byte t.T"):
        _dds.CdrPlan("t.T", 16, [("copy", 12, 8, 1)])
    with pytest.raises(ValueError, match="no CDR step of kind 'text'"):
        _dds.CdrPlan("t.T", 16, [("text", 0, 1, 1)])
