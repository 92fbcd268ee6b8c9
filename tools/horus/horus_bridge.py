"""`horus bridge`: local topics to Cyclone DDS and DDS topics into the local namespace
(docs/dds-bridge.md).

    horus bridge --export 'cmd_*' --import 'odom' [--domain N] [--best-effort] [--depth N]
                 [--transient-local PATTERN] [--deadline PATTERN=MS] [--ros2-types PATTERN]
                 [--export-service PATTERN] [--import-service PATTERN] [--service-timeout S]
                 [--accept-untyped-writers]

A local topic whose name matches an --export pattern is written to the DDS topic `rt/<name>`,
each '.' of the name a '/' (`arm.state` is rt/arm/state, as ROS 2 reads namespaces), in XCDR1 CDR
(dds_cdr) under its DDS type name (`horus-gen describe`'s dds_type, ROS 2's naming); its
writer's user data carries the HORUS identity (type name, fingerprint, schema text), so a bridge
on another host can create the topic without knowing the type beforehand. A DDS publication
`rt/<name>` whose name (each '/' a '.') matches an --import pattern is published into that local
topic: created from that identity, or the existing topic when its type is the same (a plain DDS
program gives no identity: the local topic must exist then). Another type is refused, naming
both; so is a name with no counterpart on the other side (a HORUS '-', a DDS '.'), and a DDS
writer that writes XCDR2 (the bridge's endpoints accept XCDR1 alone, so DDS does not match them).

Each writer and reader of a topic announces the XTypes type information idlc makes of its IDL
(the IDL horus-gen emits, or ROS 2's message for a twin: ros2_idl/), and an importing reader
matches only writers that announce theirs and whose type DDS finds assignable to it: a writer of
another layout under the same type name never delivers a sample. A writer that announces none (a
ROS 2 node's rmw) is refused in one line, or taken on trust under --accept-untyped-writers. Bad
samples that reach a reader all the same are one line per (writer, reason) and then a count
(horus._dds.DropReport, the C++ pumps' and the Python threads'), for at most
HORUS_BRIDGE_DROP_REPORT_CAP (1024) pairs a topic; past them, other writers' are counted.

Nothing crosses that no pattern names. DDS endpoints ignore their own participant, and a topic
named by both directions is refused, so nothing a bridge writes comes back to it. One thread per
bridged topic moves messages: for a POD type a C++ thread of horus._dds (a pump, converting with
the type's dds_cdr.pod_plan), else a Python thread; topics are looked for again every half second.

--transient-local topics are latched (the exporting side sends the newest message when it starts,
its writer keeps the last one for late readers); --deadline topics say each missed deadline on
stderr with a count. --ros2-types topics of a standard type with a ROS 2 twin (ros2_types) cross
as that twin, both ways; a topic it names whose type has none is refused. A pool-backed topic
(Image, DepthImage, PointCloud, Tensor: descriptors of tensor pool blocks) crosses with its
blocks' data (horus._dds.PoolFrames, dds_cdr.PoolCodec); the importing side fills a block of its
own namespace's default pool and publishes the descriptor naming it. An importing reader takes the QoS its writer offers unless a pattern of its
own names the topic.

Failures of a carried topic never end its thread: a DDS write or take that fails, a message that
does not encode or decode, a local topic that refuses a message or fails is one line on stderr
naming the topic, the error and how many failures the topic has had; the operation is retried
after RETRY_S (a failed DDS write with the same message, so nothing is reordered), a message that
cannot be encoded or delivered is dropped. Anything else a thread raises is a bug: one line, and
the bridge exits with status 1 instead of carrying on without that topic. SIGTERM stops the
bridge as Ctrl+C does (status 0).
"""
from __future__ import annotations

import fnmatch
import importlib
import json
import os
import random
import re
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import types

import dds_cdr
import dynamic_types
import ros2_types

PREFIX = "rt/"  # ROS 2's prefix of topic names on DDS
HORUS_NAME = re.compile(r"[A-Za-z0-9_.-]{1,200}")  # what the runtime accepts for a topic's name
XCDR1 = 0  # DDS_DATA_REPRESENTATION_XCDR1, the only CDR the bridge reads and writes
REPRESENTATIONS = {0: "XCDR1", 1: "XML", 2: "XCDR2"}
RESCAN_S = 0.5
RETRY_S = 0.5  # after a failed DDS write or take, or a failing local topic
LOCAL_CAPACITY = 64  # the geometry a topic the bridge creates gets (as `horus topic pub`'s)
LOCAL_MAX_MESSAGE = 16 * 1024
POOL_CAPACITY = 4  # a pool topic the bridge creates: as horus.Topic(Image, ...)'s, each a block held
SERVICE_TIMEOUT_S = 10.0  # how long an exporting bridge waits for its local server, by default
# ROS 2's messages the twins are (ros2_types) as IDL under rmw_cyclonedds's DDS names, for their
# type information.
ROS2_IDL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "ros2_idl")


class BridgeError(Exception):
    """A topic the bridge will not carry (one line, naming the topic and why)."""


# What a carried topic may fail with and be retried: DDS's return codes and HorusError (both
# RuntimeError), a message the codec refuses (ValueError, struct.error), the OS.
RETRIABLE = (RuntimeError, ValueError, OSError)


def _say(text: str) -> None:
    print(text, flush=True)


def _complain(text: str) -> None:
    print(f"horus bridge: {text}", file=sys.stderr, flush=True)


