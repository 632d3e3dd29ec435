"""MCAP logs of the key space: record, read, recover after a crash, summarise.

- One channel per Zenoh key, ``message_encoding = "msgpack"``, with a schema of empty
  encoding and empty data (msgpack is self-describing; the schema's name is the message
  kind, e.g. ``cekm.field/target``). Other channels (the Foxglove views of
  :mod:`cekm_swarm.runtime.foxglove_view`) go through :meth:`McapRecorder.write_encoded`.
- ``log_time`` and ``publish_time`` are sim time in integer nanoseconds.
- Chunked, indexed, zstd-compressed, written by :class:`.mcap_writer.ChunkedWriter` (the
  bytes of ``mcap.writer.Writer``, with a message path about twice as fast). Loss on a
  crash is bounded: a chunk is written out when it exceeds ``chunk_size`` bytes, and
  :meth:`McapRecorder.maybe_flush` (called on every write, and by :func:`record_zenoh` on
  a timer) closes the open chunk and flushes it to the OS at least every
  ``flush_interval`` seconds. A killed writer leaves a
  file with no footer; :func:`read_messages` still streams it up to the cut and
  :func:`recover_log` rewrites an indexed copy.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, SeekingReader, make_reader
from mcap.records import Attachment, Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from cekm_swarm.protocol import DEFAULT_KEYS, KeySpace, KeySpaceError, peek

from .errors import McapLogError
from .mcap_writer import COMPRESSIONS, ChunkedWriter

MSGPACK = "msgpack"
"""MCAP message encoding of the key-space channels."""

PROFILE = ""
LIBRARY = "cekm-swarm mcap_log"
DEFAULT_CHUNK_SIZE = 64 * 1024
DEFAULT_FLUSH_INTERVAL = 0.5
_MAGIC = b"\x89MCAP0\r\n"


MAX_NS = (1 << 64) - 1
"""MCAP timestamps are unsigned 64-bit nanoseconds (about 584 years)."""
MAX_CHANNELS = 4096
"""Key channels a recorder registers at most (MCAP channel ids are 16-bit): a peer that
invents keys must not grow the channel table without end. Further keys are refused and
counted in :attr:`McapRecorder.refused`."""


def sim_ns(t: float) -> int:
    """Sim time in seconds -> integer nanoseconds (MCAP timestamps), clamped to [0, MAX_NS]
    (a time no writer can hold never reaches it: NaN is 0, anything huge is MAX_NS)."""
    if not t > 0:  # also NaN
        return 0
    if t >= MAX_NS / 1e9:
        return MAX_NS
    return min(int(round(t * 1e9)), MAX_NS)


@dataclass(frozen=True, slots=True)
class SchemaSpec:
    """A schema to register for a channel: name, encoding (``""`` = none) and data."""

    name: str
    encoding: str = ""
    data: bytes = b""


class McapRecorder:
    """Writes one MCAP file; a context manager. Not thread-safe: use one thread (or loop)."""

    def __init__(self, path: str | Path, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 flush_interval: float | None = DEFAULT_FLUSH_INTERVAL, compression: str = "zstd",
                 keys: KeySpace = DEFAULT_KEYS, metadata: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        self.keys = keys
        self.flush_interval = flush_interval
        if compression not in COMPRESSIONS:  # before the file is opened
            raise McapLogError(str(path), f"compression {compression!r}: use {' or '.join(COMPRESSIONS)}")
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: IO[bytes] | None = open(self.path, "wb")
        except OSError as exc:
            raise McapLogError(str(path), f"cannot open for writing: {exc.strerror or exc}") from None
        self._writer = ChunkedWriter(self._file, chunk_size=chunk_size, compression=compression)
        self._writer.start(profile=PROFILE, library=LIBRARY)
        if metadata:
            self._writer.add_metadata("cekm", {str(k): str(v) for k, v in metadata.items()})
        self._schemas: dict[SchemaSpec, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}  # topic -> (channel id, message encoding)
        self._sequence: dict[int, int] = {}
        self._last_flush = time.monotonic()
        self.messages = 0
        self.refused = 0  # messages on new keys beyond MAX_CHANNELS, not written

    # ------------------------------------------------------------------ channels

    def _schema_id(self, spec: SchemaSpec) -> int:
        sid = self._schemas.get(spec)
        if sid is None:
            sid = self._schemas[spec] = self._writer.register_schema(spec.name, spec.encoding, spec.data)
        return sid

    def channel(self, topic: str, message_encoding: str, schema: SchemaSpec) -> int:
        """The channel id of ``topic``, registering channel (and schema) on first use."""
        entry = self._channels.get(topic)
        if entry is not None:
            if entry[1] != message_encoding:
                raise McapLogError(str(self.path), f"topic '{topic}' already has message encoding '{entry[1]}', "
                                                   f"not '{message_encoding}'")
            return entry[0]
        cid = self._writer.register_channel(topic, message_encoding, self._schema_id(schema))
        self._channels[topic] = (cid, message_encoding)
        self._sequence[cid] = 0
        return cid

    def _msgpack_schema(self, key: str) -> SchemaSpec:
        try:
            kind = self.keys.parse(key).kind.value
        except KeySpaceError:
            kind = "unknown"
        return SchemaSpec(f"cekm.{kind}")

    # ------------------------------------------------------------------ writing

    def write(self, key: str, payload: bytes, sim_time: float, publish_time: float | None = None) -> bool:
        """Record msgpack ``payload`` received on ``key`` at ``sim_time`` seconds. False
        (counted in :attr:`refused`) for a new key once :data:`MAX_CHANNELS` are in use."""
        entry = self._channels.get(key)
        if entry is None and len(self._channels) >= MAX_CHANNELS:
            self.refused += 1
            return False
        cid = entry[0] if entry is not None and entry[1] == MSGPACK else self.channel(key, MSGPACK,
                                                                                     self._msgpack_schema(key))
        self._add(cid, payload, sim_time, sim_time if publish_time is None else publish_time)
        return True

    def write_encoded(self, topic: str, message_encoding: str, schema: SchemaSpec, data: bytes,
                      sim_time: float) -> None:
        """Record a message of any encoding (e.g. protobuf Foxglove views) on ``topic``."""
        self._add(self.channel(topic, message_encoding, schema), data, sim_time, sim_time)

    def _add(self, cid: int, data: bytes, log_time: float, publish_time: float) -> None:
        if self._file is None:
            raise McapLogError(str(self.path), "recorder is closed")
        seq = self._sequence[cid] = (self._sequence[cid] + 1) & 0xFFFFFFFF
        log_ns = sim_ns(log_time)
        self._writer.add_message(cid, log_ns, data, log_ns if publish_time == log_time else sim_ns(publish_time), seq)
        self.messages += 1
        self.maybe_flush()

    def add_raw(self, channel_id: int, data: bytes, log_time_ns: int, publish_time_ns: int, sequence: int) -> None:
        """Add a message with times already in nanoseconds (for copying between logs)."""
        if self._file is None:
            raise McapLogError(str(self.path), "recorder is closed")
        self._writer.add_message(channel_id, log_time=log_time_ns, data=data, publish_time=publish_time_ns,
                                 sequence=sequence)
        self.messages += 1

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record (e.g. scenario, seed) in the file."""
        self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time_ns: int = 0,
                       create_time_ns: int = 0) -> None:
        """An attachment record (for copying between logs)."""
        self._writer.add_attachment(create_time=create_time_ns, log_time=log_time_ns, name=name,
                                    media_type=media_type, data=data)

    def flush(self) -> None:
        """Close the open chunk and push everything to the OS (survives a killed process)."""
        if self._file is not None:
            self._writer.flush()
            self._last_flush = time.monotonic()

    def maybe_flush(self, now: float | None = None) -> bool:
        """:meth:`flush` if ``flush_interval`` seconds passed since the last one; True if it did."""
        if self.flush_interval is None:
            return False
        now = time.monotonic() if now is None else now
        if now - self._last_flush >= self.flush_interval:
            self.flush()
            return True
        return False

    @property
    def topics(self) -> list[str]:
        """Topics with a channel so far."""
        return list(self._channels)

    def close(self) -> None:
        """Write the summary (indexes, statistics) and close the file (idempotent)."""
        if self._file is None:
            return
        try:
            self._writer.finish()
        finally:
            self._file.close()
            self._file = None

    def __enter__(self) -> "McapRecorder":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


