"""A chunked MCAP writer with a fast message path, byte for byte the file ``mcap.writer.Writer``
writes (with its defaults: every index, repeated schemas and channels, statistics,
summary offsets, CRCs on chunks and the summary, none on the data section).

Why: the world server records every message of a run (about 30 per robot per tick, 500
a tick with 16 robots), and ``Writer.add_message`` builds a ``Message`` dataclass and
writes it field by field through ``RecordBuilder``: about 17 us a message on a warm
cache, three times that in the world's tick. Here a message is one ``struct`` pack and
two appends to the open chunk's buffer. Everything that is not per message (header,
schemas, channels, metadata, attachments, chunk and summary records) is written with
``mcap.records`` exactly as ``Writer`` writes it. ``tests/runtime/test_mcap_writer.py``
holds the two writers' bytes equal over random call sequences.

Memory stays flat however long the log: the summary's chunk indexes (one per chunk, with
an offset per channel in it: about 2 KB a chunk with a hundred channels, 30 chunks a second
in a real-time run of 6 robots) go to a spooled temporary file as each chunk is written
(:data:`INDEX_SPOOL` bytes in memory, the rest on disk) and are copied into the summary at
:meth:`ChunkedWriter.finish`; the statistics are summed per chunk from its message indexes.
So the summary describes exactly the chunks written out (:meth:`ChunkedWriter.committed`),
which lets a writer that lost its disk close the file it has (:meth:`ChunkedWriter.finish`
onto the file cut back to the last chunk).
"""

from __future__ import annotations

import struct
import tempfile
import zlib
from collections.abc import Callable
from typing import IO, Any

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
_MESSAGE = struct.Struct("<BQHIQQ")  # opcode, record length, channel id, sequence, log time, publish time
_MESSAGE_FIXED = 2 + 4 + 8 + 8  # bytes of a message record after its length, before its data
_FOOTER_CRC_PREFIX = struct.Struct("<BQQQ")
INDEX_SPOOL = 256 * 1024
"""Bytes of packed chunk indexes a writer keeps in memory before they spill to a temporary file."""
_COPY = 1 << 20


def _message_index(channel_id: int, records: list[tuple[int, int]]) -> bytes:
    """A message index record: the (log time, offset in chunk) pairs of one channel in one
    chunk, packed in one call (``MessageIndex.write`` packs each number apart)."""
    n = len(records)
    flat = [v for pair in records for v in pair]
    return struct.pack(f"<BQHI{2 * n}Q", Opcode.MESSAGE_INDEX, 2 + 4 + 16 * n, channel_id, 16 * n, *flat)


COMPRESSIONS = ("zstd", "none")
"""The chunk compressions :class:`ChunkedWriter` writes."""


def _compress(kind: str) -> tuple[str, Callable[[bytes], bytes] | None]:
    """(name written in the chunk, function) of a chunk compression."""
    if kind == "zstd":
        return "zstd", zstandard.compress
    if kind == "none":
        return "", None
    raise ValueError(f"compression {kind!r}: use {' or '.join(COMPRESSIONS)}")


