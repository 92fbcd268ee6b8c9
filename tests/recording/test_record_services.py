"""Service traffic in recordings (a C++ server called by a Python client while horus-record
records every topic: info, export, replay, and `horus topic echo` of the service topics), every
type the runtime defines itself decoding from its stored schema, a refused replay leaving nothing
in the namespace, and 64-bit integers in the Foxglove export."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

import horus
from horus import mcap as horus_mcap
from horus import typedesc
from horus import Node, Scheduler
from horus.msg import CmdVel, LaserScan

from processes import wait_until
from test_record import cmd_vels, export_validated, run_horus, write_recording

SERVICE_PEER = os.environ.get("HORUS_PY_SERVICE_PEER", "")
RUNTIME_TYPES = os.environ.get("HORUS_RUNTIME_TYPES", "")


@pytest.fixture
def pyrt_test():
    """The generated Python package of the C++ service peer's services (pyrt_test.Add, Echo)."""
    folder = os.environ.get("HORUS_PYRT_TEST_PYTHON", "")
    assert folder and os.path.isdir(folder), "HORUS_PYRT_TEST_PYTHON: run through ctest (pytest_record)"
    sys.path.insert(0, folder)
    try:
        import pyrt_test as package
    finally:
        sys.path.remove(folder)
    return package