async def record_zenoh(session: Any, recorder: McapRecorder, key_expr: str | None = None, *,
                       stop: asyncio.Event, flush_every: float | None = None) -> int:
    """Record every sample on ``key_expr`` (default: the whole key space) until ``stop`` is set.

    Each message is filed at the sim time of its own ``stamp``; a message whose stamp
    cannot be read (malformed) is filed at the latest sim time seen, so nothing the
    network carried is left out. Returns the number of messages recorded."""
    from .bridge import AsyncSubscription

    key_expr = key_expr or recorder.keys.everything()
    period = flush_every or recorder.flush_interval or DEFAULT_FLUSH_INTERVAL
    last_stamp = 0.0
    n = 0
    stopper = asyncio.ensure_future(stop.wait())
    with AsyncSubscription(session, key_expr) as sub:
        try:
            while not stop.is_set():
                getter = asyncio.ensure_future(sub.get())
                done, _ = await asyncio.wait({getter, stopper}, timeout=period, return_when=asyncio.FIRST_COMPLETED)
                if getter not in done:
                    getter.cancel()
                    recorder.maybe_flush()
                    continue
                rec = getter.result()
                if rec.kind != "put":
                    continue
                _, stamp = peek(rec.payload)
                if stamp is not None:
                    last_stamp = stamp
                recorder.write(rec.key, rec.payload, last_stamp if stamp is None else stamp)
                n += 1
            while (rec := sub.get_nowait()) is not None:  # what arrived before stop
                if rec.kind == "put":
                    _, stamp = peek(rec.payload)
                    recorder.write(rec.key, rec.payload, last_stamp if stamp is None else stamp)
                    n += 1
        finally:
            stopper.cancel()
            recorder.flush()
    return n


