"""horus.Topic: typed, dict, loans, views, type mismatches, and C++ <-> Python across processes."""
from __future__ import annotations

import signal
import threading
import time

import pytest

import horus
from horus.msg import CmdVel, CompressedImage

from .conftest import python_child


def test_typed_send_try_recv_and_read_latest():
    pub = horus.Topic(CmdVel, "cmd_vel")
    sub = horus.Topic(CmdVel, "cmd_vel")
    assert sub.try_recv() is None
    assert pub.send(CmdVel(linear=1.5, angular=-0.5))
    assert pub.send(CmdVel(linear=2.5, angular=0.25))
    assert sub.has_msg()
    assert sub.try_recv() == CmdVel(linear=1.5, angular=-0.5)
    assert sub.try_recv() == CmdVel(linear=2.5, angular=0.25)
    assert sub.try_recv() is None
    assert horus.Topic(CmdVel, "cmd_vel").read_latest() == CmdVel(linear=2.5, angular=0.25)


def test_dict_topic_carries_plain_values():
    pub = horus.Topic(dict, "scan")
    sub = horus.Topic(dict, "scan")
    pub.send({"ranges": [1.0, 2.0], "ok": True, "name": "front"})
    pub.send(42)
    assert sub.try_recv() == {"ranges": [1.0, 2.0], "ok": True, "name": "front"}
    assert sub.try_recv() == 42


def test_typed_topic_rejects_another_message_class():
    topic = horus.Topic(CmdVel, "cmd_vel")
    with pytest.raises(TypeError, match="carries horus.msg.CmdVel"):
        topic.send({"linear": 1.0})


def test_type_mismatch_names_both_types_and_fingerprints_and_spares_the_incumbent():
    incumbent = horus.Topic(CmdVel, "shared")
    with pytest.raises(horus.HorusError) as raised:
        horus.Topic(dict, "shared")
    text = str(raised.value)
    assert "horus.msg.CmdVel (fingerprint 0x02b05801f27d1254)" in text
    assert "horus.msg.GenericMessage (fingerprint 0xed5005423d4f05b2)" in text
    reader = horus.Topic(CmdVel, "shared")
    assert incumbent.send(CmdVel(linear=3.0))
    assert reader.try_recv().linear == 3.0


def test_not_a_message_class_is_a_type_error():
    with pytest.raises(TypeError, match="generated message class, a plain value type"):
        horus.Topic(complex, "x")


def test_recv_times_out_with_none_and_releases_the_gil():
    sub = horus.Topic(CmdVel, "cmd_vel")
    counted = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            counted.append(1)
            time.sleep(0.001)

    worker = threading.Thread(target=count)
    worker.start()
    try:
        assert sub.recv(timeout=0.3) is None
    finally:
        stop.set()
        worker.join()
    # The thread ran while recv() waited: the GIL was not held.
    assert len(counted) > 10


def test_recv_wakes_for_a_message_from_another_thread():
    sub = horus.Topic(CmdVel, "cmd_vel")
    sender = threading.Timer(0.05, lambda: horus.Topic(CmdVel, "cmd_vel").send(CmdVel(linear=7.0)))
    sender.start()
    msg = sub.recv(timeout=10.0)
    sender.join()
    assert msg is not None and msg.linear == 7.0


def test_recv_rejects_a_negative_timeout():
    with pytest.raises(ValueError, match="timeout"):
        horus.Topic(CmdVel, "cmd_vel").recv(timeout=-1.0)


def test_lost_counts_messages_overwritten_before_they_were_read():
    pub = horus.Topic(CmdVel, "fast", capacity=4)
    sub = horus.Topic(CmdVel, "fast")
    for i in range(10):
        pub.send(CmdVel(linear=float(i)))
    received = []
    while (msg := sub.try_recv()) is not None:
        received.append(msg.linear)
    assert received == [6.0, 7.0, 8.0, 9.0]
    assert sub.lost() == 6


def test_loan_writes_in_place_and_publish_sends_it():
    pub = horus.Topic(CmdVel, "cmd_vel")
    sub = horus.Topic(CmdVel, "cmd_vel")
    slot = pub.loan()
    slot.stamp_nanos = 11
    slot.linear = 0.5
    slot.angular = 0.25
    assert pub.publish(slot)
    assert sub.try_recv() == CmdVel(stamp_nanos=11, linear=0.5, angular=0.25)
    with pytest.raises((ValueError, TypeError)):
        slot.linear = 1.0  # the view's buffer was released with the slot
    with pytest.raises(ValueError, match="last loan"):
        pub.publish(slot)


