"""MCAP logs of the key space, the reading side: every message of a log in time order
(:func:`read_messages`), or in file order up to the cut of a log whose writer died
(:func:`stream_messages`), and whether a log was closed (:func:`is_complete`)."""

from __future__ import annotations

import heapq
import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, SeekingReader, make_reader

from cekm_swarm.protocol import KeySpaceError, validate_root

from .errors import McapLogError
from .mcap_sets import log_files

_MAGIC = b"\x89MCAP0\r\n"


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


def file_complete(path: str | Path) -> bool:
    """True when this one file was closed properly (footer present), whatever set it is in."""
    return _has_footer(_open(path))


def is_complete(path: str | Path) -> bool:
    """True when the log was closed properly (footer present), every file of a set."""
    return all(_has_footer(_open(p)) for p in log_files(path))


_WORLD_KEYS = ("/world/clock", "/world/state")
"""The world's keys under the root, whose topics give an older log's root."""
_ROOT_SCAN = 1000
"""Messages of a truncated log (no summary) looked at for a world key."""


def log_root(path: str | Path) -> str | None:
    """The key root of the log ``path`` (a file or a log set): the ``root`` of its ``cekm``
    metadata (the world server's and ``cekm record``'s logs write it), else, for a log
    written before they did, the root of its world keys (``<root>/world/clock``); None
    when neither tells (the log is not readable, or holds no world key)."""
    def valid(root: str | None) -> str | None:
        try:
            return validate_root(root) if root else None
        except KeySpaceError:
            return None

    try:
        first = _open(log_files(path)[0])
        topics: list[str] = []
        if _has_footer(first):
            with open(first, "rb") as f:
                reader = make_reader(f)
                for md in reader.iter_metadata():
                    if md.name == "cekm" and valid(md.metadata.get("root")):
                        return md.metadata["root"]
                summary = reader.get_summary()
                topics = [c.topic for c in summary.channels.values()] if summary is not None else []
        else:
            for k, m in enumerate(stream_messages(first)):
                if k >= _ROOT_SCAN:
                    break
                topics.append(m.topic)
    except (McapLogError, McapError, OSError):
        return None
    for t in topics:
        for tail in _WORLD_KEYS:
            if t.endswith(tail) and valid(t[:-len(tail)]):
                return t[:-len(tail)]
    return None


def read_geometry(path: str | Path) -> dict[str, Any] | None:
    """The geometry the world server recorded (metadata ``geometry``), None if absent.
    ``path``: a file, or a log set (its directory or first file), whose every file holds it."""
    try:
        with open(log_files(path)[0], "rb") as f:
            for md in make_reader(f).iter_metadata():
                if md.name == "geometry":
                    return json.loads(md.metadata["json"])
    except Exception:  # an unfinished log has no index; draw the paths alone
        return None
    return None


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
    """Messages of a log in log-time order, optionally only some topics or message
    encodings. ``path`` is a file, or a log set (a directory, or a set's first file: see
    :mod:`.mcap_sets`), whose files are merged in log-time order."""
    return read_set(log_files(path), topics=topics, encodings=encodings)


class ResendFilter:
    """Tells the world's re-sends apart: a message byte for byte equal to the one before it
    on its topic. The log holds what was sent, and a stalled lockstep tick is sent again
    for the nodes still waiting (the same bytes, the same stamp); a reader that wants one
    sample per tick (``cekm plot``, the ROS 2 export) skips them."""

    def __init__(self) -> None:
        self._last: dict[str, bytes] = {}

    def is_resend(self, m: LoggedMessage) -> bool:
        if self._last.get(m.topic) == m.data:
            return True
        self._last[m.topic] = m.data
        return False


def without_resends(messages: Iterable[LoggedMessage]) -> Iterator[LoggedMessage]:
    """``messages`` less the world's re-sends (:class:`ResendFilter`)."""
    resends = ResendFilter()
    return (m for m in messages if not resends.is_resend(m))


def read_one(path: str | Path, *, topics: Iterable[str] | None = None,
             encodings: Iterable[str] | None = None) -> Iterator[LoggedMessage]:
    """Messages of one file in log-time order (complete file) or file order (a truncated file,
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


def read_set(files: list[Path], *, topics: Iterable[str] | None = None,
             encodings: Iterable[str] | None = None) -> Iterator[LoggedMessage]:
    """The messages of ``files`` in log-time order (files earlier in the set first on a tie)."""
    topics = None if topics is None else list(topics)
    encodings = None if encodings is None else list(encodings)
    if len(files) == 1:
        yield from read_one(files[0], topics=topics, encodings=encodings)
        return
    streams = [((m.log_time, k, i, m) for i, m in enumerate(read_one(f, topics=topics, encodings=encodings)))
               for k, f in enumerate(files)]
    for _, _, _, m in heapq.merge(*streams, key=lambda e: e[:3]):
        yield m
