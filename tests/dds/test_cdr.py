"""dds_cdr: HORUS messages as the CDR of the IDL horus-gen emits (XCDR1, little-endian), checked
byte by byte and against a plain idlc-built C program (dds_peer.c) over Cyclone DDS."""
from __future__ import annotations

import struct

import numpy
import pytest

import dds_cdr
from processes import wait_line, wait_until
from horus._core import dds as _dds
from horus.msg import CmdVel


def sample_kinds(Kinds):
    from dds_test import Inner, Mode
    return Kinds(small=7, big=-9000000000, mode=Mode.Fault, name="héllo", tag="tag8",
                 blob=b"\x01\x02\x03", raw=b"", values=[0.5, -2.0],
                 grid=numpy.array([[1, -2, 3], [-4, 5, -6]], numpy.int16), labels=["first", ""],
                 inner=Inner(flag=True, wide=0.125),
                 inners=[Inner(flag=True, wide=1.25), Inner(flag=False, wide=-3.5)],
                 maybe=6.5, nothing=None, points=[numpy.array([1.0, 2.0, 3.0], numpy.float32)],
                 last=255)


def test_a_pod_message_is_its_fields_at_their_cdr_alignment():
    cdr = dds_cdr.CdrCodec(CmdVel).encode(CmdVel(stamp_nanos=2000, linear=1.5, angular=0.75))
    # The bytes the spike's raw writer sent and an idlc program read: header CDR_LE, options 0.
    assert cdr == b"\x00\x01\x00\x00" + struct.pack("<Qff", 2000, 1.5, 0.75)


def test_every_kind_of_field_round_trips(kinds_class):
    codec = dds_cdr.CdrCodec(kinds_class)
    message = sample_kinds(kinds_class)
    assert codec.decode(codec.encode(message)) == message


def test_alignment_strings_sequences_and_options_follow_xcdr1(kinds_class):
    from dds_test import Inner
    Kinds = kinds_class
    cdr = dds_cdr.CdrCodec(Kinds).encode(Kinds(small=1, big=2, name="ab", inners=[Inner()],
                                               maybe=None, last=9))
    assert len(cdr) % 4 == 0 and cdr[:3] == b"\x00\x01\x00"
    body = cdr[4:len(cdr) - cdr[3]]
    assert body[0] == 1 and body[1:8] == bytes(7)  # u8, then i64 aligned to 8
    assert struct.unpack_from("<qH", body, 8) == (2, 0)  # big, mode (u16)
    # name: after the u16 at 16, a uint32 length (NUL included) at 20, the bytes, the NUL
    assert struct.unpack_from("<I", body, 20)[0] == 3 and body[24:27] == b"ab\0"
    assert body[-1] == 9  # last
    # an Option is sequence<T, 1>: count 0 when empty
    empty = dds_cdr.CdrCodec(Kinds).encode(Kinds(maybe=None))
    present = dds_cdr.CdrCodec(Kinds).encode(Kinds(maybe=1.0))
    assert len(present) - len(empty) >= 8


def test_bytes_that_do_not_fit_are_a_value_error(kinds_class):
    codec = dds_cdr.CdrCodec(kinds_class)
    cdr = codec.encode(sample_kinds(kinds_class))
    with pytest.raises(ValueError, match="dds_test.Kinds"):
        codec.decode(cdr[:40])
    with pytest.raises(ValueError, match="encapsulation 0007 is XCDR2, and the bridge reads XCDR1"):
        codec.decode(b"\x00\x07\x00\x00" + cdr[4:])
    with pytest.raises(ValueError, match="encapsulation 0003 is not plain CDR"):
        codec.decode(b"\x00\x03\x00\x00" + cdr[4:])  # XCDR1's parameter list (@mutable)
    with pytest.raises(ValueError, match="encapsulation header"):
        codec.decode(b"\x00")