class _Types:
    """Generated classes, DDS type names and XTypes type information of HORUS types, from their
    schema texts."""

    def __init__(self) -> None:
        self._dds_names: dict[tuple[str, str], str] = {}
        self._type_info: dict[tuple[str, str], dict] = {}

    def load(self, type_name: str, schema: str, fingerprint: int):
        try:
            return dynamic_types.load_type(type_name, schema, fingerprint)
        except dynamic_types.SchemaError as error:
            raise BridgeError(str(error)) from None

    def dds_name(self, type_name: str, schema: str) -> str:
        key = (type_name, schema)
        if key not in self._dds_names:
            with tempfile.TemporaryDirectory(prefix="horus-bridge-") as folder:
                files = dynamic_types.write_schema_files(dynamic_types.parse_schema(schema), folder)
                try:
                    described = dynamic_types.run_generator(
                        ["describe", "--json", "-I", folder, *files],
                        f"the stored schema of {type_name} does not compile")
                except dynamic_types.SchemaError as error:
                    raise BridgeError(str(error)) from None
            for entry in json.loads(described)["types"]:
                if entry["name"] == type_name:
                    self._dds_names[key] = entry["dds_type"]
                    break
            else:
                raise BridgeError(f"horus-gen does not describe {type_name}")
        return self._dds_names[key]

    def type_info(self, type_name: str, schema: str) -> dict:
        """The serialized XTypes TypeInformation and TypeMapping of the type's IDL (`horus-gen
        --lang idl`), as idlc puts them in a topic descriptor: horus._dds.Writer's and Reader's
        type_info and type_map, so that DDS matches the bridge only with writers and readers of
        an assignable type."""
        key = (type_name, schema)
        if key not in self._type_info:
            dds_type = self.dds_name(type_name, schema)
            with tempfile.TemporaryDirectory(prefix="horus-bridge-") as folder:
                files = dynamic_types.write_schema_files(dynamic_types.parse_schema(schema), folder)
                out = os.path.join(folder, "out")
                try:
                    dynamic_types.run_generator(
                        ["generate", "--lang", "idl", "--out", out, "-I", folder, *files],
                        f"the stored schema of {type_name} does not compile to IDL")
                except dynamic_types.SchemaError as error:
                    raise BridgeError(str(error)) from None
                self._type_info[key] = _idlc_type_info(os.path.join(out, "idl"), dds_type,
                                                       folder)
        return self._type_info[key]

    def twin_type_info(self, twin: ros2_types.Twin) -> dict:
        """type_info's of a ROS 2 twin, from ROS 2's message as IDL (ROS2_IDL)."""
        key = (twin.ros2, "")
        if key not in self._type_info:
            with tempfile.TemporaryDirectory(prefix="horus-bridge-") as folder:
                self._type_info[key] = _idlc_type_info(ROS2_IDL, twin.dds_type, folder)
        return self._type_info[key]


def _idlc_type_info(idl_root: str, dds_type: str, output: str) -> dict:
    """type_info and type_map of `dds_type` (horus::msg::dds_::CmdVel_), from the C idlc makes
    (in `output`) of its IDL file under `idl_root` (horus/msg/CmdVel.idl)."""
    *modules, name = [part for part in dds_type.split("::") if part != "dds_"]
    idl = os.path.join(idl_root, *modules, name[:-1] + ".idl")
    try:
        result = subprocess.run(["idlc", "-I", idl_root, "-o", output, idl], capture_output=True,
                                text=True)
    except OSError as error:
        raise BridgeError(f"cannot run idlc (Cyclone DDS's IDL compiler, Debian's "
                          f"cyclonedds-tools), which gives the bridge the XTypes type information "
                          f"of {dds_type}: {error.strerror}") from None
    if result.returncode != 0:
        first = (result.stderr.strip().splitlines() or ["(no message)"])[0]
        raise BridgeError(f"idlc refuses the IDL of {dds_type}: {first}")
    with open(os.path.join(output, name[:-1] + ".c"), encoding="utf-8") as handle:
        text = handle.read()
    mangled = dds_type.replace("::", "_")
    found = {}
    for key, macro in (("type_info", "TYPE_INFO_CDR_"), ("type_map", "TYPE_MAP_CDR_")):
        match = re.search(
            rf"#define {macro}{re.escape(mangled)} \(unsigned char \[\]\)\{{(.*?)\}}", text, re.S)
        if match is None:
            raise BridgeError(f"idlc gave no {macro}{mangled} for {dds_type}")
        found[key] = bytes(int(byte, 16) for byte in re.findall(r"0x([0-9a-f]{2})", match[1]))
    return found


def drop_report_cap(default: int) -> int:
    """How many (writer, reason) pairs, and writers' GUIDs, an imported topic's report of dropped
    samples keeps (horus._dds.DropReport): HORUS_BRIDGE_DROP_REPORT_CAP, else `default`."""
    given = os.environ.get("HORUS_BRIDGE_DROP_REPORT_CAP")
    if given is None:
        return default
    if not re.fullmatch(r"[0-9]+", given) or int(given) < 1:
        raise BridgeError(f"HORUS_BRIDGE_DROP_REPORT_CAP wants a whole number, at least 1, not "
                          f"{given!r}")
    return int(given)


def dds_topic_name(name: str) -> str:
    """The DDS topic of local topic `name`: DDS and ROS 2 names have no '.', and '/' is ROS 2's
    namespace separator, so `arm.state` is rt/arm/state."""
    if "-" in name:
        raise BridgeError("DDS topic names cannot hold its '-' (DDS and ROS 2 allow letters, "
                          "digits, '_' and '/' only, and '_' and '/' already stand for HORUS's "
                          "'_' and '.')")
    return PREFIX + name.replace(".", "/")


def horus_topic_name(dds_name: str) -> str:
    """The local topic of DDS topic `dds_name` (rt/...): rt/arm/state is `arm.state`."""
    rest = dds_name[len(PREFIX):]
    if "." in rest:
        raise BridgeError(f"its '.' makes it ambiguous: {dds_name} and "
                          f"{PREFIX}{rest.replace('.', '/')} would both be the local topic "
                          f"'{rest.replace('/', '.')}'")
    name = rest.replace("/", ".")
    if not HORUS_NAME.fullmatch(name) or name in (".", ".."):
        raise BridgeError(f"it would be the local topic '{name}', and a HORUS name is 1 to 200 of "
                          "[A-Za-z0-9_.-] (and not . or ..)")
    return name


