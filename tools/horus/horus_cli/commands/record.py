"""`horus record`: make, look into, repair, replay, compare and export session recordings (MCAP
files, docs/recording.md). horus_cli.main hands it everything after `record`.

    horus record [-a | TOPICS...] [--frames] [-o FILE] [--duration S]   (runs horus-record)
    horus record list | info F | delete NAME | repair F
    horus record replay F [--rate X] [--loop] [--topics a,b] [--start S] [--end S]
                          [--view [--view-port N]]
    horus record diff A B
    horus record export F --foxglove OUT

A recording is named by its path, or by its name in the recordings folder ($HORUS_RECORDINGS,
default ~/.local/share/horus/recordings/) with or without `.mcap`. Exit status as every horus
command: 0, 1 (not found, refused, a difference for diff), 2 (usage).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import TYPE_CHECKING

from horus_cli.common import (EXIT_NOT_FOUND, EXIT_OK, EXIT_USAGE, CommandFailed, emit,
                              introspection, non_negative_float, positive_float, positive_int,
                              table, UsageParser)
from horus_cli.live import is_service_type
from horus_cli.schemas import SCHEMA_DIR, described_types, message_class

if TYPE_CHECKING:
    # Imported where used: horus.mcap loads the horus package, which `--help` does without.
    from horus import mcap


# The standalone recorder, set by the launcher (bin/horus) to the horus-record beside it.
RECORD_PROGRAM = os.environ.get("HORUS_RECORD_PROGRAM", "horus-record")


def recordings_folder() -> str:
    return os.environ.get("HORUS_RECORDINGS") or os.path.join(
        os.path.expanduser("~"), ".local", "share", "horus", "recordings")


def resolve(name: str) -> str:
    """The file a recording argument names: a path, else a name in the recordings folder."""
    candidates = [name]
    if os.sep not in name:
        folder = recordings_folder()
        candidates += [os.path.join(folder, name), os.path.join(folder, name + ".mcap")]
    for candidate in candidates:
        if os.path.isfile(candidate):
            return candidate
    raise CommandFailed(f"no recording '{name}' (not a file, nor in {recordings_folder()})")


def _walk(path: str) -> mcap.Reader:
    """The reader of a file after a full walk (every CRC checked)."""
    from horus import mcap
    reader = mcap.Reader(path)
    try:
        for _ in reader:
            pass
    except OSError as error:
        raise CommandFailed(f"cannot read {path}: {error.strerror}") from None
    return reader


# ---------------------------------------------------------------------------------------------
# record, list, delete


def record(args) -> int:
    command = [RECORD_PROGRAM, *(["-a"] if args.all else args.topics)]
    if args.frames and not args.all:
        command.append("--frames")
    if args.output:
        command += ["-o", args.output]
    if args.duration is not None:
        command += ["--duration", str(args.duration)]
    if args.namespace:
        command += ["--namespace", args.namespace]
    try:
        os.execvp(command[0], command)
    except OSError as error:
        raise CommandFailed(f"cannot run {RECORD_PROGRAM}: {error.strerror}") from None


def list_recordings(args) -> int:
    folder = recordings_folder()
    rows = []
    if os.path.isdir(folder):
        for entry in sorted(os.scandir(folder), key=lambda e: e.name):
            if entry.is_file() and entry.name.endswith(".mcap"):
                stat = entry.stat()
                rows.append({"name": entry.name[:-len(".mcap")], "path": entry.path,
                             "size": stat.st_size, "modified_s": int(stat.st_mtime)})

    def render(items):
        if args.verbose:
            table(["NAME", "BYTES", "MODIFIED", "PATH"],
                  [[r["name"], r["size"], time.strftime("%Y-%m-%d %H:%M:%S",
                                                        time.localtime(r["modified_s"])),
                    r["path"]] for r in items])
        else:
            for r in items:
                print(r["name"])
    emit(rows, args.json, render)
    return EXIT_OK


def delete(args) -> int:
    name = args.name[:-len(".mcap")] if args.name.endswith(".mcap") else args.name
    if not name or os.sep in name or name in (".", ".."):
        raise CommandFailed(f"'{args.name}' is not a recording name (horus record list)", EXIT_USAGE)
    path = os.path.join(recordings_folder(), name + ".mcap")
    try:
        os.unlink(path)
    except FileNotFoundError:
        raise CommandFailed(f"no recording '{name}' in {recordings_folder()}") from None
    print(f"deleted {path}")
    return EXIT_OK


# ---------------------------------------------------------------------------------------------
# info


def _duration_s(stats: mcap.Statistics) -> float:
    if stats.message_count == 0:
        return 0.0
    return (stats.message_end_time - stats.message_start_time) / 1e9


def _recorder_metadata(metadata: list[mcap.Metadata]) -> dict | None:
    for record in metadata:
        if record.name == "horus.recorder":
            return record.metadata
    return None


def describe(path: str, check: bool = False) -> dict:
    """What `info` shows: from the summary when the file has one (quick), else (or with `check`)
    from a walk over every record."""
    from horus import mcap
    summary = None if check else mcap.read_summary(path)
    if summary is not None and summary.statistics is not None:
        schemas, channels, stats = summary.schemas, summary.channels, summary.statistics
        metadata = [mcap.read_metadata_record(path, index) for index in summary.metadata_indexes
                    if index.name.startswith("horus.")]
        header = None
        summary_present, cut_bytes = True, 0
    else:
        reader = _walk(path)
        schemas, channels, stats = reader.schemas, reader.channels, reader.statistics
        metadata, header = reader.metadata, reader.header
        summary_present, cut_bytes = reader.finished, reader.cut_bytes
    recorder = _recorder_metadata(metadata)
    session = next((m.metadata for m in metadata if m.name == "horus.session"), {})
    topics = []
    for channel in sorted(channels.values(), key=lambda c: c.topic):
        schema = schemas.get(channel.schema_id)
        topic = {"topic": channel.topic, "encoding": channel.message_encoding,
                 "type": channel.metadata.get("horus.type") or (schema.name if schema else ""),
                 "fingerprint": channel.metadata.get("horus.fingerprint", ""),
                 "messages": stats.channel_message_counts.get(channel.id, 0)}
        if recorder is not None and channel.topic != mcap.TICKS_TOPIC:
            topic["lost"] = int(recorder.get(f"lost.{channel.topic}", 0))
        topics.append(topic)
    info = {"path": path, "size": os.path.getsize(path), "summary": summary_present,
            "cut_bytes": cut_bytes, "messages": stats.message_count, "chunks": stats.chunk_count,
            "start_ns": stats.message_start_time, "end_ns": stats.message_end_time,
            "duration_s": round(_duration_s(stats), 6), "session": session,
            "recorder_finished": recorder is not None,
            "lost": int(recorder.get("lost_total", 0)) if recorder is not None else None,
            "topics": topics}
    if header is not None:
        info["library"] = header.library
    return info


def info(args) -> int:
    path = resolve(args.file)

    def render(i):
        print(f"file: {i['path']} ({i['size']} bytes)")
        if i["session"]:
            print(f"session: {i['session'].get('session', '-')}, namespace "
                  f"{i['session'].get('namespace', '-')}, host {i['session'].get('hostname', '-')}")
        print(f"summary: {'present' if i['summary'] else 'MISSING (the file was cut; horus record repair adds it)'}")
        if i["cut_bytes"]:
            print(f"cut: the last {i['cut_bytes']} bytes are an incomplete record (ignored)")
        print(f"duration: {i['duration_s']:.3f} s, {i['messages']} messages in {i['chunks']} chunks")
        if i["lost"] is None:
            print("lost: unknown (the recorder did not finish: no horus.recorder metadata)")
        else:
            print(f"lost: {i['lost']}")
        table(["TOPIC", "TYPE", "ENCODING", "FINGERPRINT", "MESSAGES", "LOST"],
              [[t["topic"], t["type"] or "-", t["encoding"], t["fingerprint"] or "-",
                t["messages"], t.get("lost", "-")] for t in i["topics"]])
    emit(describe(path, args.check), args.json, render)
    return EXIT_OK


def repair(args) -> int:
    from horus import mcap
    path = resolve(args.file)
    try:
        reader = mcap.repair(path, args.output)
    except OSError as error:
        raise CommandFailed(f"cannot repair {path}: {error.strerror}") from None
    print(f"repaired {args.output or path}: kept {reader.statistics.message_count} messages in "
          f"{reader.statistics.chunk_count} chunks, dropped {reader.cut_bytes} bytes of an "
          "incomplete record")
    return EXIT_OK


# ---------------------------------------------------------------------------------------------
# replay


class _ReplayTopic:
    """A recorded channel and the shared-memory topic its messages go back into."""

    def __init__(self, channel: mcap.Channel, schema: mcap.Schema) -> None:
        from horus import mcap
        self.channel = channel
        self.type_name = channel.metadata.get("horus.type") or schema.name
        fingerprint = channel.metadata.get("horus.fingerprint", "")
        try:
            self.fingerprint = int(fingerprint, 16)
        except ValueError:
            raise CommandFailed(f"channel '{channel.topic}' has no valid horus.fingerprint "
                               f"({fingerprint!r}): not a HORUS recording") from None
        self.schema = schema.data.decode("utf-8", "replace")
        # A pool-backed topic's ring carries the descriptor; its data goes into a pool block.
        self.is_pool = channel.message_encoding == mcap.POOL_ENCODING
        self.is_pod = self.is_pool or channel.message_encoding == mcap.POD_ENCODING
        self.size = int(channel.metadata.get("horus.payload_size", "0")) if self.is_pod else 0
        self.largest = 0
        self.alignment = 1
        self.description = b""
        self.handle = None
        self.frames = None

    def payload(self, recorded: bytes) -> bytes | None:
        """What goes into the ring for a recorded message (None: nothing, it is malformed or
        the pool has no free block: said on stderr)."""
        if not self.is_pool:
            return recorded
        try:
            return self.frames.replay(recorded)
        except RuntimeError as error:
            print(f"horus record replay: {self.channel.topic}: {error}", file=sys.stderr)
            return None


class _ReplayFrames:
    """The recorded frame channels (/horus/frames, /horus/frames_static), each transform set
    again in the namespace's frame tree with its recorded stamp, this process their authority:
    lookups at the recorded times answer as the recorded tree did."""

    def __init__(self, channels: dict[int, bool]) -> None:
        self.channels = channels  # by channel id: whether it holds the static transforms
        self.tree = None
        self.refused: set[str] = set()  # children said on stderr once

    def open(self, namespace: str | None) -> None:
        import horus
        self.tree = horus.FrameTree(namespace or None)

    def set(self, data: bytes, channel_id: int) -> bool:
        """Sets one recorded FrameTransform; False (said on stderr once a frame) when the tree
        refuses it: another live process is the frame's authority, or its stamp goes back."""
        import horus
        record = json.loads(data)
        child = record.get("child_frame_id", "")
        translation = tuple(record["translation"][k] for k in "xyz")
        rotation = tuple(record["rotation"][k] for k in "xyzw")
        try:
            if self.channels[channel_id]:
                self.tree.set_static_transform(record["parent_frame_id"], child, translation,
                                               rotation)
            else:
                stamp = record["timestamp"]["sec"] * 1_000_000_000 + record["timestamp"]["nsec"]
                self.tree.set_transform(record["parent_frame_id"], child, translation, rotation,
                                        stamp)
        except horus.FrameError as error:
            if child not in self.refused:
                self.refused.add(child)
                print(f"horus record replay: frame '{child}': {error}", file=sys.stderr)
            return False
        return True