def test_big_endian_cdr_reads_too():
    body = struct.pack(">Qff", 7, 2.5, -1.0)
    message = dds_cdr.CdrCodec(CmdVel).decode(b"\x00\x00\x00\x00" + body)
    assert (message.stamp_nanos, message.linear, message.angular) == (7, 2.5, -1.0)


# What dds_peer prints of sample_kinds (C's %g of each value).
KINDS_LINE = ("small=7 big=-9000000000 mode=300 name=héllo tag=tag8 blob=010203 raw= "
              "values=0.5,-2 grid=1,-2,3,-4,5,-6 labels=first, inner=(1 0.125) "
              "inners=(1 1.25)(0 -3.5) maybe=6.5 nothing=none points=(1 2 3) last=255")


def test_an_idlc_program_reads_what_the_codec_writes(dds_domain, kinds_class, dds_peer, children):
    peer = children.start([dds_peer, "read-kinds", str(dds_domain), "1"])
    wait_line(peer, "ready")
    participant = _dds.Participant(dds_domain)
    writer = _dds.Writer(participant, "rt/kinds", "dds_test::dds_::Kinds_")
    wait_until(lambda: writer.matched() == 1, "the C reader")
    writer.write(dds_cdr.CdrCodec(kinds_class).encode(sample_kinds(kinds_class)))
    out, errors = peer.communicate(timeout=30)
    assert peer.returncode == 0, errors
    assert out.splitlines()[-1] == KINDS_LINE


def test_the_codec_reads_what_an_idlc_program_writes(dds_domain, kinds_class, dds_peer, children):
    from dds_test import Inner, Mode
    participant = _dds.Participant(dds_domain)
    reader = _dds.Reader(participant, "rt/kinds", "dds_test::dds_::Kinds_")
    peer = children.start([dds_peer, "write-kinds", str(dds_domain)])
    got: list[bytes] = []
    wait_until(lambda: got.extend(reader.take(0.1)) or got, "the C writer's sample")
    message = dds_cdr.CdrCodec(kinds_class).decode(got[0])
    expected = kinds_class(small=7, big=-9000000000, mode=Mode.Fault, name="from C", tag="c-tag",
                           blob=b"\x01\x02\x03", raw=b"", values=[0.5, -2.0],
                           grid=numpy.array([[1, -2, 3], [-4, 5, -6]], numpy.int16),
                           labels=["first", ""], inner=Inner(flag=True, wide=0.125),
                           inners=[Inner(flag=True, wide=1.25), Inner(flag=False, wide=-3.5)],
                           maybe=6.5, nothing=None,
                           points=[numpy.array([1.0, 2.0, 3.0], numpy.float32)], last=255)
    assert message == expected
    peer.communicate(timeout=30)
    assert peer.returncode == 0


def test_the_cpp_bridge_converts_serialized_types_as_dds_cdr_does(kinds_class):
    # The C++ bridge's conversion of a serialized type (from its type description) writes the
    # bytes dds_cdr writes and reads them back to the same message.
    from dds_test import Inner
    Kinds = kinds_class
    codec, cpp = dds_cdr.CdrCodec(Kinds), _dds.SerializedCdr(Kinds.__horus__.description)
    for message in (sample_kinds(Kinds), Kinds(), Kinds(maybe=1.0, inners=[Inner()], last=9)):
        cdr = codec.encode(message)
        assert cpp.encode(message.to_bytes()) == cdr
        assert Kinds.from_bytes(cpp.decode(cdr)) == message
    with pytest.raises(ValueError, match="does not decode as dds_test.Kinds: a count of 5 at "
                                         "offset 32 runs past the 36-byte body"):
        cpp.decode(codec.encode(sample_kinds(Kinds))[:40])
    with pytest.raises(ValueError, match="encapsulation 0007 is XCDR2, and the bridge reads XCDR1"):
        cpp.decode(b"\x00\x07\x00\x00" + codec.encode(Kinds())[4:])
    with pytest.raises(ValueError, match="bytes are left over"):
        cpp.decode(codec.encode(Kinds()) + bytes(8))
