"""``cekm record``: record live keys into an MCAP log like the world server's own.

The same recorder (:class:`~cekm_swarm.runtime.mcap_log.McapRecorder`: one msgpack
channel per key, log time = the message's sim-time stamp) and, from ``world/state``, the
same Foxglove view channels (:class:`~cekm_swarm.runtime.foxglove_view.FoxgloveViews`:
robots, targets, moving obstacles, transforms, paths). The static scene (walls, fixed
obstacles) is not published: the world server serves it on a queryable
(:func:`serve_geometry`, key ``<root>/world/geometry``), which the recorder asks once it
sees the first world state, and writes as the world's log does (the ``geometry``
metadata record and the first ``/view/scene``). A router that refuses the query (access
control) leaves the recording without it, and says so.

A message whose stamp the recorder does not believe is not recorded: it is dropped and
counted (:attr:`RecordResult.dropped`), as the world's own recorder does
(``world/recorder.py``), so the log's times stay sane (a stamp of 1e300 was kept at the
largest time MCAP holds, and a replay of the log then waited 584 years for it). The
recorder has no clock of its own, so it judges a stamp as a module does
(:func:`record_problem`, :class:`~cekm_swarm.protocol.stamps.StampWindow`): finite, within
[0, MAX_STAMP_S], on the tick grid, and within 8 ticks of the newest stamp it took (after
a second of wall time without one, as at the start, when a run restarts or a replay loops
back, any stamp in bounds is taken). A message whose stamp cannot be read at all (not a
message, no finite number) is still recorded, at the latest sim time taken; a
``world/state`` that does not decode (its entries are typed: a robot without a finite
pose does not decode) is recorded but drawn in no view, and counted.
"""

from __future__ import annotations

import json
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS, DropCounter, KeyKind, KeySpace, KeySpaceError, WorldState, peek
from cekm_swarm.protocol.stamps import StampWindow

from . import foxglove_view
from .mcap_log import McapRecorder
from .mcap_sets import SplitRecorder, open_recorder

GEOMETRY_ENCODING = "application/json"


def serve_geometry(session: zenoh.Session, key: str, geometry: dict[str, Any]) -> zenoh.Queryable[None]:
    """Answer queries on ``key`` with ``geometry`` as JSON (the world server calls this);
    undeclare the returned queryable when done."""
    return serve_json(session, key, geometry)


def serve_json(session: zenoh.Session, key: str, doc: dict[str, Any]) -> zenoh.Queryable[None]:
    """Answer queries on ``key`` with ``doc`` as JSON (the static scene, the run's graph)."""
    blob = json.dumps(doc).encode()

    def reply(query: zenoh.Query) -> None:
        query.reply(key, blob, encoding=zenoh.Encoding(GEOMETRY_ENCODING))

    return session.declare_queryable(key, zenoh.handlers.Callback(reply, indirect=True))


def fetch_geometry(session: zenoh.Session, key: str, timeout: float = 2.0) -> dict[str, Any] | None:
    """The static scene served on ``key``, or None (no answer, or an answer that is not a
    JSON map: a malformed reply is ignored, never raised)."""
    return fetch_json(session, key, timeout)


def fetch_json(session: zenoh.Session, key: str, timeout: float = 2.0) -> dict[str, Any] | None:
    """The JSON map served on ``key``, or None (no answer, or a malformed one)."""
    try:
        replies = list(session.get(key, timeout=timeout))
    except Exception:
        return None
    for r in replies:
        if r.ok is None:
            continue
        try:
            doc = json.loads(r.ok.payload.to_bytes())
        except ValueError:
            continue
        if isinstance(doc, dict):
            return doc
    return None


def record_problem(stamp: float | None, window: StampWindow) -> str | None:
    """Why a message whose :func:`~cekm_swarm.protocol.peek` stamp is ``stamp`` is not to
    be recorded (None: record it). A stamp that cannot be read (None) is no reason: the
    message is recorded at the latest sim time taken. Any other goes through ``window``
    (bounds, tick grid, within 8 ticks of the newest stamp taken), which takes it when it
    is believed. No Zenoh: feed it stamps in arrival order."""
    if stamp is None:
        return None
    return window.check(stamp)


@dataclass
class RecordResult:
    """What a recording holds: messages per key, view messages written, malformed seen,
    messages dropped (not recorded: a stamp the recorder does not believe)."""

    messages: int = 0
    per_key: dict[str, int] = field(default_factory=dict)
    malformed: int = 0
    dropped: int = 0
    views: bool = False
    geometry: bool = False
    wall_seconds: float = 0.0
    first_stamp: float | None = None
    last_stamp: float | None = None
    files: list[Path] = field(default_factory=list)  # the files written (a log set: more than one)