def fnv1a(text: str) -> int:
    """The hash the runtime gives the identities it spells itself (horus/plain_value.hpp)."""
    value = 0xCBF29CE484222325
    for byte in text.encode():
        value = ((value ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return value


def runtime_types() -> list[dict]:
    assert RUNTIME_TYPES, "HORUS_RUNTIME_TYPES: run through ctest (pytest_record)"
    out = subprocess.run([RUNTIME_TYPES], capture_output=True, text=True, check=True, timeout=30)
    return [json.loads(line) for line in out.stdout.splitlines()]


def test_every_runtime_defined_type_decodes_from_its_stored_schema_with_its_fingerprint(pyrt_test):
    types = runtime_types()
    names = [t["name"] for t in types]
    assert names[:5] == ["horus.ServiceRegistration", "horus.ServiceRequest<pyrt_test.AddRequest>",
                         "horus.ServiceResponse<pyrt_test.AddResponse>",
                         "horus.ServiceRequest<pyrt_test.EchoRequest>",
                         "horus.ServiceResponse<pyrt_test.EchoResponse>"]
    assert {"bool", "u64", "i64", "f64", "[f32; 3]", "[[u8; 4]; 2]"} <= set(names)
    decoded = {}
    for described in types:
        fingerprint = int(described["fingerprint"], 16)
        assert fnv1a(described["schema"]) == fingerprint, described
        cls = typedesc.load_type(described["name"], described["schema"], fingerprint)
        assert bool(cls.__horus__.is_pod) == described["pod"], described["name"]
        if described["pod"]:
            assert cls.__horus__.size == described["size"], described["name"]
            data = bytes.fromhex(described["bytes"])
            message = cls.from_bytes(data)
            assert message.to_bytes() == data, described["name"]
            decoded[described["name"]] = typedesc.to_plain(message)
        else:
            assert type(cls.from_bytes(cls().to_bytes())) is cls
    assert decoded["horus.ServiceRegistration"] == {
        "server_instance": 2**60 + 1, "fingerprint": pyrt_test.Add.fingerprint,
        "request_type": "pyrt_test.AddRequest", "response_type": "pyrt_test.AddResponse",
        "server_pid": 4242}
    assert decoded["horus.ServiceRequest<pyrt_test.AddRequest>"] == {
        "client_id": 7, "request_id": 8, "reply_to": 1, "payload": {"a": -4, "b": 5}}
    assert decoded["horus.ServiceResponse<pyrt_test.AddResponse>"] == {
        "client_id": 7, "request_id": 8, "status": 1, "error": "negative a: -4",
        "payload": {"sum": 0}}
    assert decoded["u64"] == {"value": 2**63 + 1}
    assert decoded["[[u8; 4]; 2]"] == {"value": [[1, 2, 3, 4], [5, 6, 7, 8]]}
    # The Python runtime spells the frames as the C++ one does.
    from horus.introspection import ServiceFrame
    by_name = {t["name"]: t for t in types}
    for payload, response in ((pyrt_test.AddRequest, False), (pyrt_test.AddResponse, True),
                              (pyrt_test.EchoRequest, False), (pyrt_test.EchoResponse, True)):
        frame = ServiceFrame(payload, response=response)
        assert (frame.schema, f"{frame.fingerprint:016x}") == (
            by_name[frame.name]["schema"], by_name[frame.name]["fingerprint"])


def start_recording(out) -> subprocess.Popen:
    return subprocess.Popen([os.environ["HORUS_CLI"], "record", "-a", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def subscribed(topic: str) -> bool:
    return any(t["name"] == topic and t["subscribers"] for t in horus._core.list_topics(""))


def echo(topic: str) -> dict:
    shown = run_horus("topic", "echo", topic, "--once", "--json", "--timeout", "10")
    assert shown.returncode == 0, f"echo {topic}: {shown.stderr}"
    return json.loads(shown.stdout)


def test_a_recorded_service_session_is_echoed_exported_and_replayed(tmp_path, children, pyrt_test):
    assert SERVICE_PEER, "HORUS_PY_SERVICE_PEER: run through ctest (pytest_record)"
    from horus._core import ServiceRegistrationTopic
    out = tmp_path / "calls.mcap"
    recorder = start_recording(out)
    # Every topic is there and recorded before the server registers and the calls begin.
    commands = horus.Topic(CmdVel, "cmd")
    for service in (pyrt_test.Add, pyrt_test.Echo):
        ServiceRegistrationTopic(service.name)  # the segment stays when the handle goes
    add, echoes = horus.ServiceClient(pyrt_test.Add), horus.ServiceClient(pyrt_test.Echo)
    for topic in ("Add.request", "Add.response.0", "Add.service", "Echo.request", "Echo.response.0",
                  "Echo.service", "cmd"):
        wait_until(lambda: subscribed(topic), f"horus-record to subscribe to {topic}", limit=30)
    server = children.program(SERVICE_PEER, "serve")
    assert server.stdout.readline().strip() == "serving"
    for i in range(5):
        assert add.call(pyrt_test.AddRequest(a=i, b=2**40), timeout=10.0).sum == i + 2**40
        assert echoes.call(pyrt_test.EchoRequest(text="ab", repeat=i + 1), timeout=10.0).text == \
            "ab" * (i + 1)
        assert commands.send(CmdVel(linear=float(i)))
    with pytest.raises(horus.ServiceFailed, match="negative a: -1"):
        add.call(pyrt_test.AddRequest(a=-1, b=0), timeout=10.0)

    # Each service topic echoes (its latest message), POD and serialized.
    registration = echo("Add.service")
    assert registration["server_pid"] == server.pid
    assert registration["request_type"] == "pyrt_test.AddRequest"
    assert echo("Add.request")["payload"] == {"a": -1, "b": 0}
    failed = echo("Add.response.0")
    assert (failed["status"], failed["error"]) == (1, "negative a: -1")
    assert echo("Echo.request")["payload"] == {"text": "ab", "repeat": 5}
    assert echo("Echo.response.0")["payload"] == {"text": "ababababab"}

    wait_until(lambda: sum(t["message_count"] for t in horus._core.list_topics("")
                           if t["name"] == "Add.request") == 6, "the six Add requests")
    recorder.send_signal(signal.SIGINT)
    _, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr
    server.communicate(timeout=30)  # closes its stdin: it stops serving
    assert server.returncode == 0

    described = json.loads(run_horus("record", "info", str(out), "--json").stdout)
    counts = {t["topic"]: t["messages"] for t in described["topics"]}
    assert counts["Add.request"] == 6 and counts["Add.response.0"] == 6
    assert counts["Echo.request"] == 5 and counts["cmd"] == 5 and counts["Add.service"] >= 1

    # The export decodes every service topic; 64-bit integers are strings of their digits.
    exported = {}
    for topic, schema_name, value in export_validated(out, tmp_path / "calls_foxglove.mcap"):
        exported.setdefault(topic, []).append((schema_name, value))
    assert {"Add.request", "Add.response.0", "Add.service", "Echo.request", "Echo.response.0",
            "cmd"} <= set(exported)
    assert [v["payload"] for _, v in exported["Add.request"]] == [
        {"a": str(i), "b": str(2**40)} for i in range(5)] + [{"a": "-1", "b": "0"}]
    assert [v["payload"]["sum"] for _, v in exported["Add.response.0"]][:5] == [
        str(i + 2**40) for i in range(5)]
    assert exported["Add.request"][0][0] == "horus.ServiceRequest<pyrt_test.AddRequest>"
    assert exported["Add.service"][0][1]["server_pid"] == str(server.pid)
    assert [v["payload"]["text"] for _, v in exported["Echo.response.0"]] == [
        "ab" * (i + 1) for i in range(5)]

    # A replay leaves the service topics out (a live server would answer the requests again)
    # and says so; named, they replay as what they were.
    requests_before = next(t["message_count"] for t in horus._core.list_topics("")
                           if t["name"] == "Add.request")
    replayed = run_horus("record", "replay", str(out), "--rate", "50")
    assert replayed.returncode == 0, replayed.stderr
    assert "replayed 5 messages on 1 topics" in replayed.stdout
    assert "left out the service topics Add.request, Add.response.0, Add.service" in replayed.stderr
    assert next(t["message_count"] for t in horus._core.list_topics("")
                if t["name"] == "Add.request") == requests_before
    named = run_horus("record", "replay", str(out), "--topics", "Add.request,Echo.response.0",
                      "--rate", "50")
    assert named.returncode == 0, named.stderr
    assert "replayed 11 messages on 2 topics" in named.stdout
    assert echo("Add.request")["payload"] == {"a": -1, "b": 0}


def test_a_refused_replay_leaves_no_topic_behind(tmp_path, namespace):
    # `cmd` replays; demo.Thing's stored schema gives another fingerprint than its channel's,
    # which is found only once the type is compiled.
    path = tmp_path / "bad.mcap"
    thing = "message demo.Thing {\n  x: u32,\n}\n"
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream)
        meta = CmdVel.__horus__
        cmd = writer.add_channel("cmd", "horus.pod",
                                 writer.add_schema(meta.name, "horus.hmsg", meta.schema.encode()),
                                 {"horus.fingerprint": f"{meta.fingerprint:016x}",
                                  "horus.type": meta.name, "horus.payload_size": str(meta.size)})
        bad = writer.add_channel("thing", "horus.pod",
                                 writer.add_schema("demo.Thing", "horus.hmsg", thing.encode()),
                                 {"horus.fingerprint": "00000000000000ab", "horus.type": "demo.Thing",
                                  "horus.payload_size": "4"})
        writer.add_message(cmd, 1, CmdVel(linear=1.0).to_bytes())
        writer.add_message(bad, 2, b"\x01\x00\x00\x00")
        writer.finish()
    refused = run_horus("record", "replay", str(path))
    assert refused.returncode == 1
    assert "the stored schema of demo.Thing gives fingerprint" in refused.stderr
    assert [t["name"] for t in horus._core.list_topics(namespace)] == []


def test_deterministic_replay_feeds_the_nodes_but_no_service_topic(tmp_path, namespace):
    # The replaying process's nodes make their calls again: recorded requests would be answered
    # twice, a recorded registration would announce a server that is not there.
    types = {t["name"]: t for t in runtime_types()}
    path = tmp_path / "services.mcap"
    with open(path, "wb") as stream:
        writer = horus_mcap.Writer(stream)
        channels = {}
        for topic, name in (("Add.request", "horus.ServiceRequest<pyrt_test.AddRequest>"),
                            ("Add.service", "horus.ServiceRegistration")):
            described = types[name]
            channels[topic] = writer.add_channel(
                topic, "horus.pod", writer.add_schema(name, "horus.hmsg", described["schema"].encode()),
                {"horus.fingerprint": described["fingerprint"], "horus.type": name,
                 "horus.payload_size": str(described["size"])})
            writer.add_message(channels[topic], 1, bytes.fromhex(described["bytes"]))
        meta = CmdVel.__horus__
        cmd = writer.add_channel("cmd", "horus.pod",
                                 writer.add_schema(meta.name, "horus.hmsg", meta.schema.encode()),
                                 {"horus.fingerprint": f"{meta.fingerprint:016x}",
                                  "horus.type": meta.name, "horus.payload_size": str(meta.size)})
        for index, message in enumerate(cmd_vels(3)):
            writer.add_message(cmd, 2 + index, message.to_bytes(), sequence=index)
        writer.finish()
    received = []
    scheduler = Scheduler(tick_rate=100, deterministic=True, replay=str(path))
    scheduler.add(Node(name="motor", order=0, subs={"cmd": CmdVel},
                       tick=lambda node: received.extend(iter(lambda: node.recv("cmd"), None))))
    for _ in range(3):
        scheduler.tick_once()
    assert received == cmd_vels(3)
    assert [t["name"] for t in horus._core.list_topics(namespace)
            if t["name"].startswith("Add.")] == []


def test_a_refused_deterministic_replay_leaves_no_topic_behind(tmp_path, namespace):
    path = tmp_path / "changed.mcap"
    write_recording(path, {"cmd": (CmdVel, cmd_vels(3)), "thing": (LaserScan, [LaserScan()])})
    live = horus.Topic(CmdVel, "thing")  # `thing` now carries another type than recorded
    with pytest.raises(horus.HorusError, match="'thing' was recorded as horus.msg.LaserScan"):
        scheduler = Scheduler(tick_rate=100, deterministic=True, replay=str(path))
        scheduler.add(Node(name="idle", order=0, tick=lambda node: None))
        scheduler.tick_once()
    assert [t["name"] for t in horus._core.list_topics(namespace)] == ["thing"]
    assert live.send(CmdVel())


def test_foxglove_export_writes_64_bit_integers_as_strings_its_schema_states(tmp_path):
    stamps = [2**60 + 3, 2**53 + 1, 7]
    path, out = tmp_path / "big.mcap", tmp_path / "big_foxglove.mcap"
    write_recording(path, {"cmd": (CmdVel, [CmdVel(linear=1.0, stamp_nanos=s) for s in stamps])})
    messages = export_validated(path, out)
    assert [value["stamp_nanos"] for _, _, value in messages] == [str(s) for s in stamps]
    from mcap.reader import make_reader
    with open(out, "rb") as stream:
        summary = make_reader(stream).get_summary()
    schema = json.loads(next(iter(summary.schemas.values())).data)
    assert schema["properties"]["stamp_nanos"]["type"] == "string"
    assert schema["properties"]["linear"]["type"] == ["number", "null"]
    # A C++ Topic<std::uint64_t>'s plain value, as the runtime stores its type.
    described = next(t for t in runtime_types() if t["name"] == "u64")
    plain, plain_out = tmp_path / "plain.mcap", tmp_path / "plain_foxglove.mcap"
    with open(plain, "wb") as stream:
        writer = horus_mcap.Writer(stream)
        channel = writer.add_channel(
            "count", "horus.pod", writer.add_schema("u64", "horus.hmsg", described["schema"].encode()),
            {"horus.fingerprint": described["fingerprint"], "horus.type": "u64",
             "horus.payload_size": "8"})
        writer.add_message(channel, 1, bytes.fromhex(described["bytes"]))
        writer.finish()
    assert [(topic, name, value) for topic, name, value in export_validated(plain, plain_out)] == [
        ("count", "u64", {"value": str(2**63 + 1)})]


def test_foxglove_export_writes_the_node_ticks_nanoseconds_as_strings(tmp_path):
    scheduler = horus.Scheduler(tick_rate=100, recording=True)
    scheduler.add(horus.Node(name="idle", tick=lambda node: None, order=0))
    for _ in range(3):
        scheduler.tick_once()
    path = scheduler.stop_recording()[0]
    ticks = [value for topic, _, value in export_validated(path, tmp_path / "ticks_foxglove.mcap")
             if topic == "/horus/ticks"]
    assert len(ticks) == 3
    for tick in ticks:
        assert isinstance(tick["start_ns"], str) and int(tick["start_ns"]) > 2**53
        assert tick["node"] == "idle" and tick["outcome"] == "ok"