def _identity(topic: dict) -> bytes:
    return json.dumps({"type": topic["type_name"], "fingerprint": f"{topic['fingerprint']:016x}",
                       "schema": topic["schema"]}).encode()


def _local_topic(name: str, type_name: str, fingerprint: int, schema: str, capacity: int,
                 max_message_size: int, single_publisher: bool) -> dict:
    """The local topic a carried topic's thread opens (horus._core.Topic's arguments)."""
    return {"name": name, "type_name": type_name, "fingerprint": fingerprint, "schema": schema,
            "capacity": capacity, "max_message_size": max_message_size,
            "single_publisher": single_publisher}


class _MessageCarrier:
    """A topic's messages between their local bytes and CDR: the type's own, or its twin's."""

    def __init__(self, cls, codec) -> None:
        self.cls, self.codec = cls, codec

    def to_dds(self, data: bytes) -> bytes:
        return self.codec.encode(self.cls.from_bytes(data))

    def to_local(self, cdr: bytes) -> bytes:
        return self.codec.decode(cdr).to_bytes()


class _PoolCarrier:
    """A pool-backed topic's descriptors: out with their blocks' data, in as a block of this
    namespace's default pool, filled (`frames`: horus._dds.PoolFrames)."""

    def __init__(self, cls, frames) -> None:
        self.codec, self.frames = dds_cdr.PoolCodec(cls), frames

    def to_dds(self, data: bytes) -> bytes:
        recorded = self.frames.record(data)
        if recorded is None:
            raise ValueError("its pool block was freed or reused before the bridge read it")
        return self.codec.encode(recorded)

    def to_local(self, cdr: bytes) -> bytes:
        descriptor = self.frames.replay(self.codec.decode(cdr))
        if descriptor is None:
            raise ValueError("its data does not fit its descriptor")
        return descriptor


def _carrier(cls, twin, frames):
    """What a Python thread carries a topic with."""
    if frames is not None:
        return _PoolCarrier(cls, frames)
    return _MessageCarrier(cls, ros2_types.TwinCodec(twin, cls) if twin else dds_cdr.CdrCodec(cls))


def _open_local(core, local: dict, cls):
    info = cls.__horus__
    return core.Topic(is_pod=info.is_pod, size=info.size if info.is_pod else 0,
                      alignment=info.alignment if info.is_pod else 1, **local)


