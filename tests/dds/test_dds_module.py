"""horus._core.dds: raw-CDR writers and readers on Cyclone DDS, in one process on loopback."""
from __future__ import annotations

import struct

from processes import wait_until
from horus._core import dds as _dds

TYPE = "horus::msg::dds_::CmdVel_"


def cmdvel(stamp: int) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<Qff", stamp, 0.5, -0.25)


def take(reader, count: int) -> list[bytes]:
    got: list[bytes] = []
    wait_until(lambda: got.extend(reader.take(0.1)) or len(got) >= count, f"{count} samples")
    return got


def test_samples_cross_between_participants_in_order_as_written(dds_domain):
    a, b = _dds.Participant(dds_domain), _dds.Participant(dds_domain)
    writer = _dds.Writer(a, "rt/cmd_vel", TYPE)
    reader = _dds.Reader(b, "rt/cmd_vel", TYPE)
    wait_until(lambda: writer.matched() == 1 and reader.matched() == 1, "the match")
    for stamp in range(50):
        writer.write(cmdvel(stamp))
    assert take(reader, 50) == [cmdvel(stamp) for stamp in range(50)]


def test_a_participant_never_reads_its_own_writes(dds_domain):
    a, b = _dds.Participant(dds_domain), _dds.Participant(dds_domain)
    writer = _dds.Writer(a, "rt/cmd_vel", TYPE)
    own = _dds.Reader(a, "rt/cmd_vel", TYPE)
    other = _dds.Reader(b, "rt/cmd_vel", TYPE)
    wait_until(lambda: other.matched() == 1, "the other participant's reader")
    writer.write(cmdvel(1))
    assert take(other, 1) == [cmdvel(1)]
    assert own.take(0.2) == [] and own.matched() == 0 and writer.matched() == 1


def test_publications_name_topic_type_and_user_data_of_other_participants(dds_domain):
    a, b = _dds.Participant(dds_domain), _dds.Participant(dds_domain)
    writer = _dds.Writer(a, "rt/cmd_vel", TYPE, user_data=b"identity")
    own = _dds.Writer(b, "rt/other", "x::dds_::Y_")

    def found():
        return [p for p in b.publications() if p["topic"] == "rt/cmd_vel"]
    (publication,) = wait_until(found, "the publication")
    assert publication["type"] == TYPE and publication["user_data"] == b"identity"
    assert publication["participant"] == a.guid != b.guid
    assert all(p["topic"] != "rt/other" for p in b.publications())
    del writer, own  # alive until here: their publications are what the test reads


def test_a_transient_local_writer_gives_late_readers_its_history(dds_domain):
    a, b = _dds.Participant(dds_domain), _dds.Participant(dds_domain)
    writer = _dds.Writer(a, "rt/map", TYPE, transient_local=True, depth=1)
    writer.write(cmdvel(1))
    writer.write(cmdvel(2))
    reader = _dds.Reader(b, "rt/map", TYPE, transient_local=True, depth=1)
    assert take(reader, 1) == [cmdvel(2)]


def test_one_topic_name_with_two_types_is_refused(dds_domain):
    a = _dds.Participant(dds_domain)
    writer = _dds.Writer(a, "rt/cmd_vel", TYPE)
    try:
        _dds.Reader(a, "rt/cmd_vel", "horus::msg::dds_::Twist_")
    except RuntimeError as error:
        assert "horus::msg::dds_::CmdVel_" in str(error) and "Twist_" in str(error)
    else:
        raise AssertionError("a second type on one topic name was accepted")
    del writer


def test_a_reader_of_typed_writers_only_matches_writers_of_its_type_alone(dds_domain):
    from horus.msg import CmdVel, Twist
    cmdvel_type, twist_type = (dict(zip(("type_info", "type_map"),
                                        _dds.type_on_wire(cls.__horus__.description)[1:]))
                               for cls in (CmdVel, Twist))
    a, b, c, d = (_dds.Participant(dds_domain) for _ in range(4))
    reader = _dds.Reader(a, "rt/cmd_vel", TYPE, typed_writers_only=True, **cmdvel_type)
    good = _dds.Writer(b, "rt/cmd_vel", TYPE, **cmdvel_type)
    # CmdVel's name, Twist's type information; and no type information at all.
    other_type = _dds.Writer(c, "rt/cmd_vel", TYPE, **twist_type)
    untyped = _dds.Writer(d, "rt/cmd_vel", TYPE)
    wait_until(lambda: good.matched() == 1 and reader.matched() == 1, "the typed writer's match")
    other_type.write(cmdvel(1))
    untyped.write(cmdvel(2))
    good.write(cmdvel(3))
    assert take(reader, 1) == [cmdvel(3)]
    assert reader.matched() == 1 and other_type.matched() == 0 and untyped.matched() == 0


def test_take_names_each_sample_s_writer_by_handle_and_writer_guids_finds_and_caps_them(
        dds_domain):
    a, b, c = (_dds.Participant(dds_domain) for _ in range(3))
    reader = _dds.Reader(c, "rt/cmd_vel", TYPE)
    first, second = _dds.Writer(a, "rt/cmd_vel", TYPE), _dds.Writer(b, "rt/cmd_vel", TYPE)
    wait_until(lambda: reader.matched() == 2, "both writers")
    first.write(cmdvel(1))
    second.write(cmdvel(2))
    got: list = []
    wait_until(lambda: got.extend(reader.take(0.1, writers=True)) or len(got) >= 2, "2 samples")
    # A handle per sample (an int, nothing looked up); the GUID only when asked, once a writer.
    assert [cdr for _, cdr in got] == [cmdvel(1), cmdvel(2)]
    (one, _), (two, _) = got
    assert isinstance(one, int) and isinstance(two, int) and one != two
    guids = {p["participant"]: p["writer"] for p in c.publications()}
    writers = _dds.WriterGuids(reader, cap=1)
    assert writers.find(one) == guids[a.guid] and writers.kept == 1
    # Past the cap a writer is not looked up (its samples are counted as other writers').
    assert writers.find(two) is None and writers.kept == 1
    assert writers.find(one) == guids[a.guid]
    assert _dds.WriterGuids(reader).find(12345) == "unknown"  # DDS knows no such writer


def test_the_cpp_bridge_announces_the_type_information_of_horus_gens_idl(kinds_class):
    # The C++ bridge spells the IDL from the type description, a DDS program has horus-gen
    # write it: idlc must make the same XTypes type information of both, or DDS would see two
    # types (assignable at best) where there is one.
    import horus.msg
    from dds_test import Pods
    from horus_gen_types import HorusGenTypes
    types = HorusGenTypes()
    for cls in (kinds_class, Pods, horus.msg.CmdVel, horus.msg.Imu, horus.msg.ImageDescriptor):
        info = cls.__horus__
        name, type_info, type_map = _dds.type_on_wire(info.description)
        assert name == types.dds_name(info.name, info.schema), info.name
        expected = types.type_info(info.name, info.schema)
        assert (type_info, type_map) == (expected["type_info"], expected["type_map"]), info.name