# --------------------------------------------------------------------------- reading


@dataclass(frozen=True, slots=True)
class LoggedMessage:
    """One message read back from a log (times in integer nanoseconds of sim time)."""

    topic: str
    log_time: int
    publish_time: int
    sequence: int
    data: bytes
    message_encoding: str
    schema_name: str | None
    schema_encoding: str | None


def _has_footer(path: Path) -> bool:
    """True when the file ends with a footer record (the writer finished), read with the
    mcap library's seeking reader, which looks for the footer at the end of the file."""
    with open(path, "rb") as f:
        try:
            SeekingReader(f).get_summary()
        except Exception:  # no footer where it belongs: McapError, EndOfFile, struct/seek errors ...
            return False
    return True


def _open(path: str | Path) -> Path:
    path = Path(path)
    if not path.is_file():
        raise McapLogError(str(path), "no such file")
    with open(path, "rb") as f:
        if f.read(len(_MAGIC)) != _MAGIC:
            raise McapLogError(str(path), "not an MCAP file (bad magic)")
    return path


def is_complete(path: str | Path) -> bool:
    """True when the log was closed properly (footer and summary present)."""
    return _has_footer(_open(path))


def _convert(schema: Any, channel: Any, message: Any) -> LoggedMessage:
    return LoggedMessage(channel.topic, message.log_time, message.publish_time, message.sequence, message.data,
                         channel.message_encoding, schema.name if schema is not None else None,
                         schema.encoding if schema is not None else None)