class Bridge:
    def __init__(self, core, dds, namespace: str, exports: list[str], imports: list[str],
                 domain: int, reliable: bool, depth: int, service_exports: list[str] = (),
                 service_imports: list[str] = (), latched: list[str] = (),
                 deadlines: list[tuple[str, int]] = (),
                 service_timeout: float = SERVICE_TIMEOUT_S, ros2: list[str] = (),
                 accept_untyped: bool = False) -> None:
        self.core, self.dds, self.namespace = core, dds, namespace
        self.exports, self.imports = exports, imports
        self.qos = {"reliable": reliable, "depth": depth}
        self.latched = list(latched)  # patterns of transient-local topics
        self.ros2 = list(ros2)  # patterns of topics that cross as ROS 2 twins
        # Import from DDS writers that announce no type information (their type unchecked).
        self.accept_untyped = accept_untyped
        self.deadlines = list(deadlines)  # (pattern, milliseconds), the first match counts
        self.watched: dict[str, list] = {}  # topic -> [endpoint, deadline ms, misses said]
        self.domain = domain
        self.participant = dds.Participant(domain)
        self.types = _Types()
        self.stop = threading.Event()
        self.broken: str | None = None  # why a thread died of an unexpected error
        self.failures: dict[str, int] = {}  # per carried topic
        self.drop_cap = drop_report_cap(dds.DropReport.CAP)
        self.threads: list[threading.Thread] = []
        self.pumps: dict[str, object] = {}  # POD topic name -> its horus._dds pump
        self.done: set[str] = set()  # local topic names exported or imported (or refused)
        self.refused: set[str] = set()  # DDS topic names refused (each said once)
        # DDS writers refused or taken on trust, each said once; past drop_cap of them only
        # counted, so a participant that keeps making writers grows neither the bridge nor its log.
        self.writers_said: set[str] = set()
        self.writers_unsaid = 0
        self.services = Services(self, list(service_exports), list(service_imports),
                                 service_timeout)

    @staticmethod
    def _matches(name: str, patterns: list[str]) -> bool:
        return any(fnmatch.fnmatchcase(name, pattern) for pattern in patterns)

    def _claim(self, name: str) -> bool:
        """Whether `name` is new to the bridge (it is not, from now on); a name both directions
        match is refused, once."""
        if name in self.done:
            return False
        self.done.add(name)
        if self._matches(name, self.exports) and self._matches(name, self.imports):
            _complain(f"refusing topic '{name}': it matches both --export and --import (a bridge "
                      "carries a topic one way)")
            return False
        return True

    def _spawn(self, what: str, target, *args) -> None:
        def guarded() -> None:
            try:
                target(*args)
            except Exception as error:  # noqa: BLE001 - a bug: said once, and the bridge stops
                self.broken = f"{what}: {type(error).__name__}: {error}"
                self.stop.set()

        thread = threading.Thread(target=guarded, name=what, daemon=True)
        thread.start()
        self.threads.append(thread)

    def _pump(self, start, endpoint, cls, local: dict, **options) -> None:
        """Carries a POD topic on a C++ thread of horus._dds: `start` is export_pump or
        import_pump, `endpoint` its DDS writer or reader."""
        info = cls.__horus__
        plan = self.dds.CdrPlan(info.name, info.size, dds_cdr.pod_plan(cls))
        local = dict(local, alignment=info.alignment, namespace=self.namespace or "")
        self.pumps[local["name"]] = start(endpoint, plan, local,
                                          f"horus bridge: topic '{local['name']}'", **options)

    def _topic_qos(self, name: str, publication: dict | None = None) -> dict:
        """The DDS QoS of a carried topic: --transient-local and --deadline when they name it,
        else (importing) what the discovered writer offers, so the reader matches it."""
        deadline = next((ms for pattern, ms in self.deadlines
                         if fnmatch.fnmatchcase(name, pattern)), None)
        latched = self._matches(name, self.latched)
        if publication is not None:
            latched = latched or publication["transient_local"]
            deadline = publication["deadline_ms"] if deadline is None else deadline
        return dict(self.qos, transient_local=latched, deadline_ms=deadline or 0)

    def _watch_deadline(self, name: str, endpoint, qos: dict) -> None:
        if qos["deadline_ms"]:
            self.watched[name] = [endpoint, qos["deadline_ms"], 0]

    def _say_missed_deadlines(self) -> None:
        """One line per topic whose deadline passed without a message since the last look."""
        for name, watch in self.watched.items():
            endpoint, milliseconds, said = watch
            missed = endpoint.deadlines_missed()
            if missed > said:
                watch[2] = missed
                _complain(f"topic '{name}': no message within its {milliseconds} ms deadline "
                          f"(missed {missed} times so far)")

    def _failed(self, what: str, error, then: str) -> None:
        """One line for a failure of a carried topic or service, with its running count."""
        count = self.failures[what] = self.failures.get(what, 0) + 1
        _complain(f"{what}: {error} (failure {count} of it); {then}")

    # -- export: local -> DDS ---------------------------------------------------------------------

    def scan_exports(self) -> None:
        for topic in self.core.list_topics(self.namespace):
            name = topic["name"]
            if (not self._matches(name, self.exports) or not topic["type_name"] or topic["error"]
                    or not self._claim(name)):
                continue
            try:
                self._export(topic)
            except (BridgeError, RuntimeError) as error:
                _complain(f"cannot export topic '{name}': {error}")

    def _twin(self, name: str, type_name: str) -> ros2_types.Twin | None:
        """The ROS 2 twin a topic crosses as: --ros2-types names it (and its type has one)."""
        if not self._matches(name, self.ros2):
            return None
        twin = ros2_types.twin_of(type_name)
        if twin is None:
            raise BridgeError(f"--ros2-types names it, but {type_name} has no ROS 2 twin (those "
                              f"with one: {', '.join(t.horus for t in ros2_types.TWINS)})")
        return twin

    def _export(self, topic: dict) -> None:
        name, type_name = topic["name"], topic["type_name"]
        dds_name = dds_topic_name(name)
        cls = self.types.load(type_name, topic["schema"], topic["fingerprint"])
        twin = self._twin(name, type_name)
        dds_type = twin.dds_type if twin else self.types.dds_name(type_name, topic["schema"])
        local = _local_topic(name, type_name, topic["fingerprint"], topic["schema"],
                             topic["capacity"], topic["max_message_size"],
                             topic["single_publisher"])
        qos = self._topic_qos(name)
        typing = (self.types.twin_type_info(twin) if twin
                  else self.types.type_info(type_name, topic["schema"]))
        writer = self.dds.Writer(self.participant, dds_name, dds_type,
                                 user_data=_identity(topic), **typing, **qos)
        frames = self._pool_frames(local)
        if cls.__horus__.is_pod and not twin and frames is None:
            self._pump(self.dds.export_pump, writer, cls, local, latched=qos["transient_local"])
        else:
            self._spawn(f"topic '{name}'", self._pump_export, name,
                        _open_local(self.core, local, cls), _carrier(cls, twin, frames), writer,
                        qos["transient_local"])
        self._watch_deadline(name, writer, qos)
        _say(f"exporting '{name}' ({type_name}) as {dds_name} ({dds_type})")

    def _pool_frames(self, local: dict):
        """horus._dds.PoolFrames of a pool-backed topic (holding as many blocks as its ring has
        slots), None for any other."""
        return self.dds.pool_frames(local["type_name"], local["fingerprint"],
                                    self.namespace or "", local["capacity"])

    def _pump_export(self, name: str, local, carrier, writer, latched: bool) -> None:
        what = f"topic '{name}'"
        # A latched topic's newest message from before this handle, for late joiners on DDS.
        first = local.read_latest() if latched and not local.has_msg() else None
        while not self.stop.is_set():
            if first is not None:
                data, first = first, None
            else:
                try:
                    data = local.recv(0.1)
                except RETRIABLE as error:
                    self._failed(what, f"reading the local topic failed: {error}", "retrying")
                    self.stop.wait(RETRY_S)
                    continue
            if data is None:
                continue
            try:
                cdr = carrier.to_dds(data)
            except RETRIABLE as error:
                self._failed(what, f"a message does not encode as CDR: {error}", "dropped it")
                continue
            while not self.stop.is_set():
                try:
                    writer.write(cdr)
                    break
                except RuntimeError as error:
                    self._failed(what, str(error), "writing the same message again")
                    self.stop.wait(RETRY_S)

    # -- import: DDS -> local ---------------------------------------------------------------------

    def scan_imports(self) -> None:
        for publication in self.participant.publications():
            topic = publication["topic"]
            if (not topic.startswith(PREFIX) or topic in self.refused
                    or not self._matches(topic[len(PREFIX):].replace("/", "."), self.imports)):
                continue
            try:
                name = horus_topic_name(topic)
            except BridgeError as error:
                self.refused.add(topic)
                _complain(f"cannot import DDS topic {topic}: {error}")
                continue
            if (self._refuse_representation(name, publication)
                    or self._refuse_untyped(name, publication) or name in self.done):
                continue
            if self._matches(name, self.exports):
                self._claim(name)  # refused: both directions
                continue
            try:
                ready = self._import(name, publication)
                if ready is not None:
                    reader, cls, local, qos, twin = ready
                    frames = self._pool_frames(local)
                    if cls.__horus__.is_pod and not twin and frames is None:
                        self._pump(self.dds.import_pump, reader, cls, local,
                                   drop_cap=self.drop_cap)
                    else:
                        self._spawn(f"topic '{name}'", self._pump_import, name, reader,
                                    _carrier(cls, twin, frames),
                                    _open_local(self.core, local, cls))
                    self._watch_deadline(name, reader, qos)
            except (BridgeError, RuntimeError) as error:
                self.done.add(name)
                _complain(f"cannot import topic '{name}': {error}")
                continue
            if ready is not None:
                self.done.add(name)
                _say(f"importing {publication['topic']} ({publication['type']}) as '{name}' "
                     f"({cls.__horus__.name})")

    def _refuse_representation(self, name: str, publication: dict) -> bool:
        """Whether the writer of `publication` writes other than XCDR1, said once per writer
        (DDS does not match it with the bridge's reader: its samples never arrive)."""
        representation = publication["data_representation"]
        if representation == XCDR1:
            return False
        encoding = REPRESENTATIONS.get(representation, f"data representation {representation}")
        self._say_writer_once(publication["writer"], lambda: (
            f"cannot import topic '{name}' from DDS writer {publication['writer']}: it writes "
            f"{encoding}, the bridge reads XCDR1 only (DDS does not match them)"))
        return True

    def _say_writer_once(self, writer: str, line) -> None:
        """Says `line()` the first time `writer` is refused or taken on trust; past drop_cap
        writers, says once that further ones are only counted, and counts them."""
        if writer in self.writers_said:
            return
        if len(self.writers_said) < self.drop_cap:
            self.writers_said.add(writer)
            _complain(line())
            return
        self.writers_unsaid += 1
        if self.writers_unsaid == 1:
            _complain(f"{len(self.writers_said)} DDS writers refused or taken on trust were said, "
                      "the most the bridge keeps (HORUS_BRIDGE_DROP_REPORT_CAP): further ones are "
                      "not")

    def _refuse_untyped(self, name: str, publication: dict) -> bool:
        """Whether the writer of `publication` is refused for announcing no XTypes type
        information (DDS matches the bridge's reader only with writers of an assignable type;
        one that announces none cannot be checked), said once per writer; under
        --accept-untyped-writers it is taken on trust, also said once."""
        if publication["typed"]:
            return False
        writer = publication["writer"]
        if self.accept_untyped:
            self._say_writer_once(writer, lambda: (
                f"topic '{name}': DDS writer {writer} announces no type information: taking its "
                f"{publication['type']} on trust (--accept-untyped-writers)"))
        else:
            self._say_writer_once(writer, lambda: (
                f"cannot import topic '{name}' from DDS writer {writer}: it announces no type "
                f"information, so DDS cannot check that its {publication['type']} is the type's "
                "layout (--accept-untyped-writers takes such writers on trust)"))
        return not self.accept_untyped

    def _import(self, name: str, publication: dict):
        """The (reader, class, local topic, QoS, ROS 2 twin or None) of an import; None when the
        type is not known yet (a plain DDS writer, and no local topic of that name)."""
        remote = json.loads(publication["user_data"]) if publication["user_data"] else None
        twins = (ros2_types.twins_of_dds_type(publication["type"])
                 if self._matches(name, self.ros2) else [])
        local = next((t for t in self.core.list_topics(self.namespace)
                      if t["name"] == name and t["type_name"]), None)
        if local is not None:
            if remote is not None and (remote["type"] != local["type_name"]
                                       or int(remote["fingerprint"], 16) != local["fingerprint"]):
                raise BridgeError(
                    f"the local topic has type {local['type_name']} (fingerprint "
                    f"{local['fingerprint']:016x}), DDS carries {remote['type']} (fingerprint "
                    f"{remote['fingerprint']}) as {publication['type']}")
            type_name, fingerprint, schema = (local["type_name"], local["fingerprint"],
                                              local["schema"])
            capacity, max_message = local["capacity"], local["max_message_size"]
        elif remote is not None:
            type_name, fingerprint, schema = (remote["type"], int(remote["fingerprint"], 16),
                                              remote["schema"])
            capacity, max_message = None, LOCAL_MAX_MESSAGE
        elif twins:  # a ROS 2 node's: its first twin (horus.msg, from the Python path)
            meta = getattr(_imported_class(twins[0].horus), "__horus__", None)
            if meta is None:
                raise BridgeError(f"{twins[0].horus}, the twin of {publication['type']}, is not "
                                  "on the Python path (horus.msg)")
            type_name, fingerprint, schema = meta.name, meta.fingerprint, meta.schema
            capacity, max_message = None, LOCAL_MAX_MESSAGE
        else:
            return None
        twin = self._twin(name, type_name)
        dds_type = twin.dds_type if twin else self.types.dds_name(type_name, schema)
        if dds_type != publication["type"]:
            own_twin = ros2_types.twin_of(type_name)
            hint = (f" (its ROS 2 twin: --ros2-types '{name}' carries it)"
                    if own_twin and own_twin.dds_type == publication["type"] else "")
            raise BridgeError(f"the local topic has type {type_name} ({dds_type} on DDS), DDS "
                              f"carries {publication['type']}{hint}")
        cls = self.types.load(type_name, schema, fingerprint)
        if capacity is None:  # the bridge creates the topic
            pool = self.dds.pool_frames(type_name, fingerprint, self.namespace or "", 1)
            capacity = LOCAL_CAPACITY if pool is None else POOL_CAPACITY
        local = _local_topic(name, type_name, fingerprint, schema, capacity, max_message, False)
        qos = self._topic_qos(name, publication)
        typing = (self.types.twin_type_info(twin) if twin
                  else self.types.type_info(type_name, schema))
        reader = self.dds.Reader(self.participant, publication["topic"], dds_type, **typing,
                                 typed_writers_only=not self.accept_untyped, **qos)
        return reader, cls, local, qos, twin

    def _pump_import(self, name: str, reader, carrier, local) -> None:
        what = f"topic '{name}'"
        # The C++ pumps' report (one line per writer and reason, then counts) and GUID lookup.
        drops = self.dds.DropReport(self.drop_cap)
        writers = self.dds.WriterGuids(reader, self.drop_cap)

        def say(line: str) -> None:
            if line:
                _complain(f"{what}: {line}")

        def drop(writer: int, reason: str) -> None:
            count = self.failures[what] = self.failures.get(what, 0) + 1
            say(drops.dropped(writers.find(writer), reason, count, time.monotonic()))

        while not self.stop.is_set():
            say(drops.due(self.failures.get(what, 0), time.monotonic()))
            try:
                received = reader.take(0.1, writers=True)
            except RuntimeError as error:
                self._failed(what, str(error), "retrying")
                self.stop.wait(RETRY_S)
                continue
            for writer, cdr in received:
                try:
                    data = carrier.to_local(cdr)
                except ValueError as error:
                    drop(writer, f"does not decode: {error}")
                    continue
                except RETRIABLE as error:
                    drop(writer, f"cannot be made here: {error}")
                    continue
                try:
                    delivered = local.send(data)
                except RETRIABLE as error:
                    self._failed(what, f"the local topic failed: {error}", "dropped the message")
                    continue
                if not delivered:
                    drop(writer, "was refused by the local topic (no room, or a stalled "
                         "publisher)")
        say(drops.due(self.failures.get(what, 0), float("inf")))

    def run(self) -> int:
        """Carries topics until Ctrl+C or SIGTERM (0), or a thread's unexpected error (1)."""
        previous = signal.signal(signal.SIGTERM, lambda *_: self.stop.set())
        try:
            return self.serve()
        finally:
            signal.signal(signal.SIGTERM, previous)

    def serve(self) -> int:
        """Carries topics until `stop` is set (0), or a thread's unexpected error (1): the
        bridge's loop, on any thread (horus.Network runs it inside a scheduler's process)."""
        services = self.services
        _say(f"bridge on DDS domain {self.domain}: exporting {self.exports or 'nothing'}, "
             f"importing {self.imports or 'nothing'}; services: exporting "
             f"{services.exports or 'nothing'}, importing {services.imports or 'nothing'}")
        try:
            while not self.stop.is_set():
                try:
                    self.scan()
                except RETRIABLE as error:
                    _complain(f"looking for topics failed: {error}; looking again")
                self._check_pumps()
                self._say_missed_deadlines()
                self.stop.wait(RESCAN_S)
        finally:
            self.stop.set()
            for pump in self.pumps.values():
                pump.stop()
            for stop in self.services.carried.values():
                stop.set()
            for proxy in self.services.proxies.values():
                proxy.stop()  # withdraws its registration: local callers get NoServer
            for thread in self.threads:
                thread.join()
        if self.broken is not None:
            _complain(f"stopping: {self.broken}")
            return 1
        return 0

    def _check_pumps(self) -> None:
        for name, pump in self.pumps.items():
            if pump.broken is not None and self.broken is None:
                self.broken = f"topic '{name}': {pump.broken}"
                self.stop.set()

    def scan(self) -> None:
        if self.exports:
            self.scan_exports()
        if self.imports:
            self.scan_imports()
        self.services.scan()