def _frame_channels(reader_channels: dict[int, mcap.Channel],
                    wanted: set[str] | None) -> dict[int, bool]:
    """The frame channels to replay: whether each (by channel id) holds static transforms."""
    from horus import foxglove
    return {channel.id: channel.topic == foxglove.FRAMES_STATIC_TOPIC
            for channel in reader_channels.values()
            if channel.topic in foxglove.FRAME_TOPICS and channel.message_encoding == "json"
            and (wanted is None or channel.topic in wanted)}


def _replay_channels(reader_channels: dict[int, mcap.Channel], schemas: dict[int, mcap.Schema],
                     wanted: set[str] | None) -> tuple[dict[int, _ReplayTopic], list[str]]:
    """The topics to replay by channel id, and the service topics left out."""
    from horus import mcap
    topics, services = {}, []
    for channel in reader_channels.values():
        if wanted is not None and channel.topic not in wanted:
            continue
        if channel.message_encoding not in (mcap.POD_ENCODING, mcap.MSGPACK_ENCODING,
                                            mcap.POOL_ENCODING):
            continue  # node ticks and anything not a HORUS topic are not republished
        schema = schemas.get(channel.schema_id)
        if schema is None:
            raise CommandFailed(f"channel '{channel.topic}' has no schema record")
        topic = _ReplayTopic(channel, schema)
        # Replayed, a recorded request would have a live server act on it again, and a
        # registration would announce a server that is not there: left out unless named.
        if wanted is None and is_service_type(topic.type_name):
            services.append(channel.topic)
            continue
        topics[channel.id] = topic
    if wanted is not None:
        missing = sorted(wanted - {t.channel.topic for t in topics.values()})
        if missing:
            raise CommandFailed(f"not in the recording: {', '.join(missing)}")
    return topics, sorted(services)


