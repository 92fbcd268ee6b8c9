"""`horus bridge`: local topics to Cyclone DDS and DDS topics into the local namespace
(docs/dds-bridge.md).

    horus bridge --export 'cmd_*' --import 'odom' [--domain N] [--best-effort] [--depth N]

A local topic whose name matches an --export pattern is written to the DDS topic `rt/<name>`
in CDR (dds_cdr) under its DDS type name (`horus-gen describe`'s dds_type, ROS 2's naming); its
writer's user data carries the HORUS identity (type name, fingerprint, schema text), so a bridge
on another host can create the topic without knowing the type beforehand. A DDS publication
`rt/<name>` whose name matches an --import pattern is published into the local topic <name>:
created from that identity, or the existing topic when its type is the same (a plain DDS program
gives no identity: the local topic must exist then). Another type is refused, naming both.

Nothing crosses that no pattern names. DDS endpoints ignore their own participant, and a topic
named by both directions is refused, so nothing a bridge writes comes back to it. One thread per
bridged topic moves messages; topics are looked for again every half second.
"""
from __future__ import annotations

import fnmatch
import json
import sys
import tempfile
import threading
import time

import dds_cdr
import dynamic_types

PREFIX = "rt/"  # ROS 2's prefix of topic names on DDS
RESCAN_S = 0.5
LOCAL_CAPACITY = 64  # the geometry a topic the bridge creates gets (as `horus topic pub`'s)
LOCAL_MAX_MESSAGE = 16 * 1024


class BridgeError(Exception):
    """A topic the bridge will not carry (one line, naming the topic and why)."""


def _say(text: str) -> None:
    print(text, flush=True)


def _complain(text: str) -> None:
    print(f"horus bridge: {text}", file=sys.stderr, flush=True)


class _Types:
    """Generated classes and DDS type names of HORUS types, from their schema texts."""

    def __init__(self) -> None:
        self._dds_names: dict[tuple[str, str], str] = {}

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


def _identity(topic: dict) -> bytes:
    return json.dumps({"type": topic["type_name"], "fingerprint": f"{topic['fingerprint']:016x}",
                       "schema": topic["schema"]}).encode()


def _open_local(core, name: str, type_name: str, fingerprint: int, schema: str, cls, capacity: int,
                max_message_size: int, single_publisher: bool):
    info = cls.__horus__
    return core.Topic(name, type_name, fingerprint, schema, info.is_pod,
                      info.size if info.is_pod else 0, info.alignment if info.is_pod else 1,
                      capacity, max_message_size, single_publisher)


class Bridge:
    def __init__(self, core, dds, namespace: str, exports: list[str], imports: list[str],
                 domain: int, reliable: bool, depth: int) -> None:
        self.core, self.dds, self.namespace = core, dds, namespace
        self.exports, self.imports = exports, imports
        self.qos = {"reliable": reliable, "depth": depth}
        self.domain = domain
        self.participant = dds.Participant(domain)
        self.types = _Types()
        self.stop = threading.Event()
        self.threads: list[threading.Thread] = []
        self.done: set[str] = set()  # local topic names exported or imported (or refused)

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

    def _spawn(self, target, *args) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True)
        thread.start()
        self.threads.append(thread)

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

    def _export(self, topic: dict) -> None:
        name, type_name = topic["name"], topic["type_name"]
        cls = self.types.load(type_name, topic["schema"], topic["fingerprint"])
        dds_type = self.types.dds_name(type_name, topic["schema"])
        local = _open_local(self.core, name, type_name, topic["fingerprint"], topic["schema"], cls,
                            topic["capacity"], topic["max_message_size"],
                            topic["single_publisher"])
        writer = self.dds.Writer(self.participant, PREFIX + name, dds_type,
                                 user_data=_identity(topic), **self.qos)
        self._spawn(self._pump_export, local, cls, writer)
        _say(f"exporting '{name}' ({type_name}) as {PREFIX}{name} ({dds_type})")

    def _pump_export(self, local, cls, writer) -> None:
        codec = dds_cdr.CdrCodec(cls)
        while not self.stop.is_set():
            data = local.recv(0.1)
            if data is not None:
                writer.write(codec.encode(cls.from_bytes(data)))

    # -- import: DDS -> local ---------------------------------------------------------------------

    def scan_imports(self) -> None:
        for publication in self.participant.publications():
            if not publication["topic"].startswith(PREFIX):
                continue
            name = publication["topic"][len(PREFIX):]
            if not self._matches(name, self.imports) or name in self.done:
                continue
            if self._matches(name, self.exports):
                self._claim(name)  # refused: both directions
                continue
            try:
                ready = self._import(name, publication)
            except (BridgeError, RuntimeError) as error:
                self.done.add(name)
                _complain(f"cannot import topic '{name}': {error}")
                continue
            if ready is not None:
                self.done.add(name)
                self._spawn(self._pump_import, *ready)
                _say(f"importing {publication['topic']} ({publication['type']}) as '{name}' "
                     f"({ready[1].__horus__.name})")

    def _import(self, name: str, publication: dict):
        """The (reader, class, local handle) of an import; None when the type is not known
        yet (a plain DDS writer, and no local topic of that name)."""
        remote = json.loads(publication["user_data"]) if publication["user_data"] else None
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
            capacity, max_message = LOCAL_CAPACITY, LOCAL_MAX_MESSAGE
        else:
            return None
        dds_type = self.types.dds_name(type_name, schema)
        if dds_type != publication["type"]:
            raise BridgeError(f"the local topic has type {type_name} ({dds_type} on DDS), DDS "
                              f"carries {publication['type']}")
        cls = self.types.load(type_name, schema, fingerprint)
        handle = _open_local(self.core, name, type_name, fingerprint, schema, cls, capacity,
                             max_message, False)
        reader = self.dds.Reader(self.participant, publication["topic"], dds_type, **self.qos)
        return reader, cls, handle

    def _pump_import(self, reader, cls, local) -> None:
        codec = dds_cdr.CdrCodec(cls)
        while not self.stop.is_set():
            for cdr in reader.take(0.1):
                try:
                    message = codec.decode(cdr)
                except ValueError as error:
                    _complain(str(error))
                    continue
                if not local.send(message.to_bytes()):
                    _complain(f"topic '{local.name}' refused a message from DDS")

    def run(self) -> None:
        _say(f"bridge on DDS domain {self.domain}: exporting {self.exports or 'nothing'}, "
             f"importing {self.imports or 'nothing'}")
        try:
            while True:
                if self.exports:
                    self.scan_exports()
                if self.imports:
                    self.scan_imports()
                time.sleep(RESCAN_S)
        finally:
            self.stop.set()
            for thread in self.threads:
                thread.join()