# -- services -------------------------------------------------------------------------------------
#
# A service S crosses as ROS 2's pair of DDS topics: requests on rq/SRequest (type
# <pkg>::dds_::S_Request_), replies on rr/SReply (<pkg>::dds_::S_Response_). As rmw_cyclonedds
# does, each sample starts (after the 4-byte encapsulation) with a request header of two 8-byte
# fields, the caller's id (u64) and the call's sequence number (i64), followed by the message's
# CDR body; a reply repeats its request's header. The raw CDR API gives no sample identity to
# write, so the header is in the data. A call the server side could not answer (HORUS's failure,
# no server, a timeout there) is replied with the sequence number negated and a CDR string
# "<kind>: <text>" (the ServiceError's) instead of the response (a ROS 2 client ignores it, and
# times out); the importing side raises that kind to its caller.

SERVICE_REQUEST, SERVICE_REPLY = "rq/", "rr/"
PROXY_TIMEOUT_S = 30.0  # how long an importing bridge's proxy waits for a reply over DDS
MATCH_WAIT_S = 5.0  # how long a new proxy waits for its request writer to match the server side
_HEADER = struct.Struct("<Qq")


def _with_header(cdr: bytes, caller: int, sequence: int) -> bytes:
    return cdr[:4] + _HEADER.pack(caller, sequence) + cdr[4:]


