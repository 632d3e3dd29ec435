"""Log sets: one long log split into numbered MCAP files, like rosbag2's ``--max-bag-size``
and ``--max-bag-duration``, read back as one log.

Writing (:class:`SplitRecorder`): ``run.mcap`` with ``max_bytes`` or ``max_seconds`` becomes
``run_0.mcap``, ``run_1.mcap``, ... beside it. A file is closed (with its summary) and the
next begun at the first message once the file holds ``max_bytes`` written out or once the
message's log time is ``max_seconds`` of sim time past the file's first. Every file is a
complete MCAP by itself: its own schemas and channels (registered at their first message
in it), every metadata record of the log again (``cekm``, ``geometry``: ``cekm plot`` and
``cekm log info`` read any one file alone), a ``log_set`` metadata record (the set's name,
the file's index, its first log time), and the messages written as *sticky* (the static
scene of the Foxglove views) again at its start.

Reading (:func:`log_files`): a path names a set when it is a directory (the ``.mcap`` files
in it: one log, a set or a single file) or the set's first file (``run_0.mcap`` with a
``run_1.mcap`` beside it); any other file is itself. :func:`.mcap_read.read_set` gives the
messages of every file in log-time order (a merge: a message whose stamp lags the file
boundary still comes in its place).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from cekm_swarm.protocol import DEFAULT_KEYS, KeySpace

from .errors import McapLogError
from .mcap_record import DEFAULT_CHUNK_SIZE, DEFAULT_FLUSH_INTERVAL, McapRecorder, SchemaSpec, sim_ns

_NUMBERED = re.compile(r"^(?P<stem>.+)_(?P<index>\d+)\.mcap$")
_SKIP = (".truncated.mcap", ".recovered.mcap")


def set_file(path: str | Path, index: int) -> Path:
    """File ``index`` of the set that ``path`` (``run.mcap``) names: ``run_<index>.mcap``."""
    path = Path(path)
    stem = path.name[:-5] if path.name.endswith(".mcap") else path.name
    return path.with_name(f"{stem}_{index}.mcap")


def _members(first: Path) -> list[Path]:
    m = _NUMBERED.match(first.name)
    if m is None or int(m["index"]) != 0:
        return [first]
    out, k = [], 0
    while (p := first.with_name(f"{m['stem']}_{k}.mcap")).is_file():
        out.append(p)
        k += 1
    return out


def log_files(path: str | Path) -> list[Path]:
    """The files of the log ``path`` names, in order (see the module's docstring); a
    :class:`McapLogError` when it names none, or a directory holds several logs."""
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.glob("*.mcap") if p.is_file() and not p.name.endswith(_SKIP))
        logs: dict[str, list[Path]] = {}
        for p in files:
            m = _NUMBERED.match(p.name)
            if m is not None and p.with_name(f"{m['stem']}_0.mcap").is_file():
                logs.setdefault(m["stem"], [])
            else:
                logs.setdefault(p.name, [p])
        if not logs:
            raise McapLogError(str(path), "no .mcap log in this directory")
        if len(logs) > 1:
            names = sorted(k if v else f"{k}_*.mcap" for k, v in logs.items())
            raise McapLogError(str(path), f"holds several logs ({', '.join(names)}): name one")
        (name, single), = logs.items()
        return single or _members(path / f"{name}_0.mcap")
    if not path.is_file():
        raise McapLogError(str(path), "no such file")
    return _members(path)


class SplitRecorder:
    """A :class:`McapRecorder` that splits its log into a set (see the module's docstring):
    the same calls, the files ``<path stem>_<k>.mcap``. ``max_bytes`` or ``max_seconds``
    (or both) must be given."""

    def __init__(self, path: str | Path, *, max_bytes: int | None = None, max_seconds: float | None = None,
                 chunk_size: int = DEFAULT_CHUNK_SIZE, flush_interval: float | None = DEFAULT_FLUSH_INTERVAL,
                 compression: str = "zstd", keys: KeySpace = DEFAULT_KEYS,
                 metadata: dict[str, str] | None = None, kinds: dict[str, str] | None = None,
                 schemas: dict[str, Any] | None = None) -> None:
        if max_bytes is None and max_seconds is None:
            raise ValueError("a log set needs max_bytes or max_seconds")
        if (max_bytes is not None and max_bytes <= 0) or (max_seconds is not None and not max_seconds > 0):
            raise McapLogError(str(path), "a log set's limits must be > 0")
        self.base = Path(path)
        self.keys = keys
        self.max_ns = None if max_seconds is None else sim_ns(max_seconds)
        self.max_bytes = max_bytes
        self._options: dict[str, Any] = {"chunk_size": chunk_size, "flush_interval": flush_interval,
                                         "compression": compression, "keys": keys, "kinds": kinds, "schemas": schemas}
        self._metadata: list[tuple[str, dict[str, str]]] = []  # every file gets them all
        if metadata:
            self._metadata.append(("cekm", {str(k): str(v) for k, v in metadata.items()}))
        self._sticky: dict[str, tuple[str, SchemaSpec, bytes]] = {}  # topic -> the latest sticky message
        self.files: list[Path] = []
        self.messages = 0  # in every file
        self._done_refused = 0
        self._rec: McapRecorder | None = None
        self._first_ns: int | None = None
        self._open(None)

    # ------------------------------------------------------------------ files

    def _open(self, first_ns: int | None) -> None:
        index = len(self.files)
        path = set_file(self.base, index)
        rec = McapRecorder(path, **self._options)
        self.files.append(path)
        self._rec = rec
        self._first_ns = first_ns
        for name, meta in self._metadata:
            rec.add_metadata(name, meta)
        rec.add_metadata("log_set", {"name": self.base.name, "index": str(index),
                                     "first_log_time_ns": "" if first_ns is None else str(first_ns)})
        t = 0.0 if first_ns is None else first_ns / 1e9
        for topic, (encoding, schema, data) in self._sticky.items():
            rec.write_encoded(topic, encoding, schema, data, t)

    def _roll(self, log_ns: int) -> None:
        """Start the next file when the open one is full (by size or by time)."""
        rec = self._rec
        assert rec is not None
        if self._first_ns is None:
            self._first_ns = log_ns
        if rec.messages == 0:
            return
        if (self.max_ns is not None and log_ns - self._first_ns >= self.max_ns) or \
                (self.max_bytes is not None and rec.size >= self.max_bytes):
            self._done_refused += rec.refused
            rec.close()
            self._open(log_ns)

    # ------------------------------------------------------------------ the recorder's calls

    @property
    def path(self) -> Path:
        """The file being written."""
        assert self._rec is not None
        return self._rec.path

    @property
    def refused(self) -> int:
        return self._done_refused + (self._rec.refused if self._rec is not None else 0)

    @property
    def size(self) -> int:
        return self._rec.size if self._rec is not None else 0

    @property
    def topics(self) -> list[str]:
        return self._rec.topics if self._rec is not None else []

    def write(self, key: str, payload: bytes, sim_time: float, publish_time: float | None = None) -> bool:
        self._roll(sim_ns(sim_time))
        ok = self._rec.write(key, payload, sim_time, publish_time)  # type: ignore[union-attr]
        self.messages += ok
        return ok

    def write_encoded(self, topic: str, message_encoding: str, schema: SchemaSpec, data: bytes, sim_time: float,
                      sticky: bool = False) -> None:
        """As :meth:`McapRecorder.write_encoded`; a ``sticky`` message (the static scene) is
        written again at the start of every later file."""
        self._roll(sim_ns(sim_time))
        self._rec.write_encoded(topic, message_encoding, schema, data, sim_time)  # type: ignore[union-attr]
        self.messages += 1
        if sticky:
            self._sticky[topic] = (message_encoding, schema, data)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        entry = (name, {str(k): str(v) for k, v in data.items()})
        self._metadata.append(entry)
        self._rec.add_metadata(*entry)  # type: ignore[union-attr]

    def flush(self) -> None:
        if self._rec is not None:
            self._rec.flush()

    def maybe_flush(self, now: float | None = None) -> bool:
        return self._rec.maybe_flush(now) if self._rec is not None else False

    @property
    def full(self) -> Any:
        return self._rec.full if self._rec is not None else None

    def close(self) -> None:
        if self._rec is not None:
            rec, self._rec = self._rec, None
            self._done_refused += rec.refused
            rec.close()

    def __enter__(self) -> SplitRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_recorder(path: str | Path, *, max_bytes: int | None = None, max_seconds: float | None = None,
                  **options: Any) -> McapRecorder | SplitRecorder:
    """One file at ``path``, or a set beside it when a limit is given."""
    if max_bytes is None and max_seconds is None:
        return McapRecorder(path, **options)
    return SplitRecorder(path, max_bytes=max_bytes, max_seconds=max_seconds, **options)
