"""MCAP files (https://mcap.dev/spec) as HORUS recordings use them: read, verify, write, repair.

Python standard library plus zstandard (Debian python3-zstandard) for the chunks. The reader walks
the data section record by record, so it reads a file with or without its summary: a recorder
killed with `kill -9` leaves its complete chunks and no summary (and maybe half a record at the
end), and everything complete is still read. It checks every CRC it meets (chunks, data section,
summary) and raises McapError naming the offset of what is wrong. The writer writes zstd chunks,
each followed by its message indexes, then the data-end record, the summary (schemas, channels,
statistics, chunk and metadata indexes, summary offsets) and the footer; `repair` appends that tail
to a file that lacks it. The HORUS conventions on top (schema and channel metadata, among it the
type description `Channel.description` gives, the `/horus/ticks` channel, the `horus.session` and
`horus.recorder` metadata) are in docs/recording.md.
"""
from __future__ import annotations

import base64
import os
import struct
import zlib
from dataclasses import dataclass, field
from typing import BinaryIO, Iterator

MAGIC = b"\x89MCAP0\r\n"

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX = 0x07, 0x08, 0x09, 0x0A
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX, OP_SUMMARY_OFFSET, OP_DATA_END = 0x0B, 0x0C, 0x0D, 0x0E, 0x0F

RECORD_HEAD = struct.Struct("<BQ")  # opcode, content length
FOOTER_SIZE = RECORD_HEAD.size + 20  # opcode, length, summary_start, summary_offset_start, crc
DEFAULT_CHUNK_SIZE = 1 << 20  # uncompressed bytes of records per chunk, as the C++ recorder

# The HORUS convention: channels of topics carry their raw POD or MessagePack bytes; the node
# ticks are JSON on a channel no topic can be named (topic names have no '/').
POD_ENCODING, MSGPACK_ENCODING = "horus.pod", "horus.msgpack"
# A pool-backed topic (Image, DepthImage, PointCloud, Tensor): the descriptor (horus.payload_size
# bytes, its block zeroed) followed by the data it covers (docs/recording.md).
POOL_ENCODING = "horus.pool"
TICKS_TOPIC = "/horus/ticks"
# A topic channel's type description (docs/type-description.md), base64 in its metadata.
DESCRIPTION_KEY = "horus.description"


class McapError(Exception):
    """A file that is not MCAP, or whose contents contradict themselves (CRC, lengths)."""


@dataclass
class Header:
    profile: str
    library: str


@dataclass
class Schema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass
class Channel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]

    @property
    def description(self) -> bytes:
        """The topic's type description (MessagePack bytes, as `T.__horus__["description"]`), or
        b"" for a file written before recordings carried it. McapError when it is not base64."""
        text = self.metadata.get(DESCRIPTION_KEY)
        if text is None:
            return b""
        try:
            return base64.b64decode(text, validate=True)
        except ValueError:
            raise McapError(f"channel '{self.topic}': {DESCRIPTION_KEY} is not base64") from None


def description_metadata(description: bytes) -> dict[str, str]:
    """The channel metadata that carries `description` (none for b"")."""
    return {DESCRIPTION_KEY: base64.b64encode(description).decode("ascii")} if description else {}


@dataclass
class Message:
    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


@dataclass
class Metadata:
    name: str
    metadata: dict[str, str]


@dataclass
class ChunkIndex:
    message_start_time: int
    message_end_time: int
    chunk_start_offset: int
    chunk_length: int
    message_index_offsets: dict[int, int]
    message_index_length: int
    compression: str
    compressed_size: int
    uncompressed_size: int


@dataclass
class MetadataIndex:
    offset: int
    length: int
    name: str