def _split_header(sample: bytes) -> tuple[int, int, bytes]:
    """(caller, sequence, CDR of the message with its encapsulation header)."""
    if len(sample) < 4 + _HEADER.size:
        raise ValueError(f"a service sample of {len(sample)} bytes has no request header")
    caller, sequence = _HEADER.unpack_from(sample, 4)
    return caller, sequence, sample[:4] + sample[4 + _HEADER.size:]


def _failure_body(text: str) -> bytes:
    data = text.encode()
    return b"\x00\x01\x00\x00" + struct.pack("<I", len(data) + 1) + data + b"\0"


def _failure_text(cdr: bytes) -> str:
    (length,) = struct.unpack_from("<I", cdr, 4)
    return cdr[8:8 + length - 1].decode("utf-8", "replace")


def _service(name: str, request, response, fingerprint: int):
    """What horus.ServiceClient / ServiceServer need of a generated service class."""
    return types.SimpleNamespace(name=name, Request=request, Response=response,
                                 request_topic=f"{name}.request",
                                 response_topic=f"{name}.response", fingerprint=fingerprint)


def _service_identity(service) -> bytes:
    def part(cls):
        meta = cls.__horus__
        return {"type": meta.name, "fingerprint": f"{meta.fingerprint:016x}",
                "schema": meta.schema}

    return json.dumps({"service": service.name, "fingerprint": f"{service.fingerprint:016x}",
                       "request": part(service.Request),
                       "response": part(service.Response)}).encode()