def _cut_reason(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text}" if text else f"{type(exc).__name__}: the file ends inside a record"


@dataclass
class StreamResult:
    """Filled by :func:`stream_messages`: whether the file ended cleanly, and the error at the cut."""

    complete: bool = True
    error: str | None = None
    messages: int = 0


def stream_messages(path: str | Path, result: StreamResult | None = None) -> Iterator[LoggedMessage]:
    """Every message in file order with the non-seeking reader, up to a cut if the writer died.

    Works on complete and truncated files alike; ``result`` (if given) tells how it ended."""
    path = _open(path)
    result = result if result is not None else StreamResult()
    with open(path, "rb") as f:
        reader = NonSeekingReader(f, validate_crcs=True)
        try:
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                result.messages += 1
                yield _convert(schema, channel, message)
        except Exception as exc:  # the cut: McapError, EndOfFile, struct.error, zstd errors ...
            result.complete = False
            result.error = _cut_reason(exc)
    if result.complete and not _has_footer(path):
        result.complete = False
        result.error = result.error or "no footer"


def read_messages(path: str | Path, *, topics: Iterable[str] | None = None,
                  encodings: Iterable[str] | None = None) -> Iterator[LoggedMessage]:
    """Messages of a log in log-time order (complete file) or file order (a truncated file,
    read up to the cut), optionally only some topics or message encodings."""
    path = _open(path)
    topic_set = set(topics) if topics is not None else None
    enc_set = set(encodings) if encodings is not None else None

    def wanted(m: LoggedMessage) -> bool:
        return (topic_set is None or m.topic in topic_set) and (enc_set is None or m.message_encoding in enc_set)

    if not _has_footer(path):
        yield from (m for m in stream_messages(path) if wanted(m))
        return
    with open(path, "rb") as f:
        try:
            reader = make_reader(f)
            it = reader.iter_messages(topics=list(topic_set) if topic_set is not None else None, log_time_order=True)
            for schema, channel, message in it:
                m = _convert(schema, channel, message)
                if wanted(m):
                    yield m
        except McapError as exc:
            raise McapLogError(str(path), f"unreadable: {exc}") from None


@dataclass(frozen=True, slots=True)
class RecoveryReport:
    """What :func:`recover_log` did: messages, channels, metadata and attachment records
    copied, and how the input ended (``cut_reason`` None when it was complete)."""

    source: Path
    output: Path
    messages: int
    channels: int
    input_complete: bool
    cut_reason: str | None
    metadata: int = 0
    attachments: int = 0