def _installed_fingerprints(args) -> dict[str, str]:
    """Each type of the installed (or -I) schemas with its current fingerprint (16 hex digits);
    empty when there are no schemas to read."""
    if not (args.include or SCHEMA_DIR):
        return {}
    return {t["name"]: t["fingerprint"].lower().removeprefix("0x")
            for t in described_types(args)}


def check_types(topics: dict[int, _ReplayTopic], args) -> None:
    """Refuses (by type name) a type whose fingerprint differs from the recorded one, in the
    schemas or on a live topic of the namespace: its bytes would be read as another layout."""
    installed = _installed_fingerprints(args)
    live = {t["name"]: t for t in introspection().list_topics(args.namespace)}
    for topic in topics.values():
        recorded = f"{topic.fingerprint:016x}"
        current = installed.get(topic.type_name)
        if current is not None and current != recorded:
            raise CommandFailed(f"type {topic.type_name} changed since the recording (topic "
                               f"'{topic.channel.topic}': recorded fingerprint {recorded}, the "
                               f"schemas now give {current}); refusing to replay it")
        segment = live.get(topic.channel.topic)
        if segment is not None and segment["type_name"] and (
                segment["type_name"] != topic.type_name or segment["fingerprint"] != topic.fingerprint):
            what = ("type " + topic.type_name + " changed since the recording"
                    if segment["type_name"] == topic.type_name else "the topic carries another type")
            raise CommandFailed(f"{what}: topic '{topic.channel.topic}' now carries "
                               f"{segment['type_name']} (fingerprint {segment['fingerprint']:016x}), "
                               f"the recording has {topic.type_name} (fingerprint {recorded}); "
                               "refusing to replay it")


