"""``cekm record``: record live keys into an MCAP log like the world server's own.

The same recorder (:class:`~cekm_swarm.runtime.mcap_log.McapRecorder`: one msgpack
channel per key, log time = the message's sim-time stamp) and, from ``world/state``, the
same Foxglove view channels (:class:`~cekm_swarm.runtime.foxglove_view.FoxgloveViews`:
robots, targets, moving obstacles, transforms, paths). Not recorded, because the world
does not publish it: the static scene (walls and fixed obstacles), which the world
server writes into its own log from the scenario.

A message whose stamp cannot be read is still recorded, at the latest sim time seen; a
``world/state`` that does not decode is recorded but drawn in no view, and counted.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS, DropCounter, KeyKind, KeySpace, KeySpaceError, WorldState, peek

from .mcap_log import McapRecorder


@dataclass
class RecordResult:
    """What a recording holds: messages per key, view messages written, malformed seen."""

    messages: int = 0
    per_key: dict[str, int] = field(default_factory=dict)
    malformed: int = 0
    views: bool = False
    wall_seconds: float = 0.0
    first_stamp: float | None = None
    last_stamp: float | None = None


class Recording:
    """The pure part: feed (key, payload) in arrival order; writes the log. One thread."""

    def __init__(self, recorder: McapRecorder, keys: KeySpace = DEFAULT_KEYS, views: bool = True) -> None:
        self.recorder = recorder
        self.keys = keys
        self.drops = DropCounter("record", keys=keys)
        self.result = RecordResult()
        self._last = 0.0
        self._views = None
        if views:
            try:
                from . import foxglove_view

                if foxglove_view.available():
                    self._views = foxglove_view.FoxgloveViews(recorder)
                    self.result.views = True
            except ImportError:  # pragma: no cover - foxglove-sdk missing
                self._views = None

    def add(self, key: str, payload: bytes) -> None:
        """Record one message received on ``key``."""
        _, stamp = peek(payload)
        t = self._last if stamp is None else stamp
        self._last = max(self._last, t)
        self.recorder.write(key, payload, t)
        r = self.result
        r.messages += 1
        r.per_key[key] = r.per_key.get(key, 0) + 1
        if stamp is not None:
            r.first_stamp = stamp if r.first_stamp is None else min(r.first_stamp, stamp)
            r.last_stamp = stamp if r.last_stamp is None else max(r.last_stamp, stamp)
        if self._views is not None and self._is_state(key):
            msg = self.drops.decode(key, payload)
            if isinstance(msg, WorldState):
                try:
                    self._views.write_state(msg.stamp, {"robots": msg.robots, "targets": msg.targets,
                                                        "obstacles": msg.obstacles})
                except (KeyError, TypeError, ValueError) as exc:  # well-formed plain data, wrong shape
                    self.drops.drop(key, f"world state not drawable: {exc!r}")
        r.malformed = self.drops.total

    def _is_state(self, key: str) -> bool:
        try:
            return self.keys.parse(key).kind is KeyKind.WORLD_STATE
        except KeySpaceError:
            return False


def record(session: zenoh.Session, out: str | Path, key_expr: str, *, keys: KeySpace = DEFAULT_KEYS,
           stop: threading.Event, duration: float | None = None, count: int | None = None,
           metadata: dict[str, str] | None = None, views: bool = True,
           on_first: Callable[[], None] | None = None,
           on_progress: Callable[[RecordResult], None] | None = None, progress_every: float = 1.0) -> RecordResult:
    """Record every sample on ``key_expr`` into ``out`` until ``stop`` is set, ``duration``
    seconds passed, or ``count`` messages were recorded. The file is closed (indexed) at the
    end, and flushed every half second on the way, so a killed recorder leaves a log that
    ``cekm log info --recover`` restores."""
    inbox: queue.SimpleQueue[tuple[str, bytes] | None] = queue.SimpleQueue()

    def on_sample(sample: zenoh.Sample) -> None:  # Zenoh's thread: hand over and return
        if sample.kind == zenoh.SampleKind.PUT:
            inbox.put((str(sample.key_expr), sample.payload.to_bytes()))

    meta = {"recorded_by": "cekm record", "key_expr": key_expr}
    meta.update(metadata or {})
    t0 = time.monotonic()
    with McapRecorder(out, keys=keys, metadata=meta) as recorder:
        rec = Recording(recorder, keys, views)
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
                    if rec.result.messages == 0 and on_first is not None:
                        on_first()
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
    return rec.result
