"""horus.Topic's C path for POD messages with scalar fields only (_core.pod_fast_path): the same
bytes as to_bytes(), the same messages as from_bytes(), and for every value it does not take as is
the general path's result or error."""
from __future__ import annotations

import math

import numpy
import pytest

import horus
from horus.msg import CmdVel, CompressedImage, Pose2D, Twist
from pyrt_test import ManyScalars, Scalars

EVERY_SCALAR = dict(flag=True, small=-30000, tiny=-128, octet=255, half=65535,
                    word=-2**31, uword=2**32 - 1, single=0.1, wide=-2**63, ulong=2**64 - 1,
                    precise=math.pi, last=True)


def pair(msg_type, name="fast"):
    return horus.Topic(msg_type, name), horus.Topic(msg_type, name)


def test_scalar_pod_topics_take_the_c_path_and_others_do_not():
    assert type(horus.Topic(CmdVel, "a").send).__name__ == "builtin_function_or_method"
    assert type(horus.Topic(Scalars, "b").try_recv).__name__ == "builtin_function_or_method"
    for msg_type in (Twist, CompressedImage, dict):  # arrays, serialized, GenericMessage
        assert type(horus.Topic(msg_type, msg_type.__name__).send).__name__ == "method"


@pytest.mark.parametrize("values", [EVERY_SCALAR, {}, dict(flag=False, single=-1e38, wide=7,
                                                            precise=-0.0, last=False)])
def test_sent_bytes_are_to_bytes_and_received_messages_are_from_bytes(values):
    pub = horus.Topic(Scalars, "scalars")
    raw = horus.Topic(Scalars, "scalars")._core  # the general (pybind11) receive: bytes
    sub = horus.Topic(Scalars, "scalars")
    msg = Scalars(**values)
    assert pub.send(msg)
    data = raw.try_recv()
    assert data == msg.to_bytes()
    got = sub.try_recv()
    assert type(got) is Scalars
    assert got == Scalars.from_bytes(data)
    assert [getattr(got, f) for f in Scalars.__horus__.fields] == \
        [getattr(Scalars.from_bytes(data), f) for f in Scalars.__horus__.fields]
    assert [type(getattr(got, f)) for f in Scalars.__horus__.fields] == \
        [type(getattr(Scalars.from_bytes(data), f)) for f in Scalars.__horus__.fields]


def test_padding_is_zero_whatever_was_sent_before():
    pub, sub = pair(Scalars)
    raw = horus.Topic(Scalars, "fast")._core
    pub.send(Scalars(**EVERY_SCALAR))
    pub.send(Scalars())
    raw.try_recv()
    assert raw.try_recv() == bytes(Scalars.__horus__.size)


@pytest.mark.parametrize("field, value", [
    ("single", 3),                      # an int for a float
    ("precise", True),                  # a bool for a float
    ("word", True),                     # a bool for an int
    ("single", numpy.float32(0.25)),    # numpy scalars: the general path
    ("ulong", numpy.uint64(2**64 - 1)),
    ("flag", 2),                        # truthiness, as struct's '?'
    ("last", []),
    ("single", math.inf),
    ("precise", math.nan),
])
def test_values_the_general_path_accepts_give_its_bytes(field, value):
    pub = horus.Topic(Scalars, "values")
    raw = horus.Topic(Scalars, "values")._core
    msg = Scalars(**{field: value})
    assert pub.send(msg)
    assert raw.try_recv() == msg.to_bytes()


@pytest.mark.parametrize("field, value", [
    ("tiny", 128), ("octet", -1), ("small", 2**15), ("half", 2**16), ("word", 2**31),
    ("uword", -1), ("wide", 2**63), ("ulong", 2**64), ("single", 1e39), ("precise", "1.0"),
    ("word", 1.5), ("ulong", None),
])
def test_values_the_general_path_refuses_raise_its_error_and_send_nothing(field, value):
    pub, sub = pair(Scalars, "refused")
    msg = Scalars(**{field: value})
    with pytest.raises(ValueError) as general:
        msg.to_bytes()
    with pytest.raises(ValueError) as fast:
        pub.send(msg)
    assert str(fast.value) == str(general.value)
    assert sub.try_recv() is None