@dataclass
class Statistics:
    message_count: int = 0
    schema_count: int = 0
    channel_count: int = 0
    attachment_count: int = 0
    metadata_count: int = 0
    chunk_count: int = 0
    message_start_time: int = 0
    message_end_time: int = 0
    channel_message_counts: dict[int, int] = field(default_factory=dict)

    def count(self, message: Message) -> None:
        if self.message_count == 0 or message.log_time < self.message_start_time:
            self.message_start_time = message.log_time
        if self.message_count == 0 or message.log_time > self.message_end_time:
            self.message_end_time = message.log_time
        self.message_count += 1
        self.channel_message_counts[message.channel_id] = (
            self.channel_message_counts.get(message.channel_id, 0) + 1)


@dataclass
class Summary:
    """The summary section of a finished file (what `read_summary` finds)."""
    schemas: dict[int, Schema]
    channels: dict[int, Channel]
    statistics: Statistics | None
    chunk_indexes: list[ChunkIndex]
    metadata_indexes: list[MetadataIndex]


# ---------------------------------------------------------------------------------------------
# Record contents: parsing


class _Fields:
    """Reads the fields of one record's content, failing clearly on a short record."""

    def __init__(self, data: bytes, what: str) -> None:
        self.data, self.at, self.what = data, 0, what

    def take(self, size: int) -> bytes:
        if self.at + size > len(self.data):
            raise McapError(f"{self.what}: record too short")
        piece = self.data[self.at:self.at + size]
        self.at += size
        return piece

    def unpack(self, fmt: str):
        layout = struct.Struct("<" + fmt)
        values = layout.unpack(self.take(layout.size))
        return values[0] if len(values) == 1 else values

    def string(self) -> str:
        try:
            return self.take(self.unpack("I")).decode("utf-8")
        except UnicodeDecodeError:
            raise McapError(f"{self.what}: a string is not UTF-8") from None

    def byte_array(self) -> bytes:
        return self.take(self.unpack("I"))

    def string_map(self) -> dict[str, str]:
        entries = _Fields(self.take(self.unpack("I")), self.what)
        out = {}
        while entries.at < len(entries.data):
            key = entries.string()
            out[key] = entries.string()
        return out

    def rest(self) -> bytes:
        piece = self.data[self.at:]
        self.at = len(self.data)
        return piece


def _parse_header(data: bytes) -> Header:
    f = _Fields(data, "header")
    return Header(f.string(), f.string())


def _parse_schema(data: bytes) -> Schema:
    f = _Fields(data, "schema")
    return Schema(f.unpack("H"), f.string(), f.string(), f.byte_array())


def _parse_channel(data: bytes) -> Channel:
    f = _Fields(data, "channel")
    channel_id, schema_id = f.unpack("HH")
    return Channel(channel_id, schema_id, f.string(), f.string(), f.string_map())


def _parse_message(data: bytes) -> Message:
    f = _Fields(data, "message")
    channel_id, sequence, log_time, publish_time = f.unpack("HIQQ")
    return Message(channel_id, sequence, log_time, publish_time, f.rest())


def _parse_metadata(data: bytes) -> Metadata:
    f = _Fields(data, "metadata")
    return Metadata(f.string(), f.string_map())


def _parse_chunk_index(data: bytes) -> ChunkIndex:
    f = _Fields(data, "chunk index")
    start, end, offset, length = f.unpack("QQQQ")
    offsets_field = _Fields(f.take(f.unpack("I")), "chunk index")
    offsets = {}
    while offsets_field.at < len(offsets_field.data):
        channel_id, index_offset = offsets_field.unpack("HQ")
        offsets[channel_id] = index_offset
    index_length = f.unpack("Q")
    compression = f.string()
    compressed, uncompressed = f.unpack("QQ")
    return ChunkIndex(start, end, offset, length, offsets, index_length, compression, compressed,
                      uncompressed)


def _parse_statistics(data: bytes) -> Statistics:
    f = _Fields(data, "statistics")
    values = f.unpack("QHIIIIQQ")
    counts_field = _Fields(f.take(f.unpack("I")), "statistics")
    counts = {}
    while counts_field.at < len(counts_field.data):
        channel_id, count = counts_field.unpack("HQ")
        counts[channel_id] = count
    return Statistics(*values, channel_message_counts=counts)


