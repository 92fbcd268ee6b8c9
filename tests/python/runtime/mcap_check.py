"""The independent check of a recording file, shared by the suites that read files
with PyPI `mcap` (pytest_runtime_recording, pytest_record): every CRC, the summary's too, and
every index pointing where it says."""
from __future__ import annotations

import io
import struct
import zlib

import zstandard
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd, Footer, MessageIndex
from mcap.stream_reader import StreamReader


def check_file(path) -> dict:
    """Reads `path` with PyPI mcap, checking every CRC (chunks, data section, and the summary's,
    which the library does not check), that each chunk index points at its chunk and message
    indexes, and that each message index entry points at a message of that time. Returns
    {topic: [(sequence, log_time, bytes)]}."""
    with open(path, "rb") as f:
        data = f.read()
    records = list(StreamReader(io.BytesIO(data), validate_crcs=True).records)
    assert isinstance(records[-1], Footer) and any(isinstance(r, DataEnd) for r in records)
    footer = records[-1]
    summary_crc = zlib.crc32(data[footer.summary_start:len(data) - 8 - 4])
    assert footer.summary_crc == summary_crc

    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    header = reader.get_header()
    assert header.profile == "horus" and header.library.startswith("horus ")
    summary = reader.get_summary()
    assert summary is not None and summary.chunk_indexes
    for index in summary.chunk_indexes:
        piece = data[index.chunk_start_offset:index.chunk_start_offset + index.chunk_length
                     + index.message_index_length]
        chunk_records = records_until_end(io.BytesIO(piece), skip_magic=True, emit_chunks=True)
        assert isinstance(chunk_records[0], Chunk)
        chunk = chunk_records[0]
        assert chunk.compression == "zstd"
        assert (chunk.message_start_time, chunk.message_end_time) == (index.message_start_time,
                                                                      index.message_end_time)
        indexes = {r.channel_id: r for r in chunk_records[1:] if isinstance(r, MessageIndex)}
        assert set(indexes) == set(index.message_index_offsets)
        for channel_id, offset in index.message_index_offsets.items():
            assert data[offset] == 0x07  # a MessageIndex record at the offset the index names
        plain = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        for channel_id, entries in indexes.items():
            for log_time, offset in entries.records:
                assert plain[offset] == 0x05
                channel, _, time_at = struct.unpack_from("<HIQ", plain, offset + 9)
                assert (channel, time_at) == (channel_id, log_time)

    stats = summary.statistics
    messages: dict[str, list] = {}
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        messages.setdefault(channel.topic, []).append(
            (message.sequence, message.log_time, message.data, schema, channel))
    assert stats.message_count == sum(len(v) for v in messages.values())
    assert stats.chunk_count == len(summary.chunk_indexes)
    return messages


def records_until_end(source, **options) -> list:
    """The records of a stream that has no footer (a piece of a file, a cut file), up to its
    end or to the record that was cut short."""
    out = []
    try:
        for record in StreamReader(source, **options).records:
            out.append(record)
    except EndOfFile:
        pass
    return out
