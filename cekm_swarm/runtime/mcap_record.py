"""MCAP logs of the key space, the writing side: :class:`McapRecorder` (one file) and
:func:`record_zenoh` (a live key expression into it).

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
  ``flush_interval`` seconds. A killed writer leaves a file with no footer;
  :func:`.mcap_read.read_messages` still streams it up to the cut and
  :func:`.mcap_recover.recover_log` rewrites an indexed copy.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mcap.data_stream import RecordBuilder
from mcap.records import DataEnd, Footer

from cekm_swarm.protocol import DEFAULT_KEYS, KeySpace, KeySpaceError, peek
from cekm_swarm.protocol.codec import peek_type

from .bridge import AsyncSubscription
from .errors import McapLogError
from .mcap_writer import COMPRESSIONS, MAGIC, ChunkedWriter

MSGPACK = "msgpack"
"""MCAP message encoding of the key-space channels."""

PROFILE = ""
LIBRARY = "cekm-swarm mcap_log"
DEFAULT_CHUNK_SIZE = 64 * 1024
DEFAULT_FLUSH_INTERVAL = 0.5


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


class LogFull(McapLogError):
    """The log's disk is full (or its file may grow no further: a size limit, a quota, an I/O
    error): the recorder closed the file with what it had written out whole (see
    :meth:`McapRecorder._lost`) and writes no more. ``closed`` says how the file ends:
    ``summary`` (complete, indexed), ``footer`` (complete, no index: read in file order) or
    ``cut`` (at the last whole chunk, no footer)."""

    def __init__(self, path: str, problem: str, *, closed: str, size: int, messages: int) -> None:
        self.closed, self.size, self.messages = closed, size, messages
        super().__init__(path, problem)


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.1f} kB"


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


class _At(io.BytesIO):
    """A memory stream that reports offsets from ``base`` (the tail of a file built in memory)."""

    def __init__(self, base: int) -> None:
        super().__init__()
        self.base = base

    def tell(self) -> int:
        return self.base + super().tell()


def _footer_only() -> bytes:
    """A data end and a footer with no summary, and the closing magic (45 bytes): the file is
    complete, and readers read it in file order."""
    b = RecordBuilder()
    DataEnd(0).write(b)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(b)
    return b.end() + MAGIC


class McapRecorder:
    """Writes one MCAP file; a context manager. Not thread-safe: use one thread (or loop).

    A write the OS refuses (a full disk, a file-size limit) ends the log cleanly: the file
    is cut back to the last chunk written out whole and closed with its summary, or, if
    even that does not fit, a bare footer (:meth:`_lost`); every call then raises
    :class:`LogFull`, whose message says so in one line."""

    def __init__(self, path: str | Path, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 flush_interval: float | None = DEFAULT_FLUSH_INTERVAL, compression: str = "zstd",
                 keys: KeySpace = DEFAULT_KEYS, metadata: dict[str, str] | None = None,
                 kinds: dict[str, str] | None = None, schemas: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        self.schemas = dict(schemas or {})  # a user message kind -> its JSON Schema, written as its channel's schema
        self.keys = keys
        self.kinds = dict(kinds or {})  # a graph's keys -> their message kind (data:FreeDirection), for schema names
        self.flush_interval = flush_interval
        if compression not in COMPRESSIONS:  # before the file is opened
            raise McapLogError(str(path), f"compression {compression!r}: use {' or '.join(COMPRESSIONS)}")
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: IO[bytes] | None = open(self.path, "wb")  # noqa: SIM115 -- open while recording, close()d
        except OSError as exc:
            raise McapLogError(str(path), f"cannot open for writing: {exc.strerror or exc}") from None
        self._writer = ChunkedWriter(self._file, chunk_size=chunk_size, compression=compression)
        self.full: LogFull | None = None  # set once the disk refused a write
        try:
            self._writer.start(profile=PROFILE, library=LIBRARY)
            if metadata:
                self._writer.add_metadata("cekm", {str(k): str(v) for k, v in metadata.items()})
        except OSError as exc:
            self._lost(exc)
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
        self._check_open()
        try:
            cid = self._writer.register_channel(topic, message_encoding, self._schema_id(schema))
        except OSError as exc:
            self._lost(exc)
        self._channels[topic] = (cid, message_encoding)
        self._sequence[cid] = 0
        return cid

    def _msgpack_schema(self, key: str, payload: bytes = b"") -> SchemaSpec:
        """``cekm.<kind>`` of the key; on a graph's own key, the kind its first message says
        (``cekm.data``, ``cekm.field/target``), a user's type by its name (``cekm.data:FreeDirection``)."""
        try:
            kind = self.keys.parse(key).kind.value
        except KeySpaceError:
            kind = "unknown"
        if kind == "node" and key in self.kinds:  # what the run's graph declares it carries
            kind = self.kinds[key]
        elif kind == "node" and payload:
            said, _ = peek(payload)
            if said is not None and said != "none":
                name = peek_type(payload) if said == "data" else None
                kind = said if name is None else f"data:{name}"
        if kind in self.schemas:
            return SchemaSpec(f"cekm.{kind}", "jsonschema", json.dumps(self.schemas[kind]).encode())
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
                                                                                     self._msgpack_schema(key, payload))
        self._add(cid, payload, sim_time, sim_time if publish_time is None else publish_time)
        return True

    def write_encoded(self, topic: str, message_encoding: str, schema: SchemaSpec, data: bytes,
                      sim_time: float, sticky: bool = False) -> None:
        """Record a message of any encoding (e.g. protobuf Foxglove views) on ``topic``
        (``sticky``: a log set writes it again at the start of each file; one file: no matter)."""
        self._add(self.channel(topic, message_encoding, schema), data, sim_time, sim_time)

    def _check_open(self) -> None:
        if self._file is None:
            raise self.full if self.full is not None else McapLogError(str(self.path), "recorder is closed")

    def _add(self, cid: int, data: bytes, log_time: float, publish_time: float) -> None:
        self._check_open()
        seq = self._sequence[cid] = (self._sequence[cid] + 1) & 0xFFFFFFFF
        log_ns = sim_ns(log_time)
        try:
            self._writer.add_message(cid, log_ns, data, log_ns if publish_time == log_time else sim_ns(publish_time),
                                     seq)
        except OSError as exc:
            self._lost(exc)
        self.messages += 1
        self.maybe_flush()

    def add_raw(self, channel_id: int, data: bytes, log_time_ns: int, publish_time_ns: int, sequence: int) -> None:
        """Add a message with times already in nanoseconds (for copying between logs)."""
        self._check_open()
        try:
            self._writer.add_message(channel_id, log_time=log_time_ns, data=data, publish_time=publish_time_ns,
                                     sequence=sequence)
        except OSError as exc:
            self._lost(exc)
        self.messages += 1

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record (e.g. scenario, seed) in the file."""
        self._check_open()
        try:
            self._writer.add_metadata(name, {str(k): str(v) for k, v in data.items()})
        except OSError as exc:
            self._lost(exc)

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time_ns: int = 0,
                       create_time_ns: int = 0) -> None:
        """An attachment record (for copying between logs)."""
        self._check_open()
        try:
            self._writer.add_attachment(create_time=create_time_ns, log_time=log_time_ns, name=name,
                                        media_type=media_type, data=data)
        except OSError as exc:
            self._lost(exc)

    def flush(self) -> None:
        """Close the open chunk and push everything to the OS (survives a killed process)."""
        if self._file is not None:
            try:
                self._writer.flush()
            except OSError as exc:
                self._lost(exc)
            self._last_flush = time.monotonic()

    @property
    def size(self) -> int:
        """Bytes of the file written out so far (up to the last whole record)."""
        return self._writer.committed

    def _lost(self, exc: OSError) -> None:
        """The OS refused a write: close the file with what reached it whole, then raise
        :class:`LogFull`. The file is cut back to the last chunk written out with its
        message indexes (the open chunk, at most ``flush_interval`` s of messages, is lost),
        then ends with the summary of those chunks, or, if that does not fit, a bare footer,
        or, if not even that fits, at that chunk (no footer: read up to the end all the
        same). The handle that failed is closed first (its buffer may still hold bytes)."""
        w, keep = self._writer, self._writer.committed
        old, self._file = self._file, None
        try:
            if old is not None:
                old.close()
        except OSError:
            pass
        closed = "cut"
        try:
            tail = _At(keep)
            w.lost_stream(tail)
            try:
                w.finish()
                attempts = [("summary", tail.getvalue()), ("footer", _footer_only())]
            except OSError:  # the chunk indexes' temporary file failed too
                attempts = [("footer", _footer_only())]
            fd = os.open(self.path, os.O_WRONLY)
            try:
                for how, data in attempts:
                    try:
                        os.ftruncate(fd, keep)
                        os.lseek(fd, keep, os.SEEK_SET)
                        _write_all(fd, data)
                        os.fsync(fd)
                        closed = how
                        break
                    except OSError:
                        os.ftruncate(fd, keep)
            finally:
                os.close(fd)
        except OSError:
            pass
        messages = w.committed_messages
        what = {"summary": "closed with its summary", "footer": "closed with a footer (no index)",
                "cut": "cut at its last whole chunk (no footer)"}[closed]
        self.full = LogFull(str(self.path), f"{exc.strerror or exc} after {_size(keep)}: the log stops "
                            f"here, {what}, with {messages} messages, readable", closed=closed, size=keep,
                            messages=messages)
        raise self.full

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
        """Write the summary (indexes, statistics) and close the file (idempotent; after
        :class:`LogFull` the file is closed already)."""
        if self._file is None:
            return
        try:
            self._writer.finish()
            self._file.close()
        except OSError as exc:
            self._lost(exc)
        finally:
            if self._file is not None:
                with contextlib.suppress(OSError):
                    self._file.close()
                self._file = None

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


async def record_zenoh(session: Any, recorder: McapRecorder, key_expr: str | None = None, *,
                       stop: asyncio.Event, flush_every: float | None = None) -> int:
    """Record every sample on ``key_expr`` (default: the whole key space) until ``stop`` is set.

    Each message is filed at the sim time of its own ``stamp``; a message whose stamp
    cannot be read (malformed) is filed at the latest sim time seen, so nothing the
    network carried is left out. Returns the number of messages recorded."""
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