def _open_topic(topic: _ReplayTopic, capacity: int, namespace: str):
    runtime = introspection()
    topic.handle = runtime.open_topic(topic.channel.topic, topic.type_name, topic.fingerprint,
                                      topic.schema, topic.is_pod, topic.size, topic.alignment,
                                      capacity, max(16 * 1024, topic.largest), False,
                                      topic.description)
    if topic.is_pool:
        # Each frame is made again in the namespace's pool; as many stay alive as the ring
        # (which an existing topic sized) can still hand out.
        topic.frames = runtime.replay_frames(topic.type_name, topic.fingerprint, namespace,
                                             topic.handle.capacity)


def _selected(message: mcap.Message, first: int, start: float | None, end: float | None) -> bool:
    offset = (message.log_time - first) / 1e9
    return (start is None or offset >= start) and (end is None or offset <= end)


def replay(args) -> int:
    if args.start is not None and args.end is not None and args.end < args.start:
        raise CommandFailed(f"--end {args.end:g} is before --start {args.start:g}: nothing to replay",
                            EXIT_USAGE)
    if args.view_port is not None and not args.view:
        raise CommandFailed("--view-port is the live view's: add --view", EXIT_USAGE)
    from horus import foxglove, mcap
    path = resolve(args.file)
    wanted = {t for t in args.topics.split(",") if t} if args.topics else None
    # A first walk finds the channels, each one's first message time and largest message (a
    # serialized topic's slots must hold it) before anything is published.
    reader = mcap.Reader(path)
    first_time: dict[int, int] = {}
    largest: dict[int, int] = {}
    for record in reader:
        if isinstance(record, mcap.Message):
            first_time[record.channel_id] = min(first_time.get(record.channel_id, record.log_time),
                                                record.log_time)
            largest[record.channel_id] = max(largest.get(record.channel_id, 0), len(record.data))
    frames = _ReplayFrames(_frame_channels(reader.channels, wanted))
    if wanted is not None:
        missing = sorted(wanted & set(foxglove.FRAME_TOPICS)
                         - {reader.channels[i].topic for i in frames.channels})
        if missing:
            raise CommandFailed(f"not in the recording: {', '.join(missing)}")
    named_topics = None if wanted is None else wanted - set(foxglove.FRAME_TOPICS)
    topics, services = _replay_channels(reader.channels, reader.schemas, named_topics)
    if services:
        print(f"horus record replay: left out the service topics {', '.join(services)} (name "
              "them with --topics to replay them)", file=sys.stderr)
    if not topics and not frames.channels:
        raise CommandFailed(f"{path} has no HORUS topic to replay")
    check_types(topics, args)
    replayed = [*topics, *frames.channels]
    if not any(channel_id in first_time for channel_id in replayed):
        raise CommandFailed(f"{path} holds no message on the topics to replay")
    first = min(first_time[channel_id] for channel_id in replayed if channel_id in first_time)
    # Everything that can refuse the recording does so before the first topic is opened: a
    # refusal then leaves nothing behind in the namespace.
    for channel_id, topic in topics.items():
        topic.largest = topic.size if topic.is_pool else largest.get(channel_id, 0)
        # The class made from the type description the channel carries (else from the schema
        # text) gives what the recording does not state: a POD type's alignment, and the type
        # description of a topic the replay creates.
        info = message_class(topic.type_name, topic.schema, topic.fingerprint,
                             topic.channel.description).__horus__
        if topic.is_pod:
            topic.alignment = info.alignment
        if info.name == topic.type_name:
            topic.description = info.description
    # Before the first topic is opened, so that a port it cannot listen on leaves nothing behind;
    # the view finds the topics at its next look at the namespace (every 250 ms).
    view = _start_view(args, first) if args.view else None
    try:
        for topic in topics.values():
            _open_topic(topic, args.capacity, args.namespace or "")
        if frames.channels:
            frames.open(args.namespace)
        sent, failed, transforms, refused = _publish(path, topics, frames, first, args, view)
    finally:
        if view is not None:
            view.stop()
    print(f"replayed {sent} messages on {len(topics)} topics"
          + (f"; {failed} could not be published (horus topic info shows why)" if failed else "")
          + (f"; set {transforms} transforms in the frame tree" if frames.channels else "")
          + (f" ({refused} refused, said above)" if refused else ""))
    return EXIT_OK if failed == 0 and refused == 0 else EXIT_NOT_FOUND