def _parse_metadata_index(data: bytes) -> MetadataIndex:
    f = _Fields(data, "metadata index")
    offset, length = f.unpack("QQ")
    return MetadataIndex(offset, length, f.string())


def _decompress(compression: str, data: bytes, size: int, where: str) -> bytes:
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard  # Debian python3-zstandard; imported here so that `--help` stays quick
        try:
            return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        except zstandard.ZstdError as error:
            raise McapError(f"{where}: zstd: {error}") from None
    raise McapError(f"{where}: chunk compression '{compression}' is not supported (zstd or none)")


# ---------------------------------------------------------------------------------------------
# Record contents: writing


def _string(text: str) -> bytes:
    raw = text.encode("utf-8")
    return struct.pack("<I", len(raw)) + raw


def _string_map(values: dict[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in sorted(values.items()))
    return struct.pack("<I", len(body)) + body


def _record(opcode: int, content: bytes) -> bytes:
    return RECORD_HEAD.pack(opcode, len(content)) + content


def _schema_record(s: Schema) -> bytes:
    return _record(OP_SCHEMA, struct.pack("<H", s.id) + _string(s.name) + _string(s.encoding)
                   + struct.pack("<I", len(s.data)) + s.data)


def _channel_record(c: Channel) -> bytes:
    return _record(OP_CHANNEL, struct.pack("<HH", c.id, c.schema_id) + _string(c.topic)
                   + _string(c.message_encoding) + _string_map(c.metadata))


def _message_record(m: Message) -> bytes:
    return _record(OP_MESSAGE, struct.pack("<HIQQ", m.channel_id, m.sequence, m.log_time,
                                           m.publish_time) + m.data)


def _metadata_record(m: Metadata) -> bytes:
    return _record(OP_METADATA, _string(m.name) + _string_map(m.metadata))


def _chunk_index_record(c: ChunkIndex) -> bytes:
    offsets = b"".join(struct.pack("<HQ", k, v) for k, v in sorted(c.message_index_offsets.items()))
    return _record(OP_CHUNK_INDEX, struct.pack("<QQQQ", c.message_start_time, c.message_end_time,
                                               c.chunk_start_offset, c.chunk_length)
                   + struct.pack("<I", len(offsets)) + offsets
                   + struct.pack("<Q", c.message_index_length) + _string(c.compression)
                   + struct.pack("<QQ", c.compressed_size, c.uncompressed_size))


def _statistics_record(s: Statistics) -> bytes:
    counts = b"".join(struct.pack("<HQ", k, v) for k, v in sorted(s.channel_message_counts.items()))
    return _record(OP_STATISTICS, struct.pack("<QHIIIIQQ", s.message_count, s.schema_count,
                                              s.channel_count, s.attachment_count,
                                              s.metadata_count, s.chunk_count,
                                              s.message_start_time, s.message_end_time)
                   + struct.pack("<I", len(counts)) + counts)


def _metadata_index_record(m: MetadataIndex) -> bytes:
    return _record(OP_METADATA_INDEX, struct.pack("<QQ", m.offset, m.length) + _string(m.name))


class _CrcFile:
    """A file being written, remembering its offset and the CRC of everything written since
    the CRC was last reset (the data section, then the summary)."""

    def __init__(self, stream: BinaryIO, offset: int, crc: int = 0) -> None:
        self.stream, self.offset, self.crc = stream, offset, crc

    def write(self, data: bytes) -> int:
        start = self.offset
        self.stream.write(data)
        self.offset += len(data)
        self.crc = zlib.crc32(data, self.crc)
        return start


def _write_tail(out: _CrcFile, schemas: dict[int, Schema], channels: dict[int, Channel],
                statistics: Statistics, chunk_indexes: list[ChunkIndex],
                metadata_indexes: list[MetadataIndex]) -> None:
    """DataEnd (CRC of everything before it), the summary section, its offsets, the footer and
    the closing magic: what a finished file ends with and a cut one lacks."""
    out.write(_record(OP_DATA_END, struct.pack("<I", out.crc)))
    summary_start = out.offset
    out.crc = 0
    groups = []
    for opcode, records in (
            (OP_SCHEMA, [_schema_record(s) for _, s in sorted(schemas.items())]),
            (OP_CHANNEL, [_channel_record(c) for _, c in sorted(channels.items())]),
            (OP_STATISTICS, [_statistics_record(statistics)]),
            (OP_CHUNK_INDEX, [_chunk_index_record(c) for c in chunk_indexes]),
            (OP_METADATA_INDEX, [_metadata_index_record(m) for m in metadata_indexes])):
        if records:
            start = out.offset
            for record in records:
                out.write(record)
            groups.append((opcode, start, out.offset - start))
    offsets_start = out.offset
    for opcode, start, length in groups:
        out.write(_record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", opcode, start, length)))
    out.write(RECORD_HEAD.pack(OP_FOOTER, 20) + struct.pack("<QQ", summary_start, offsets_start))
    out.stream.write(struct.pack("<I", out.crc) + MAGIC)


class Writer:
    """Writes one MCAP file: schemas and channels as they are added (in the data section, outside
    the chunks, so that a cut file keeps every one a complete chunk refers to), messages and
    metadata into zstd chunks of about `chunk_size` uncompressed bytes, the summary at finish()."""

    def __init__(self, stream: BinaryIO, *, profile: str = "horus", library: str = "horus",
                 chunk_size: int = DEFAULT_CHUNK_SIZE, compression: str = "zstd") -> None:
        if compression not in ("zstd", ""):
            raise ValueError(f"compression must be 'zstd' or '' (none), got {compression!r}")
        self._out = _CrcFile(stream, 0)
        self._out.write(MAGIC)
        self._out.write(_record(OP_HEADER, _string(profile) + _string(library)))
        self._chunk_size, self._compression = chunk_size, compression
        self._compressor = None
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.statistics = Statistics()
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._chunk = bytearray()
        self._chunk_stats = Statistics()
        self._chunk_index: dict[int, list[tuple[int, int]]] = {}
        self._finished = False

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(len(self.schemas) + 1, name, encoding, bytes(data))
        self.schemas[schema.id] = schema
        self.statistics.schema_count += 1
        self._out.write(_schema_record(schema))
        return schema.id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int,
                    metadata: dict[str, str] | None = None) -> int:
        if schema_id and schema_id not in self.schemas:
            raise ValueError(f"channel '{topic}': no schema with id {schema_id}")
        channel = Channel(len(self.channels), schema_id, topic, message_encoding,
                          dict(metadata or {}))
        self.channels[channel.id] = channel
        self.statistics.channel_count += 1
        self._out.write(_channel_record(channel))
        return channel.id

    def add_message(self, channel_id: int, log_time: int, data: bytes, *,
                    publish_time: int | None = None, sequence: int = 0) -> None:
        if channel_id not in self.channels:
            raise ValueError(f"no channel with id {channel_id}")
        message = Message(channel_id, sequence & 0xFFFFFFFF, log_time,
                          log_time if publish_time is None else publish_time, bytes(data))
        self._chunk_index.setdefault(channel_id, []).append((log_time, len(self._chunk)))
        self._chunk += _message_record(message)
        self.statistics.count(message)
        self._chunk_stats.count(message)
        if len(self._chunk) >= self._chunk_size:
            self._flush_chunk()

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        """A metadata record, in the data section outside the chunks (indexed in the summary)."""
        record = _metadata_record(Metadata(name, {k: str(v) for k, v in values.items()}))
        offset = self._out.write(record)
        self._metadata_indexes.append(MetadataIndex(offset, len(record), name))
        self.statistics.metadata_count += 1

    def _flush_chunk(self) -> None:
        if not self._chunk:
            return
        records = bytes(self._chunk)
        if self._compression == "zstd":
            if self._compressor is None:
                import zstandard
                self._compressor = zstandard.ZstdCompressor(level=3)
            compressed = self._compressor.compress(records)
        else:
            compressed = records
        content = (struct.pack("<QQQI", self._chunk_stats.message_start_time,
                               self._chunk_stats.message_end_time, len(records),
                               zlib.crc32(records))
                   + _string(self._compression) + struct.pack("<Q", len(compressed)) + compressed)
        chunk_record = _record(OP_CHUNK, content)
        chunk_start = self._out.write(chunk_record)
        offsets = {}
        for channel_id, entries in sorted(self._chunk_index.items()):
            body = b"".join(struct.pack("<QQ", t, o) for t, o in entries)
            offsets[channel_id] = self._out.write(
                _record(OP_MESSAGE_INDEX, struct.pack("<HI", channel_id, len(body)) + body))
        self._chunk_indexes.append(ChunkIndex(
            self._chunk_stats.message_start_time, self._chunk_stats.message_end_time, chunk_start,
            len(chunk_record), offsets, self._out.offset - chunk_start - len(chunk_record),
            self._compression, len(compressed), len(records)))
        self.statistics.chunk_count += 1
        self._chunk.clear()
        self._chunk_stats = Statistics()
        self._chunk_index = {}

    def finish(self) -> None:
        """Writes the last chunk and the summary; the stream is left open (and flushed)."""
        if self._finished:
            return
        self._flush_chunk()
        _write_tail(self._out, self.schemas, self.channels, self.statistics, self._chunk_indexes,
                    self._metadata_indexes)
        self._out.stream.flush()
        self._finished = True


# ---------------------------------------------------------------------------------------------
# Reading


def _read_exact(stream: BinaryIO, size: int) -> bytes:
    data = stream.read(size)
    return data if len(data) == size else b""


def read_summary(path: str) -> Summary | None:
    """The summary of a finished file (CRC checked), or None when the file has no footer (cut)
    or its summary section is empty. Raises McapError when footer or summary are corrupt."""
    with open(path, "rb") as stream:
        size = stream.seek(0, os.SEEK_END)
        if size < len(MAGIC) * 2 + FOOTER_SIZE:
            return None
        stream.seek(size - len(MAGIC) - FOOTER_SIZE)
        footer = stream.read(FOOTER_SIZE + len(MAGIC))
        if footer[-len(MAGIC):] != MAGIC or footer[0] != OP_FOOTER:
            return None
        summary_start, _, crc = struct.unpack_from("<QQI", footer, RECORD_HEAD.size)
        if summary_start == 0:
            return None
        footer_start = size - len(MAGIC) - FOOTER_SIZE
        if summary_start > footer_start:
            raise McapError(f"footer: summary start {summary_start} is past the footer")
        stream.seek(summary_start)
        summary = stream.read(footer_start - summary_start)
        if crc != 0:
            computed = zlib.crc32(footer[:FOOTER_SIZE - 4], zlib.crc32(summary))
            if computed != crc:
                raise McapError(f"summary CRC mismatch (footer says {crc:08x}, "
                                f"summary has {computed:08x})")
    result = Summary({}, {}, None, [], [])
    at = 0
    while at < len(summary):
        if at + RECORD_HEAD.size > len(summary):
            raise McapError(f"summary: record at offset {summary_start + at} is cut")
        opcode, length = RECORD_HEAD.unpack_from(summary, at)
        content = summary[at + RECORD_HEAD.size:at + RECORD_HEAD.size + length]
        if len(content) != length:
            raise McapError(f"summary: record at offset {summary_start + at} is cut")
        if opcode == OP_SCHEMA:
            schema = _parse_schema(content)
            result.schemas[schema.id] = schema
        elif opcode == OP_CHANNEL:
            channel = _parse_channel(content)
            result.channels[channel.id] = channel
        elif opcode == OP_STATISTICS:
            result.statistics = _parse_statistics(content)
        elif opcode == OP_CHUNK_INDEX:
            result.chunk_indexes.append(_parse_chunk_index(content))
        elif opcode == OP_METADATA_INDEX:
            result.metadata_indexes.append(_parse_metadata_index(content))
        at += RECORD_HEAD.size + length
    return result


def read_metadata_record(path: str, index: MetadataIndex) -> Metadata:
    with open(path, "rb") as stream:
        stream.seek(index.offset)
        raw = _read_exact(stream, index.length)
    if not raw or raw[0] != OP_METADATA:
        raise McapError(f"metadata index '{index.name}' points at offset {index.offset}, "
                        "where no metadata record is")
    return _parse_metadata(raw[RECORD_HEAD.size:])


class Reader:
    """Walks a file's data section from the start, yielding its records in order (chunk contents
    expanded): Header, Schema, Channel, Message, Metadata. It needs no summary. When the walk is
    done, the attributes tell what it found: the schemas, channels, metadata, statistics, chunk
    and metadata indexes (all rebuilt from the data section, as `repair` writes them), whether
    the file ended properly (`finished`: data end, summary and footer all there and valid) and
    `data_end`, where the complete records end (a cut file's incomplete tail starts there).

    Every chunk's CRC is checked (and the data section's when the file has one); a mismatch raises
    McapError naming the offset."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.header: Header | None = None
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.metadata: list[Metadata] = []
        self.statistics = Statistics()
        self.chunk_indexes: list[ChunkIndex] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.finished = False
        self.has_data_end = False
        self.data_end = 0
        self.cut_bytes = 0  # bytes after the last complete record (a cut file's partial record)
        self.data_crc = 0

    def __iter__(self) -> Iterator[Header | Schema | Channel | Message | Metadata]:
        with open(self.path, "rb") as stream:
            size = stream.seek(0, os.SEEK_END)
            stream.seek(0)
            if stream.read(len(MAGIC)) != MAGIC:
                raise McapError(f"{self.path}: not an MCAP file (bad magic)")
            crc = zlib.crc32(MAGIC)
            offset = len(MAGIC)
            last_chunk: ChunkIndex | None = None
            while True:
                head = _read_exact(stream, RECORD_HEAD.size)
                if not head:
                    break
                opcode, length = RECORD_HEAD.unpack(head)
                if length > size - offset - RECORD_HEAD.size:
                    break
                content = _read_exact(stream, length)
                where = f"{self.path}: offset {offset}"
                if opcode == OP_DATA_END:
                    self.has_data_end = True
                    self.data_end = offset
                    (expected,) = struct.unpack_from("<I", content)
                    if expected and expected != crc:
                        raise McapError(f"{where}: data section CRC mismatch (data end says "
                                        f"{expected:08x}, data has {crc:08x})")
                    self.data_crc = crc
                    break
                crc = zlib.crc32(content, zlib.crc32(head, crc))
                if opcode != OP_MESSAGE_INDEX:
                    last_chunk = None
                if opcode == OP_CHUNK:
                    last_chunk = self._chunk_index(content, offset, RECORD_HEAD.size + length)
                    yield from self._chunk(content, where)
                elif opcode == OP_MESSAGE_INDEX:
                    if last_chunk is not None:
                        (channel_id,) = struct.unpack_from("<H", content)
                        last_chunk.message_index_offsets[channel_id] = offset
                        last_chunk.message_index_length += RECORD_HEAD.size + length
                elif opcode == OP_METADATA:
                    self.metadata_indexes.append(MetadataIndex(
                        offset, RECORD_HEAD.size + length, _parse_metadata(content).name))
                    yield from self._record(opcode, content, where)
                else:
                    yield from self._record(opcode, content, where)
                offset += RECORD_HEAD.size + length
                self.data_end = offset
            if self.has_data_end:
                try:
                    self.finished = read_summary(self.path) is not None
                except McapError:
                    self.finished = False
            else:
                self.cut_bytes = size - self.data_end
                self.data_crc = crc

    def _chunk_index(self, content: bytes, offset: int, record_length: int) -> ChunkIndex:
        f = _Fields(content, "chunk")
        start, end, uncompressed, _ = f.unpack("QQQI")
        compression = f.string()
        compressed = f.unpack("Q")
        index = ChunkIndex(start, end, offset, record_length, {}, 0, compression, compressed,
                           uncompressed)
        self.chunk_indexes.append(index)
        self.statistics.chunk_count += 1
        return index

    def _chunk(self, content: bytes, where: str):
        f = _Fields(content, f"{where}: chunk")
        _, _, uncompressed_size, expected_crc = f.unpack("QQQI")
        compression = f.string()
        records = _decompress(compression, f.take(f.unpack("Q")), uncompressed_size, where)
        if len(records) != uncompressed_size:
            raise McapError(f"{where}: chunk holds {len(records)} bytes, its header says "
                            f"{uncompressed_size}")
        if expected_crc and zlib.crc32(records) != expected_crc:
            raise McapError(f"{where}: chunk CRC mismatch")
        at = 0
        while at < len(records):
            if at + RECORD_HEAD.size > len(records):
                raise McapError(f"{where}: chunk ends inside a record")
            opcode, length = RECORD_HEAD.unpack_from(records, at)
            body = records[at + RECORD_HEAD.size:at + RECORD_HEAD.size + length]
            if len(body) != length:
                raise McapError(f"{where}: chunk ends inside a record")
            yield from self._record(opcode, body, f"{where} (chunk record at {at})")
            at += RECORD_HEAD.size + length

    def _record(self, opcode: int, content: bytes, where: str):
        if opcode == OP_HEADER:
            self.header = _parse_header(content)
            yield self.header
        elif opcode == OP_SCHEMA:
            schema = _parse_schema(content)
            if schema.id not in self.schemas:
                self.schemas[schema.id] = schema
                self.statistics.schema_count += 1
            yield schema
        elif opcode == OP_CHANNEL:
            channel = _parse_channel(content)
            if channel.id not in self.channels:
                self.channels[channel.id] = channel
                self.statistics.channel_count += 1
            yield channel
        elif opcode == OP_MESSAGE:
            message = _parse_message(content)
            if message.channel_id not in self.channels:
                raise McapError(f"{where}: message on channel {message.channel_id}, which no "
                                "channel record before it defines")
            self.statistics.count(message)
            yield message
        elif opcode == OP_METADATA:
            metadata = _parse_metadata(content)
            self.metadata.append(metadata)
            self.statistics.metadata_count += 1
            yield metadata
        # Attachments and records of later spec versions are skipped, as the spec asks.


def messages(path: str) -> Iterator[tuple[Channel, Message]]:
    """Every message of the file in file order, with its channel."""
    reader = Reader(path)
    for record in reader:
        if isinstance(record, Message):
            yield reader.channels[record.channel_id], record


def repair(path: str, output: str | None = None) -> Reader:
    """Gives a file cut before its end (no data-end record, summary or footer) the tail a finished
    file has, keeping every complete record; written in place (the incomplete last record cut
    off) or, with `output`, into a copy. Returns the reader that walked it. Raises McapError for a
    file that needs no repair or is corrupt before its cut."""
    reader = Reader(path)
    for _ in reader:
        pass
    if reader.finished:
        raise McapError(f"{path}: the file is complete (summary and footer present); "
                        "nothing to repair")
    if output is not None:
        with open(path, "rb") as source, open(output, "wb") as target:
            remaining = reader.data_end
            while remaining:
                piece = source.read(min(remaining, 1 << 22))
                if not piece:
                    raise McapError(f"{path}: shrank while being copied")
                target.write(piece)
                remaining -= len(piece)
        target_path = output
    else:
        target_path = path
    with open(target_path, "r+b") as stream:
        stream.truncate(reader.data_end)
        stream.seek(reader.data_end)
        _write_tail(_CrcFile(stream, reader.data_end, reader.data_crc), reader.schemas,
                    reader.channels, reader.statistics, reader.chunk_indexes,
                    reader.metadata_indexes)
    return reader