class Recording:
    """The pure part: feed (key, payload) in arrival order; writes the log. One thread."""

    def __init__(self, recorder: McapRecorder | SplitRecorder, keys: KeySpace = DEFAULT_KEYS, views: bool = True,
                 geometry: Callable[[], dict[str, Any] | None] | None = None) -> None:
        self.recorder = recorder
        self._geometry = geometry  # asked once, at the first world state
        self.keys = keys
        self.drops = DropCounter("record", keys=keys)  # recorded, but not drawn: malformed
        self.stamp_drops = DropCounter("record", keys=keys)  # not recorded: a stamp not believed
        self.window = StampWindow()
        self.result = RecordResult()
        self._last = 0.0
        self._views = None
        if views and foxglove_view.available():  # foxglove-sdk is installed
            self._views = foxglove_view.FoxgloveViews(recorder)
            self.result.views = True

    def add(self, key: str, payload: bytes) -> None:
        """Record one message received on ``key`` (or drop and count it: :func:`record_problem`)."""
        _, stamp = peek(payload)
        why = record_problem(stamp, self.window)
        if why is not None:
            self.stamp_drops.drop(key, why)
            self.result.dropped = self.stamp_drops.total
            return
        t = self._last if stamp is None else stamp
        self._last = max(self._last, t)
        self.recorder.write(key, payload, t)
        r = self.result
        r.messages += 1
        r.per_key[key] = r.per_key.get(key, 0) + 1
        if stamp is not None:
            r.first_stamp = stamp if r.first_stamp is None else min(r.first_stamp, stamp)
            r.last_stamp = stamp if r.last_stamp is None else max(r.last_stamp, stamp)
        if self._is_state(key):
            msg = self.drops.decode(key, payload)
            if isinstance(msg, WorldState) and self._geometry is not None:
                self._add_geometry(msg.stamp)
            if isinstance(msg, WorldState) and self._views is not None:  # typed: every entry drawable
                self._views.write_state(msg.stamp, {"robots": msg.robots, "targets": msg.targets,
                                                    "obstacles": msg.obstacles})
        r.malformed = self.drops.total

    def _add_geometry(self, t: float) -> None:
        source, self._geometry = self._geometry, None
        geometry = source() if source is not None else None
        if geometry is None:
            return
        self.recorder.add_metadata("geometry", {"json": json.dumps(geometry)})
        if self._views is not None:
            try:
                self._views.write_geometry(t, geometry)
            except (KeyError, TypeError, ValueError, IndexError) as exc:  # a scene it cannot draw
                self.drops.drop(self.keys.world_geometry(), f"geometry not drawable: {exc!r}")
                return
        self.result.geometry = True

    def _is_state(self, key: str) -> bool:
        try:
            return self.keys.parse(key).kind is KeyKind.WORLD_STATE
        except KeySpaceError:
            return False


def record(session: zenoh.Session, out: str | Path, key_expr: str, *, keys: KeySpace = DEFAULT_KEYS,
           stop: threading.Event, duration: float | None = None, count: int | None = None,
           metadata: dict[str, str] | None = None, views: bool = True,
           on_first: Callable[[], None] | None = None,
           on_progress: Callable[[RecordResult], None] | None = None, progress_every: float = 1.0,
           max_bytes: int | None = None, max_seconds: float | None = None) -> RecordResult:
    """Record every sample on ``key_expr`` into ``out`` until ``stop`` is set, ``duration``
    seconds passed, or ``count`` messages were recorded. The file is closed (indexed) at the
    end, and flushed every half second on the way, so a killed recorder leaves a log that
    ``cekm log info --recover`` restores. With ``max_bytes`` or ``max_seconds`` the recording
    is a log set (``out`` ``run.mcap``: ``run_0.mcap``, ``run_1.mcap``, ...; :mod:`.mcap_sets`)."""
    inbox: queue.SimpleQueue[tuple[str, bytes] | None] = queue.SimpleQueue()

    def on_sample(sample: zenoh.Sample) -> None:  # Zenoh's thread: hand over and return
        if sample.kind == zenoh.SampleKind.PUT:
            inbox.put((str(sample.key_expr), sample.payload.to_bytes()))

    meta = {"recorded_by": "cekm record", "key_expr": key_expr, "root": keys.root}
    meta.update(metadata or {})
    t0 = time.monotonic()
    with open_recorder(out, keys=keys, metadata=meta, max_bytes=max_bytes, max_seconds=max_seconds) as recorder:
        rec = Recording(recorder, keys, views, geometry=lambda: fetch_geometry(session, keys.world_geometry()))
        sub = session.declare_subscriber(key_expr, on_sample)
        last_progress = t0
        try:
            while not stop.is_set():
                now = time.monotonic()
                if duration is not None and now - t0 >= duration:
                    break
                if count is not None and rec.result.messages >= count:
                    break
                wait = 0.1 if duration is None else max(0.0, min(0.1, t0 + duration - now))
                try:
                    item = inbox.get(timeout=wait)
                except queue.Empty:
                    recorder.maybe_flush()
                    item = None
                if item is not None:
                    if on_first is not None:  # once, at the first message (recorded or dropped)
                        on_first()
                        on_first = None
                    rec.add(*item)
                if on_progress is not None and time.monotonic() - last_progress >= progress_every:
                    last_progress = time.monotonic()
                    on_progress(rec.result)
        finally:
            sub.undeclare()
            while count is None or rec.result.messages < count:  # what arrived before the stop
                try:
                    item = inbox.get_nowait()
                except queue.Empty:
                    break
                if item is not None:
                    rec.add(*item)
    rec.result.wall_seconds = time.monotonic() - t0
    rec.result.files = list(getattr(recorder, "files", None) or [Path(out)])
    return rec.result