def _start_view(args, first: int):
    """The live view of the replayed namespace (docs/live-view.md), on this machine only, its
    time the recording's from the first message on; says where once listening."""
    runtime = introspection()
    if not runtime.has_view():
        raise CommandFailed("--view needs the live view, which this horus was built without "
                            "(it is built where Cap'n Proto is installed: Debian's libcapnp-dev "
                            "and capnproto)")
    port = 8765 if args.view_port is None else args.view_port
    view = runtime.live_view(args.namespace or "", "127.0.0.1", port)
    view.set_time(first)
    view.start()
    print(f"live view: ws://127.0.0.1:{view.port}/", flush=True)
    return view


def _publish(path: str, topics: dict[int, _ReplayTopic], frames: _ReplayFrames, first: int, args,
             view) -> tuple[int, int, int, int]:
    """Publishes the selected messages with their recorded timing (the view's time set to each
    one's log time first, so that viewers see it stamped as recorded), and sets the recorded
    transforms in the frame tree at theirs; (sent, failed, transforms set, transforms refused).
    Transforms are set in the first pass of a --loop only: the tree keeps them by their stamps,
    which a second pass would take back in time. A static transform recorded before --start is
    set at the start, as it holds for good."""
    from horus import mcap
    sent = failed = transforms = refused = 0
    first_pass = True
    while True:
        wall_start = time.monotonic()
        for record in mcap.Reader(path):
            if not isinstance(record, mcap.Message):
                continue
            if record.channel_id in frames.channels:
                if not first_pass:
                    continue
                early_static = (frames.channels[record.channel_id]
                                and args.start is not None
                                and (record.log_time - first) / 1e9 < args.start)
                if not early_static and not _selected(record, first, args.start, args.end):
                    continue
            elif record.channel_id not in topics or not _selected(record, first, args.start,
                                                                   args.end):
                continue
            offset = (record.log_time - first) / 1e9 - (args.start or 0.0)
            delay = wall_start + offset / args.rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if record.channel_id in frames.channels:
                if view is not None:
                    view.set_time(record.log_time)
                if frames.set(record.data, record.channel_id):
                    transforms += 1
                else:
                    refused += 1
                continue
            topic = topics[record.channel_id]
            payload = topic.payload(record.data)
            if view is not None:
                view.set_time(record.log_time)
            if payload is not None and topic.handle.send(payload):
                sent += 1
            else:
                failed += 1
        if not args.loop:
            break
        first_pass = False
    return sent, failed, transforms, refused


