"""The world server's log: what its recorder takes from other sessions
(:class:`RecordFilter`) and the opening of ``run.mcap`` (or of a log set, ``run_0.mcap``,
``run_1.mcap``, ...: :mod:`cekm_swarm.runtime.mcap_sets`) with its metadata and Foxglove
views (:func:`open_run_log`).

Two recordings (``--record``): ``full`` (the default) logs every message of the run's keys
and the views at every tick; ``lean``, for long runs, logs what the world sent (readings,
clock, state) and of the nodes' messages only the answers and what teammates share
(:data:`LEAN_KINDS`), with the views once every :data:`LEAN_VIEW_TICKS` ticks and each
robot's path view every :data:`LEAN_PATH_S` s."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from cekm_swarm.protocol import DropCounter, KeyKind, KeySpace, KeySpaceError, ParamChange, expect_of
from cekm_swarm.protocol.stamps import PAST_S, stamp_problem
from cekm_swarm.runtime import foxglove_view
from cekm_swarm.runtime.mcap_sets import open_recorder

RECORD_MODES = ("full", "lean")
LEAN_KINDS = frozenset({KeyKind.CMD_WHEELS, KeyKind.SHARE, ParamChange})
"""The kinds of the nodes' messages a lean log keeps (not the fields, the bulk of a full log):
the answers, what teammates share, and every parameter change (``cekm param set``)."""
WORLD_SENT_KINDS = frozenset(k for k in KeyKind if k.value.startswith("sense/"))
"""The kinds of a robot's keys only the world publishes: its readings (with a graph, the
recorder takes none of them from other sessions)."""
LEAN_VIEW_TICKS = 8
"""A lean log's Foxglove views: once every 8 ticks (1.024 s of sim time)."""
LEAN_PATH_S = 10.0
"""A lean log's path views: each robot's path at most every 10 s of sim time."""
RECORD_QUEUE = 1 << 13
"""Samples the recording queue holds between two drains (one per tick); the oldest go first.
Zenoh's ring channel allocates its ring at once, about 256 bytes a sample, and the ring's
pages become resident one by one as its head goes round, whatever the queue's length: a
queue of 65,536 grew the world server by 16 MB over its first 65,536 messages from other
sessions (the first 4 minutes of an 8-robot real-time run; docs/performance.md, "Long
runs"). 8,192 (2 MB) still holds about 350 ticks of a 6-robot ``tracking-crowd`` run's
traffic (23 messages a tick) or 30 ticks of 16 robots sending every reading; a drain that
finds it full says so (:meth:`world.publisher.TickPublisher.drain`)."""


class RecordFilter:
    """What the world's recorder takes from other sessions: a message on a key of this
    run (a robot of the scenario, or the world's keys) that decodes as its key's message,
    with a stamp on the tick grid no older than ``PAST_S`` and not ahead of the world's
    sim time (no peer is ahead of the world's clock: the world starts each tick). Anything
    else is dropped and counted per source key (a key outside the key space, or of a robot
    this run does not have, is counted without a channel being opened for it), so the log
    holds at most a fixed set of channels and no stamp a writer cannot hold."""

    def __init__(self, keys: KeySpace, robots: list[str], drops: DropCounter,
                 declared: dict[str, str] | None = None, lean: bool = False) -> None:
        self.keys, self.robots, self.drops = keys, frozenset(robots), drops
        self.lean = lean
        self.left_out = 0  # a lean log: messages of the run not logged (fields), not drops
        self.declared = None if declared is None else {k: expect_of(v) for k, v in declared.items()}
        self._known: dict[str, tuple[KeyKind, int | None] | str] = {}  # key -> (kind, index) or why not
        self._expect: dict[str, KeyKind] = {}

    def _key(self, key: str) -> tuple[KeyKind, int | None] | str:
        """(kind, sensor index) of a key of this run, else why it is not one (the drop's
        reason). With the run's graph (``declared``: every key its nodes send, and its
        kind), a robot's key is one of those; without it, any key of a robot of the run."""
        hit = self._known.get(key)
        if hit is None:
            hit = self._classify(key)
            if len(self._known) < 4096:  # only ever a bounded memo: foreign keys are unbounded
                self._known[key] = hit
        return hit

    def _classify(self, key: str) -> tuple[KeyKind, int | None] | str:
        try:
            p = self.keys.parse(key)
        except KeySpaceError:
            return "key outside this run's key space"
        if p.robot is None:
            return (p.kind, p.index)
        if p.robot not in self.robots:
            return f"robot {p.robot!r} is not a robot of this run"
        if self.declared is None:
            if p.kind is KeyKind.NODE:
                return "not a key of the key space's own kinds (a run without a graph records no node keys)"
            return (p.kind, p.index)
        kind = self.declared.get(key)
        if kind is not None:
            self._expect[key] = kind
            return (kind if p.kind is KeyKind.NODE else p.kind, p.index)
        if p.kind in WORLD_SENT_KINDS:
            return "a key only the world publishes (its log holds the world's own messages on it, no one else's)"
        return "not a key this run's graph's nodes send on"

    def check(self, key: str, payload: bytes, now: float) -> float | None:
        """The message's stamp when it is to be recorded at sim time ``now``, else None
        (dropped and counted; in a lean log a message of a kind it does not keep is left out,
        counted in :attr:`left_out`, before it is decoded)."""
        hit = self._key(key)
        if type(hit) is str:
            self.drops.drop(key, hit)
            return None
        if self.lean and hit[0] not in LEAN_KINDS:
            self.left_out += 1
            return None
        msg = self.drops.decode(key, payload, expect=self._expect.get(key))
        if msg is None:
            return None
        why = stamp_problem(msg.stamp, now, PAST_S, 0.0)
        if why is not None:
            self.drops.drop(key, why)
            return None
        return msg.stamp


def open_run_log(path: Path, scenario: str, seed: int, mode: str, geometry: dict[str, Any],
                 robot_radius: float, *, max_bytes: int | None = None, max_seconds: float | None = None,
                 record: str = "full", keys: KeySpace | None = None,
                 kinds: dict[str, str] | None = None, schemas: dict[str, Any] | None = None) -> tuple[Any, Any]:
    """The run's MCAP log (one file, or a set with ``max_bytes``/``max_seconds``) with its
    metadata (scenario, seed, mode, recording, the key root of ``keys``, the static geometry)
    and, when foxglove-sdk is installed, its Foxglove views with the scene written at t = 0
    (else None for the views). ``keys``: the run's key space (its root is what the log's
    readers decode its keys under; without it, no root is written and readers take the root
    from the log's world keys)."""
    metadata = {"scenario": scenario, "seed": str(seed), "mode": mode, "record": record}
    options: dict[str, Any] = {}
    if keys is not None:
        metadata["root"] = keys.root
        options["keys"] = keys
    if kinds:
        options["kinds"] = kinds
    if schemas:
        options["schemas"] = schemas
    recorder = open_recorder(path, max_bytes=max_bytes, max_seconds=max_seconds, metadata=metadata, **options)
    recorder.add_metadata("geometry", {"json": json.dumps(geometry)})
    views = None
    if foxglove_view.available():  # foxglove-sdk is installed
        views = foxglove_view.FoxgloveViews(recorder, robot_radius=robot_radius,
                                            path_every=LEAN_PATH_S if record == "lean" else foxglove_view.PATH_EVERY_S)
        views.write_geometry(0.0, geometry)
    return recorder, views