def test_an_unset_field_raises_the_general_error():
    pub = horus.Topic(CmdVel, "unset")
    msg = CmdVel.__new__(CmdVel)
    msg.linear = 1.0
    with pytest.raises(ValueError, match="stamp_nanos"):
        pub.send(msg)


def test_another_class_is_refused_and_a_subclass_sent_as_its_base():
    class Stamped(CmdVel):
        __slots__ = ()

    pub, sub = pair(CmdVel)
    with pytest.raises(TypeError, match="carries horus.msg.CmdVel, not Pose2D"):
        pub.send(Pose2D())
    assert pub.send(Stamped(linear=2.0, stamp_nanos=5))
    got = sub.try_recv()
    assert type(got) is CmdVel and got == CmdVel(linear=2.0, stamp_nanos=5)


def test_f32_fields_arrive_rounded_as_from_bytes_rounds_them():
    pub, sub = pair(CmdVel)
    pub.send(CmdVel(linear=0.1, angular=-1e-45))
    got = sub.try_recv()
    assert got.linear == numpy.float32(0.1) and got.linear != 0.1
    assert got.angular == CmdVel.from_bytes(CmdVel(angular=-1e-45).to_bytes()).angular


def test_received_messages_are_independent_objects():
    pub, sub = pair(CmdVel)
    pub.send(CmdVel(linear=1.0))
    pub.send(CmdVel(linear=2.0))
    first, second = sub.try_recv(), sub.try_recv()
    first.linear = 9.0
    assert second.linear == 2.0 and first.log_summary().startswith("CmdVel(linear 9")
    assert CmdVel.from_bytes(first.to_bytes()).linear == 9.0


def test_try_recv_view_and_bad_arguments():
    pub, sub = pair(CmdVel)
    pub.send(CmdVel(linear=4.0))
    view = sub.try_recv(view=True)
    assert view.linear == 4.0 and view.to_message() == CmdVel(linear=4.0)
    assert sub.try_recv(view=True) is None
    with pytest.raises(TypeError, match="view"):
        sub.try_recv(True)
    with pytest.raises(TypeError, match="view"):
        sub.try_recv(copy=False)


def test_a_dropped_topic_is_freed_at_once():
    import weakref

    topic = horus.Topic(CmdVel, "dropped")
    alive = weakref.ref(topic)
    del topic  # no reference cycle through the C path: freed without the garbage collector
    assert alive() is None


def test_a_bool_whose_truth_sends_on_the_same_topic_does_not_mix_the_two_messages():
    pub = horus.Topic(Scalars, "reentrant")
    raw = horus.Topic(Scalars, "reentrant")._core
    inner = Scalars(word=2, precise=2.0)

    class Truth:
        def __bool__(self):
            pub.send(inner)
            return True

    assert pub.send(Scalars(word=1, precise=1.0, last=Truth()))  # `last` is the final field
    assert raw.try_recv() == inner.to_bytes()
    assert raw.try_recv() == Scalars(word=1, precise=1.0, last=True).to_bytes()


def test_a_message_with_many_fields_round_trips():
    pub, sub = pair(ManyScalars)
    msg = ManyScalars(**{f"v{i}": (-i if i % 2 else i / 4) for i in range(20)})
    assert pub.send(msg)
    got = sub.try_recv()
    assert type(got) is ManyScalars and got == msg
    assert got.to_bytes() == msg.to_bytes()


def test_a_subclass_that_keeps_its_fields_otherwise_takes_the_general_path():
    class Scaled(CmdVel):
        linear = property(lambda self: 2.0, lambda self, value: None)  # not the slot

    class Counted(CmdVel):
        __slots__ = ()

        def __new__(cls, *args, **kwargs):
            return super().__new__(cls)

    for cls in (Scaled, Counted):
        pub, sub = pair(cls, cls.__name__)
        assert type(pub.send).__name__ == "method"
        assert pub.send(cls()) and type(sub.try_recv()) is cls
    assert horus.Topic(CmdVel, "Scaled").read_latest().linear == 2.0