# ---------------------------------------------------------------------------------------------
# diff


def _per_topic(path: str) -> dict[str, list[mcap.Message]]:
    from horus import mcap
    topics: dict[str, list[mcap.Message]] = {}
    reader = mcap.Reader(path)
    for record in reader:
        if isinstance(record, mcap.Message):
            channel = reader.channels[record.channel_id]
            if channel.topic != mcap.TICKS_TOPIC:
                topics.setdefault(channel.topic, []).append(record)
    return topics


def first_differences(a_path: str, b_path: str) -> list[dict]:
    """Per topic of either file, the first message (by its index on the topic) whose bytes
    differ, or where one file has no more; times are not compared (two runs differ in them)."""
    a, b = _per_topic(a_path), _per_topic(b_path)
    differences = []
    for topic in sorted(set(a) | set(b)):
        left, right = a.get(topic, []), b.get(topic, [])
        for index in range(max(len(left), len(right))):
            if index >= len(left) or index >= len(right):
                differences.append({"topic": topic, "index": index,
                                    "reason": f"only {'B' if index >= len(left) else 'A'} has "
                                              f"message #{index} (A has {len(left)}, "
                                              f"B has {len(right)})"})
                break
            if left[index].data != right[index].data:
                x, y = left[index].data, right[index].data
                at = next((i for i in range(min(len(x), len(y))) if x[i] != y[i]),
                          min(len(x), len(y)))
                differences.append({"topic": topic, "index": index,
                                    "reason": f"bytes differ from offset {at} (A {len(x)} bytes "
                                              f"at {left[index].log_time} ns, B {len(y)} bytes at "
                                              f"{right[index].log_time} ns)"})
                break
    return differences


def diff(args) -> int:
    differences = first_differences(resolve(args.a), resolve(args.b))

    def render(rows):
        if not rows:
            print("no difference: every topic has the same messages in the same order")
        for row in rows:
            print(f"{row['topic']}: message #{row['index']}: {row['reason']}")
    emit(differences, args.json, render)
    return EXIT_NOT_FOUND if differences else EXIT_OK