class ChunkedWriter:
    """Writes a chunked, indexed MCAP stream to ``stream`` (a binary file opened by the
    caller, who closes it). ``compression``: ``zstd`` or ``none``. A chunk is
    closed once its records pass ``chunk_size`` bytes, or on :meth:`flush`."""

    def __init__(self, stream: IO[bytes], *, chunk_size: int = 1024 * 1024, compression: str = "zstd") -> None:
        self._stream = stream
        self._chunk_size = chunk_size
        self._compression, self._compress = _compress(compression)
        self._out = RecordBuilder()  # records outside chunks, written out at each _flush
        self._chunk = bytearray()  # the open chunk's records
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0
        self._chunk_indexes: dict[int, list[tuple[int, int]]] = {}  # channel -> [(log time, offset in chunk)]
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._index_spool = tempfile.SpooledTemporaryFile(  # noqa: SIM115 -- the writer's, closed by finish()
            max_size=INDEX_SPOOL)  # packed ChunkIndex records
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = {}  # channel -> messages in the chunks written out
        self._messages = 0  # ... and their statistics
        self._start_time = 0
        self._end_time = 0
        self._attachments = 0
        self._metadata = 0
        self._chunks = 0
        self._committed = 0  # the stream's offset after the last complete record that reached the OS

    # ------------------------------------------------------------------ records

    def start(self, profile: str = "", library: str = "") -> None:
        """The magic and the header record."""
        self._stream.write(MAGIC)
        Header(profile, library).write(self._out)
        self._flush()
        self._commit()

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """A schema record in the open chunk (and the summary); its id, from 1."""
        sid = len(self._schemas) + 1
        schema = self._schemas[sid] = Schema(id=sid, data=data, encoding=encoding, name=name)
        self._in_chunk(schema)
        return sid

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        """A channel record in the open chunk (and the summary); its id, from 1."""
        cid = len(self._channels) + 1
        channel = self._channels[cid] = Channel(id=cid, topic=topic, message_encoding=message_encoding,
                                                schema_id=schema_id, metadata={})
        self._in_chunk(channel)
        return cid

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int = 0) -> None:
        """A message record in the open chunk, indexed by channel (the hot path)."""
        chunk = self._chunk
        if self._chunk_messages == 0 or log_time < self._chunk_start:
            self._chunk_start = log_time
        if log_time > self._chunk_end:
            self._chunk_end = log_time
        index = self._chunk_indexes.get(channel_id)
        if index is None:
            index = self._chunk_indexes[channel_id] = []
        index.append((log_time, len(chunk)))
        self._chunk_messages += 1
        chunk += _MESSAGE.pack(Opcode.MESSAGE, _MESSAGE_FIXED + len(data), channel_id, sequence, log_time,
                               publish_time)
        chunk += data
        if len(chunk) > self._chunk_size:
            self._finish_chunk()

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record (outside chunks), indexed."""
        self._flush()
        offset = self._stream.tell()
        Metadata(name=name, metadata=data).write(self._out)
        entry = MetadataIndex(offset=offset, length=self._out.count, name=name)
        self._flush()
        self._commit()
        self._metadata += 1
        self._metadata_indexes.append(entry)

    def add_attachment(self, create_time: int, log_time: int, name: str, media_type: str, data: bytes) -> None:
        """An attachment record (outside chunks), indexed."""
        self._flush()
        offset = self._stream.tell()
        Attachment(create_time=create_time, log_time=log_time, name=name, media_type=media_type,
                   data=data).write(self._out)
        entry = AttachmentIndex(offset=offset, length=self._out.count, create_time=create_time, log_time=log_time,
                                data_size=len(data), name=name, media_type=media_type)
        self._flush()
        self._commit()
        self._attachments += 1
        self._attachment_indexes.append(entry)

    def flush(self) -> None:
        """Close the open chunk (if it holds a message) and push everything to the OS."""
        self._finish_chunk()
        self._flush()
        self._stream.flush()

    @property
    def committed(self) -> int:
        """The stream's length up to the last record that reached the OS whole (a chunk
        with its message indexes, a metadata or attachment record): what :meth:`finish`
        after :meth:`lost_stream` keeps."""
        return self._committed

    @property
    def committed_messages(self) -> int:
        """Messages in the chunks written out (what the summary counts)."""
        return self._messages

    def lost_stream(self, stream: IO[bytes]) -> None:
        """Continue on ``stream``, a new handle on the same file cut back to
        :attr:`committed` (a write failed: the disk is full): the open chunk and whatever
        was not written out whole are dropped, so :meth:`finish` closes the file with the
        chunks it has."""
        self._stream = stream
        self._out = RecordBuilder()
        self._chunk = bytearray()
        self._chunk_messages = 0
        self._chunk_start = self._chunk_end = 0
        self._chunk_indexes = {}

    def finish(self) -> None:
        """The last chunk, the data end, the summary (schemas, channels, statistics, chunk,
        attachment and metadata indexes, summary offsets), the footer and the closing magic."""
        self._finish_chunk()
        DataEnd(0).write(self._out)
        self._flush()
        summary_start = self._stream.tell()
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []
        crc = 0
        written = 0  # summary bytes already streamed out (the chunk indexes)

        def group(opcode: Opcode, records: Any) -> None:
            begin = summary.count
            for record in records:
                record.write(summary)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + written + begin,
                                         group_length=summary.count - begin))

        group(Opcode.SCHEMA, self._schemas.values())
        group(Opcode.CHANNEL, self._channels.values())
        group(Opcode.STATISTICS, [Statistics(
            message_count=self._messages, schema_count=len(self._schemas), channel_count=len(self._channels),
            attachment_count=self._attachments, metadata_count=self._metadata, chunk_count=self._chunks,
            message_start_time=self._start_time, message_end_time=self._end_time,
            channel_message_counts=self._counts)])
        head = summary.end()
        crc = zlib.crc32(head, crc)
        self._stream.write(head)
        written = len(head)
        spool = self._index_spool
        spool.seek(0)
        begin = written
        while block := spool.read(_COPY):  # the chunk indexes, as they were packed chunk by chunk
            crc = zlib.crc32(block, crc)
            self._stream.write(block)
            written += len(block)
        offsets.append(SummaryOffset(group_opcode=Opcode.CHUNK_INDEX, group_start=summary_start + begin,
                                     group_length=written - begin))
        group(Opcode.ATTACHMENT_INDEX, self._attachment_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offset_start = summary_start + written + summary.count
        for offset in offsets:
            offset.write(summary)
        data = summary.end()
        crc = zlib.crc32(_FOOTER_CRC_PREFIX.pack(Opcode.FOOTER, 8 + 8 + 4, summary_start, offset_start),
                         zlib.crc32(data, crc))
        self._stream.write(data)
        Footer(summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc).write(self._out)
        self._flush()
        self._stream.write(MAGIC)
        self._stream.flush()
        self._index_spool.close()

    # ------------------------------------------------------------------ internals

    def _in_chunk(self, record: Any) -> None:
        builder = RecordBuilder()
        record.write(builder)
        self._chunk += builder.end()
        if len(self._chunk) > self._chunk_size:
            self._finish_chunk()

    def _flush(self) -> None:
        self._stream.write(self._out.end())

    def _commit(self) -> None:
        """Push what was written to the OS; its end is the new :attr:`committed`."""
        self._stream.flush()
        self._committed = self._stream.tell()

    def _finish_chunk(self) -> None:
        if self._chunk_messages == 0:
            return
        raw = bytes(self._chunk)
        packed = raw if self._compress is None else self._compress(raw)
        chunk = Chunk(compression=self._compression, data=packed, message_start_time=self._chunk_start,
                      message_end_time=self._chunk_end, uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw))
        self._flush()
        chunk_offset = self._stream.tell()
        chunk.write(self._out)
        index = ChunkIndex(message_start_time=self._chunk_start, message_end_time=self._chunk_end,
                           chunk_start_offset=chunk_offset, chunk_length=self._out.count, message_index_offsets={},
                           message_index_length=0, compression=self._compression, compressed_size=len(packed),
                           uncompressed_size=len(raw))
        self._flush()
        index_start = self._stream.tell()
        for cid, records in self._chunk_indexes.items():
            index.message_index_offsets[cid] = index_start + self._out.count
            self._out.write(_message_index(cid, records))  # = MessageIndex(cid, records).write(self._out)
        index.message_index_length = self._out.count
        self._flush()
        self._commit()  # the chunk and its message indexes are out: only now does the summary count them
        packer = RecordBuilder()
        index.write(packer)
        self._index_spool.write(packer.end())
        counts = self._counts
        for cid, records in self._chunk_indexes.items():
            counts[cid] = counts.get(cid, 0) + len(records)
        if self._messages == 0 or self._chunk_start < self._start_time:
            self._start_time = self._chunk_start
        if self._chunk_end > self._end_time:
            self._end_time = self._chunk_end
        self._messages += self._chunk_messages
        self._chunks += 1
        self._chunk = bytearray()
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0
        self._chunk_indexes = {}