def _imported_class(type_name: str):
    """A generated class by its HORUS name from the Python path (horus.msg, a user package)."""
    package, _, short = type_name.rpartition(".")
    try:
        return getattr(importlib.import_module(package), short)
    except (ImportError, AttributeError):
        return None


class Services:
    """The service half of a bridge: exported services (a local server answers calls from DDS)
    and imported ones (a local proxy server forwards calls to DDS), by pattern."""

    def __init__(self, bridge: "Bridge", exports: list[str], imports: list[str],
                 timeout: float) -> None:
        self.bridge = bridge
        self.exports, self.imports = exports, imports
        self.timeout = timeout  # seconds an exported service's local server has to answer
        self.carried: dict[str, threading.Event] = {}  # service name -> its stop
        self.proxies: dict[str, object] = {}  # imported service name -> its ServiceServer
        self.refused: set[str] = set()

    def scan(self) -> None:
        if self.exports:
            self.scan_exports()
        if self.imports:
            self.scan_imports()

    # -- export: a local server, called from DDS ---------------------------------------------

    def _classes(self, service: dict):
        """(Request, Response) classes of a local service: from its request and reply topics'
        stored schemas, else from the Python path; None while neither gives them."""
        found = {}
        for topic in self.bridge.core.list_topics(self.bridge.namespace):
            name = topic["name"]
            if not topic["type_name"] or topic["error"]:
                continue
            if name == f"{service['name']}.request":
                found.setdefault("request", topic)
            elif name.startswith(f"{service['name']}.response."):
                found.setdefault("response", topic)

        def payload(kind: str, type_name: str):
            topic = found.get(kind)
            if topic is not None:
                text = topic["schema"]
                return self.bridge.types.load(type_name, text[text.find("\n}\n") + 3:], None)
            return _imported_class(type_name)

        request = payload("request", service["request_type"])
        response = payload("response", service["response_type"])
        return None if request is None or response is None else (request, response)

    def _dds_types(self, service) -> tuple[str, str]:
        """ROS 2's type names of the request and response: <pkg>::dds_::S_Request_."""
        names = []
        for cls, suffix in ((service.Request, "Request_"), (service.Response, "Response_")):
            meta = cls.__horus__
            scope = self.bridge.types.dds_name(meta.name, meta.schema).rsplit("::", 1)[0]
            names.append(f"{scope}::{service.name}_{suffix}")
        return names[0], names[1]

    def scan_exports(self) -> None:
        for entry in self.bridge.core.list_services(self.bridge.namespace):
            name = entry["name"]
            if not Bridge._matches(name, self.exports) or name in self.refused:
                continue
            running = self.carried.get(name)
            if running is not None:
                if not entry["servers"]:  # the server left: so does the service, from DDS
                    running.set()
                    del self.carried[name]
                    _say(f"no longer exporting service '{name}' (its server stopped)")
                continue
            if not entry["servers"]:
                continue
            if Bridge._matches(name, self.imports):
                self.refused.add(name)
                _complain(f"refusing service '{name}': it matches both --export-service and "
                          "--import-service")
                continue
            try:
                classes = self._classes(entry)
                if classes is None:
                    continue  # the response type shows with the first reply topic
                self._export(_service(name, *classes, entry["fingerprint"]))
            except (BridgeError, RuntimeError) as error:
                self.refused.add(name)
                _complain(f"cannot export service '{name}': {error}")

    def _export(self, service) -> None:
        from horus._service import ServiceClient

        request_type, response_type = self._dds_types(service)
        dds, participant, qos = self.bridge.dds, self.bridge.participant, self.bridge.qos
        identity = _service_identity(service)
        reader = dds.Reader(participant, f"{SERVICE_REQUEST}{service.name}Request", request_type,
                            **qos)
        writer = dds.Writer(participant, f"{SERVICE_REPLY}{service.name}Reply", response_type,
                            user_data=identity, **qos)
        client = ServiceClient(service)
        stop = self.carried[service.name] = threading.Event()
        self.bridge._spawn(f"service '{service.name}'", self._answer_calls, service, reader,
                           writer, client, stop)
        _say(f"exporting service '{service.name}' as {SERVICE_REQUEST}{service.name}Request "
             f"({request_type}) and {SERVICE_REPLY}{service.name}Reply ({response_type})")

    def _answer_calls(self, service, reader, writer, client, stop) -> None:
        from horus._service import ServiceError

        requests = dds_cdr.CdrCodec(service.Request)
        responses = dds_cdr.CdrCodec(service.Response)
        what = f"service '{service.name}'"
        try:
            while not stop.is_set() and not self.bridge.stop.is_set():
                try:
                    received = reader.take(0.1)
                except RuntimeError as error:
                    self.bridge._failed(what, str(error), "retrying")
                    stop.wait(RETRY_S)
                    continue
                for sample in received:
                    try:
                        caller, sequence, cdr = _split_header(sample)
                        request = requests.decode(cdr)
                    except RETRIABLE as error:
                        self.bridge._failed(what, f"a request does not decode: {error}",
                                            "dropped it")
                        continue
                    try:
                        reply = _with_header(
                            responses.encode(client.call(request, self.timeout)), caller,
                            sequence)
                    except ServiceError as error:
                        reply = _with_header(_failure_body(f"{error.kind}: {error}"), caller,
                                             -sequence)
                    try:
                        writer.write(reply)
                    except RuntimeError as error:
                        self.bridge._failed(what, str(error), "the caller gets no reply")
        finally:
            client.close()

    # -- import: a local proxy server, calling over DDS ---------------------------------------

    def scan_imports(self) -> None:
        offered = {}
        for publication in self.bridge.participant.publications():
            topic = publication["topic"]
            if topic.startswith(SERVICE_REPLY) and topic.endswith("Reply"):
                name = topic[len(SERVICE_REPLY):-len("Reply")]
                if Bridge._matches(name, self.imports) and publication["user_data"]:
                    offered[name] = publication
        for name in [n for n in self.proxies if n not in offered]:
            self.carried.pop(name).set()
            self.proxies.pop(name).stop()  # no server on DDS: local callers get NoServer
            _say(f"no longer importing service '{name}' (no server on DDS)")
        for name, publication in offered.items():
            if name in self.proxies or name in self.refused:
                continue
            if Bridge._matches(name, self.exports):
                self.refused.add(name)
                _complain(f"refusing service '{name}': it matches both --export-service and "
                          "--import-service")
                continue
            try:
                self._import(name, publication)
            except (BridgeError, RuntimeError, ValueError, KeyError) as error:
                self.refused.add(name)
                _complain(f"cannot import service '{name}': {error}")

    def _import(self, name: str, publication: dict) -> None:
        from horus._service import ServiceServer

        remote = json.loads(publication["user_data"])
        request, response = (
            self.bridge.types.load(remote[kind]["type"], remote[kind]["schema"],
                                   int(remote[kind]["fingerprint"], 16))
            for kind in ("request", "response"))
        service = _service(name, request, response, int(remote["fingerprint"], 16))
        request_type, response_type = self._dds_types(service)
        if response_type != publication["type"]:
            raise BridgeError(f"DDS carries its replies as {publication['type']}, its HORUS "
                              f"types make {response_type}")
        dds, participant, qos = self.bridge.dds, self.bridge.participant, self.bridge.qos
        writer = dds.Writer(participant, f"{SERVICE_REQUEST}{name}Request", request_type, **qos)
        reader = dds.Reader(participant, publication["topic"], response_type, **qos)
        stop = threading.Event()
        proxy = _Proxy(service, writer, reader, stop)
        self.proxies[name] = ServiceServer(service, proxy.call, forward_errors=True)
        self.carried[name] = stop
        _say(f"importing service '{name}' from {SERVICE_REPLY}{name}Reply ({response_type})")