# ---------------------------------------------------------------------------------------------
# export


def export(args) -> int:
    from horus import foxglove
    path = resolve(args.file)
    try:
        counts, skipped = foxglove.export(path, args.foxglove)
    except foxglove.ExportError as error:
        raise CommandFailed(str(error)) from None
    print(f"wrote {args.foxglove}: {sum(counts.values())} JSON messages on {len(counts)} topics")
    for reason in skipped.values():
        print(f"horus: left out of the export: {reason}", file=sys.stderr)
    return EXIT_NOT_FOUND if skipped else EXIT_OK


# ---------------------------------------------------------------------------------------------
# command line


def _parents() -> tuple[argparse.ArgumentParser, argparse.ArgumentParser]:
    """The options every `horus record` parser takes, and those of the listings."""
    common = UsageParser(add_help=False)
    common.add_argument("--namespace", "-n", default=argparse.SUPPRESS,
                        help="the namespace (default: $HORUS_NAMESPACE, else 'default')")
    listing = UsageParser(add_help=False)
    listing.add_argument("--json", action="store_true", help="print JSON instead of text")
    return common, listing


def build_parser() -> argparse.ArgumentParser:
    parser = UsageParser(prog="horus record", parents=[_parents()[0]],
                         description="Record the namespace's topics (runs horus-record until "
                                     "Ctrl+C or --duration), or, with an action, work on "
                                     "recordings: " + ", ".join(ACTIONS)
                                     + ". `horus record ACTION --help` for each.")
    parser.add_argument("-a", "--all", action="store_true",
                        help="every topic of the namespace, also those that appear later, the "
                             "parameter changes and the frame tree")
    parser.add_argument("topics", nargs="*", metavar="TOPIC", help="topics to record")
    parser.add_argument("--frames", action="store_true",
                        help="the namespace's frame tree too (/horus/frames, "
                             "/horus/frames_static); -a records it anyway")
    parser.add_argument("-o", "--output", metavar="FILE",
                        help="the file (default: a new session_YYYY_MM_DD_HHMMSS.mcap in "
                             "$HORUS_RECORDINGS)")
    parser.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds")
    parser.set_defaults(handler=record)
    return parser