def recover_log(path: str | Path, output: str | Path | None = None, *,
                chunk_size: int = DEFAULT_CHUNK_SIZE) -> RecoveryReport:
    """Rewrite a (possibly truncated) log as a complete, indexed file.

    Reads the input's records in file order with the mcap library's stream reader (no
    index or footer needed) and writes every complete message, with its channel, schema,
    times and sequence, and every metadata and attachment record into ``output``
    (default ``<name>.recovered.mcap``). A record cut in the middle (the writer was
    killed while writing it, or its chunk was still in memory) ends the copy: what came
    before is kept. The input is left untouched."""
    src = _open(path)
    out = Path(output) if output is not None else src.with_name(src.stem + ".recovered.mcap")
    if out.resolve() == src.resolve():
        raise McapLogError(str(src), "recovery output must differ from the input")
    schemas: dict[int, SchemaSpec] = {}
    channels: dict[int, int] = {}  # input channel id -> output channel id
    footer, cut = False, None
    n = n_meta = n_att = 0
    with McapRecorder(out, chunk_size=chunk_size, flush_interval=None) as rec, open(src, "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Message):
                    cid = channels.get(record.channel_id)
                    if cid is None:
                        raise McapError(f"message on channel {record.channel_id}, which has no channel record")
                    rec.add_raw(cid, record.data, record.log_time, record.publish_time, record.sequence)
                    n += 1
                elif isinstance(record, Schema):
                    schemas[record.id] = SchemaSpec(record.name, record.encoding, bytes(record.data))
                elif isinstance(record, Channel):
                    spec = schemas.get(record.schema_id, SchemaSpec("")) if record.schema_id else SchemaSpec("")
                    channels[record.id] = rec.channel(record.topic, record.message_encoding, spec)
                elif isinstance(record, Metadata):
                    rec.add_metadata(record.name, dict(record.metadata))
                    n_meta += 1
                elif isinstance(record, Attachment):
                    rec.add_attachment(record.name, record.media_type, bytes(record.data), record.log_time,
                                       record.create_time)
                    n_att += 1
                elif isinstance(record, Footer):
                    footer = True
        except Exception as exc:  # the cut: EndOfFile, McapError (bad CRC), struct.error, zstd errors ...
            cut = _cut_reason(exc)
        n_channels = len(rec.topics)
    if cut is None and not footer:
        cut = "no footer"
    return RecoveryReport(src, out, n, n_channels, cut is None, cut, n_meta, n_att)


# --------------------------------------------------------------------------- summary


@dataclass(frozen=True, slots=True)
class ChannelInfo:
    """One channel of a log: count, first/last sim time (s), mean rate (Hz)."""

    topic: str
    message_encoding: str
    schema_name: str | None
    count: int
    first: float
    last: float

    @property
    def rate(self) -> float:
        """Mean rate over the channel's own span (0 for fewer than 2 messages)."""
        span = self.last - self.first
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


@dataclass(frozen=True, slots=True)
class LogInfo:
    """Summary of a log: channels, counts, rates, start/end sim time and duration."""

    path: Path
    size_bytes: int
    complete: bool
    messages: int
    start: float
    end: float
    channels: tuple[ChannelInfo, ...] = field(default=())
    cut_reason: str | None = None

    @property
    def duration(self) -> float:
        """end - start, in seconds of sim time."""
        return self.end - self.start


def log_info(path: str | Path) -> LogInfo:
    """Summarise a log (complete or truncated) by streaming its messages once."""
    src = _open(path)
    result = StreamResult()
    stats: dict[str, list[Any]] = {}
    for m in stream_messages(src, result):
        s = stats.get(m.topic)
        if s is None:
            stats[m.topic] = [m.message_encoding, m.schema_name, 1, m.log_time, m.log_time]
        else:
            s[2] += 1
            s[3] = min(s[3], m.log_time)
            s[4] = max(s[4], m.log_time)
    channels = tuple(ChannelInfo(t, s[0], s[1], s[2], s[3] / 1e9, s[4] / 1e9) for t, s in sorted(stats.items()))
    start = min((c.first for c in channels), default=0.0)
    end = max((c.last for c in channels), default=0.0)
    return LogInfo(src, src.stat().st_size, result.complete, sum(c.count for c in channels), start, end, channels,
                   result.error)


def format_log_info(info: LogInfo) -> str:
    """A human-readable table of :func:`log_info`'s result."""
    lines = [f"{info.path}: {info.size_bytes / 1024:.1f} KiB, "
             f"{'complete' if info.complete else 'INCOMPLETE (writer did not finish: ' + str(info.cut_reason) + ')'}",
             f"messages {info.messages}, channels {len(info.channels)}, sim time {info.start:.3f} .. {info.end:.3f} s "
             f"(duration {info.duration:.3f} s)"]
    if info.channels:
        w = max(len(c.topic) for c in info.channels)
        lines.append(f"  {'topic':<{w}}  {'encoding':<9} {'count':>7} {'rate Hz':>9} {'first s':>9} {'last s':>9}  schema")
        for c in info.channels:
            lines.append(f"  {c.topic:<{w}}  {c.message_encoding:<9} {c.count:>7} {c.rate:>9.2f} {c.first:>9.3f} "
                         f"{c.last:>9.3f}  {c.schema_name or '-'}")
    return "\n".join(lines)