class _Proxy:
    """The handler of an imported service's local server: each call goes to DDS as a request
    with this proxy's id and the next sequence number, and waits for the reply repeating them.
    A failure reply is raised as the ServiceError of its kind, which the local server (with
    forward_errors) hands the caller as that kind: NoServer, Timeout, Transport as they were on
    the server's host, a handler's failure as ServiceFailed. When the exporting side's request
    reader goes (its server left, so it withdrew the service) a call waiting for it gets NoServer
    at once, as it would from that side a moment earlier."""

    def __init__(self, service, writer, reader, stop: threading.Event) -> None:
        self.service, self.writer, self.reader, self.stop = service, writer, reader, stop
        self.requests = dds_cdr.CdrCodec(service.Request)
        self.responses = dds_cdr.CdrCodec(service.Response)
        self.caller = random.getrandbits(64)
        self.sequence = 0
        self.server_seen = False  # whether the exporting side's request reader ever matched

    def _wait_for_server(self) -> bool:
        """Whether the exporting side's request reader matches the request writer, waiting for
        it a moment after the proxy started (a request written before would be lost)."""
        deadline = time.monotonic() + (0 if self.server_seen else MATCH_WAIT_S)
        while not self.writer.matched():
            if self.server_seen or time.monotonic() >= deadline or self.stop.is_set():
                return False
            time.sleep(0.01)
        self.server_seen = True
        return True

    def call(self, request):
        from horus import NoServerError, ServiceTimeout, TransportError

        left = NoServerError(f"the server of {self.service.name} left the DDS side")
        if not self._wait_for_server():
            raise left
        self.sequence += 1
        try:
            self.writer.write(_with_header(self.requests.encode(request), self.caller,
                                           self.sequence))
        except RuntimeError as error:
            raise TransportError(f"the request did not go out on DDS: {error}") from None
        deadline = time.monotonic() + PROXY_TIMEOUT_S
        while not self.stop.is_set() and time.monotonic() < deadline:
            if not self.writer.matched():
                raise left
            for sample in self.reader.take(0.05):
                caller, sequence, cdr = _split_header(sample)
                if caller != self.caller or abs(sequence) != self.sequence:
                    continue  # another caller's reply, or a late one to a call that timed out
                if sequence < 0:
                    raise _remote_error(_failure_text(cdr))
                return self.responses.decode(cdr)
        raise ServiceTimeout(f"no reply over DDS within {PROXY_TIMEOUT_S:g} s")


def _remote_error(text: str):
    """The ServiceError of a failure reply's "<kind>: <text>" (ServiceFailed for a kind this
    side does not know)."""
    from horus import NoServerError, ServiceFailed, ServiceTimeout, TransportError

    kind, _, detail = text.partition(": ")
    errors = {error.kind: error
              for error in (ServiceFailed, NoServerError, ServiceTimeout, TransportError)}
    if kind not in errors:
        return ServiceFailed(f"on the server's host: {text}")
    return errors[kind](f"on the server's host: {detail}")