def _replay_arguments(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("file")
    sub.add_argument("--rate", type=positive_float, default=1.0,
                     help="speed factor (default 1: as recorded; 2: twice as fast)")
    sub.add_argument("--loop", action="store_true", help="start again at the end, until Ctrl+C")
    sub.add_argument("--topics", metavar="A,B", help="only these topics")
    sub.add_argument("--start", type=non_negative_float, metavar="S",
                     help="from S seconds after the first message")
    sub.add_argument("--end", type=non_negative_float, metavar="S",
                     help="up to S seconds after the first message")
    sub.add_argument("--capacity", type=positive_int, default=64,
                     help="slots of topics the replay creates (default 64)")
    sub.add_argument("-I", dest="include", action="append", metavar="DIR",
                     help="schema folder whose types must match the recording (repeatable; "
                          "default: the installed schemas)")
    sub.add_argument("--view", action="store_true",
                     help="serve the replayed namespace to Foxglove, Lichtblick and the built-in "
                          "page on 127.0.0.1 (as `horus view` does) while replaying, its time "
                          "the recording's (docs/live-view.md)")
    sub.add_argument("--view-port", type=_port, metavar="N",
                     help="the live view's port (default 8765; 0: any free one)")


def _port(text: str) -> int:
    """An argparse type: a TCP port, 0 for any free one."""
    if not text.isdigit() or int(text) > 65535:
        raise argparse.ArgumentTypeError(f"needs a port number from 0 to 65535, got {text!r}")
    return int(text)


# Each action: its handler, whether it lists (--json), what it does, its own arguments.
ACTION_SPECS = {
    "list": (list_recordings, True, "The recordings in $HORUS_RECORDINGS.",
             lambda sub: sub.add_argument("-v", "--verbose", action="store_true",
                                          help="with size, time and path")),
    "info": (info, True, "A recording's topics, types, message counts, duration, losses and "
                         "whether its summary is there (a cut file has none).",
             lambda sub: (sub.add_argument("file", help="a path, or a name of `horus record list`"),
                          sub.add_argument("--check", action="store_true",
                                           help="read every record (checking every CRC) instead "
                                                "of the summary"))),
    "delete": (delete, False, "Delete a recording of the folder.",
               lambda sub: sub.add_argument("name", help="a name of `horus record list`")),
    "repair": (repair, False, "Write the summary and footer of a cut file (a recorder killed with "
                              "kill -9), keeping every complete chunk.",
               lambda sub: (sub.add_argument("file"),
                            sub.add_argument("-o", "--output", metavar="FILE",
                                             help="write the repaired file there (default: in "
                                                  "place)"))),
    "replay": (replay, False, "Publish a recording's messages into the namespace's shared-memory "
                              "topics with the recorded timing.", _replay_arguments),
    "diff": (diff, True, "The first differing message of each topic of two recordings (bytes, in "
                         "order; times are ignored). Exit status 1 when they differ.",
             lambda sub: (sub.add_argument("a"), sub.add_argument("b"))),
    "export": (export, False, "Write an MCAP that Foxglove opens with no plugin: JSON messages "
                              "with JSON Schema schemas; images, point clouds, laser scans, poses "
                              "and transforms as Foxglove's own schemas.",
               lambda sub: (sub.add_argument("file"),
                            sub.add_argument("--foxglove", required=True, metavar="OUT",
                                             help="the file to write"))),
}
ACTIONS = tuple(ACTION_SPECS)


def build_action_parser(action: str) -> argparse.ArgumentParser:
    handler, lists, description, add_arguments = ACTION_SPECS[action]
    common, listing = _parents()
    sub = UsageParser(prog=f"horus record {action}", description=description,
                      parents=[common, listing] if lists else [common])
    add_arguments(sub)
    sub.set_defaults(handler=handler)
    return sub


def parse_record(argv: list[str]) -> argparse.Namespace | None:
    """The parsed arguments of `horus [--namespace NS] record ...` (with their `handler`), or None
    for any other command: horus_cli.main asks this first, as `record` parses its own arguments
    (topics and actions mix), then runs the handler as it runs its own."""
    namespace, at = None, 0
    while at < len(argv) and (argv[at] in ("-n", "--namespace")
                              or argv[at].startswith("--namespace=")):
        if "=" in argv[at]:
            namespace, at = argv[at].split("=", 1)[1], at + 1
        else:
            namespace, at = (argv[at + 1] if at + 1 < len(argv) else None), at + 2
    if at >= len(argv) or argv[at] != "record":
        return None
    argv = argv[at + 1:]
    if argv and argv[0] in ACTIONS:
        args = build_action_parser(argv[0]).parse_args(argv[1:])
    else:
        # `--` lets a topic be named like an action: horus record -- list
        parser = build_parser()
        args = parser.parse_args(argv)
        if not args.all and not args.topics and not args.frames:
            parser.error("name the topics to record, --frames for the frame tree, or -a for all "
                         "of them")
        if args.all and args.topics:
            parser.error("-a records every topic: name no topic with it")
    args.namespace = getattr(args, "namespace", None) or namespace
    handler = args.handler

    def reporting(parsed):
        try:
            return handler(parsed)
        except Exception as error:  # noqa: BLE001 (only an McapError is converted)
            # A file's fault, one line as every failure; only a loaded horus.mcap raises one.
            loaded = sys.modules.get("horus.mcap")
            if loaded is not None and isinstance(error, loaded.McapError):
                raise CommandFailed(str(error)) from None
            raise
    args.handler = reporting
    return args


def register(commands) -> None:
    # Only its line of `horus --help` and its completion words: parse_record parses its
    # arguments before argparse sees them.
    sub = commands.command("record", add_help=False, help="record, inspect, repair, replay, "
                           "compare and export sessions (MCAP): horus record --help")
    sub.set_defaults(completion_words=" ".join(ACTIONS) + " $(horus topic list 2>/dev/null)")