def test_an_unpublished_loan_sends_nothing():
    pub = horus.Topic(CmdVel, "cmd_vel")
    sub = horus.Topic(CmdVel, "cmd_vel")
    pub.loan().linear = 9.0
    second = pub.loan()  # the first loan is released unpublished
    second.assign(CmdVel(linear=2.0))
    assert pub.publish(second)
    assert sub.try_recv().linear == 2.0
    assert sub.try_recv() is None


def test_loan_needs_a_pod_type():
    with pytest.raises(TypeError, match="only POD"):
        horus.Topic(CompressedImage, "image").loan()


def test_view_reads_the_message_without_building_it():
    pub = horus.Topic(CmdVel, "cmd_vel")
    sub = horus.Topic(CmdVel, "cmd_vel")
    pub.send(CmdVel(linear=4.0, angular=2.0))
    view = sub.try_recv(view=True)
    assert (view.linear, view.angular) == (4.0, 2.0)
    assert view.to_message() == CmdVel(linear=4.0, angular=2.0)


def _values(proc, count):
    got = [float(proc.stdout.readline()) for _ in range(count)]
    assert proc.wait(timeout=30) == 0, proc.stderr.read()
    return got


@pytest.mark.parametrize("kind", ["cmdvel", "image", "dict"])
def test_cpp_publisher_python_subscriber(peer, kind):
    msg_type = {"cmdvel": CmdVel, "image": CompressedImage, "dict": dict}[kind]
    sub = horus.Topic(msg_type, "xlang")
    proc = peer("pub", kind, "xlang", "20")
    got = []
    while len(got) < 20:
        msg = sub.recv(timeout=10.0)
        assert msg is not None, f"only {got} arrived"
        got.append(msg)
    assert proc.wait(timeout=30) == 0, proc.stderr.read()
    if kind == "cmdvel":
        assert [(m.linear, m.angular) for m in got] == [(i, -i) for i in range(1, 21)]
    elif kind == "image":
        assert [(m.format, m.width, m.data) for m in got] == [
            ("png", i, b"\xab" * i) for i in range(1, 21)]
    else:
        assert got == [{"linear": float(i)} for i in range(1, 21)]


@pytest.mark.parametrize("kind", ["cmdvel", "image", "dict"])
def test_python_publisher_cpp_subscriber(peer, kind):
    proc = peer("sub", kind, "xlang", "20")
    assert proc.stdout.readline().strip() == "ready"
    if kind == "cmdvel":
        pub = horus.Topic(CmdVel, "xlang")
        messages = [CmdVel(linear=float(i)) for i in range(1, 21)]
    elif kind == "image":
        pub = horus.Topic(CompressedImage, "xlang")
        messages = [CompressedImage(format="png", width=i, height=1, data=b"x" * i)
                    for i in range(1, 21)]
    else:
        pub = horus.Topic(dict, "xlang")
        messages = [{"linear": float(i)} for i in range(1, 21)]
    for msg in messages:
        assert pub.send(msg)
        time.sleep(0.001)
    assert _values(proc, 20) == [float(i) for i in range(1, 21)]


def test_python_to_python_across_processes():
    sub = horus.Topic(dict, "py2py")
    child = python_child(
        "import horus, time\n"
        "t = horus.Topic(dict, 'py2py')\n"
        "for i in range(5):\n"
        "    t.send({'i': i}); time.sleep(0.002)\n")
    got = [sub.recv(timeout=10.0) for _ in range(5)]
    assert child.wait(timeout=30) == 0, child.stderr.read()
    assert got == [{"i": i} for i in range(5)]


def test_python_publisher_killed_mid_stream_leaves_the_topic_usable(peer):
    sub = horus.Topic(CmdVel, "killed")
    child = python_child(
        "import horus, itertools\n"
        "from horus.msg import CmdVel\n"
        "t = horus.Topic(CmdVel, 'killed')\n"
        "print('sending', flush=True)\n"
        "for i in itertools.count(1):\n"
        "    t.send(CmdVel(linear=float(i)))\n")
    assert child.stdout.readline().strip() == "sending"
    assert sub.recv(timeout=10.0) is not None
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    while sub.try_recv() is not None:
        pass
    # A new publisher in another language, and this one, both get through.
    proc = peer("sub", "cmdvel", "killed", "3")
    assert proc.stdout.readline().strip() == "ready"
    pub = horus.Topic(CmdVel, "killed")
    for i in (101, 102, 103):
        assert pub.send(CmdVel(linear=float(i)))
    assert _values(proc, 3) == [101.0, 102.0, 103.0]
    assert [sub.try_recv().linear for _ in range(3)] == [101.0, 102.0, 103.0]


def test_a_topic_name_that_is_not_a_path_component_is_refused():
    with pytest.raises(horus.HorusError, match="bad/name"):
        horus.Topic(CmdVel, "bad/name")
