"""What the world sends each tick and what it logs: per robot the readings its graph reads
(the world's :mod:`world.sense` encoders, and the episode's other readings), the clock and
the ground-truth state; a stalled lockstep tick published again for the robots still
waiting; and the tick's log (what the world sent, its Foxglove views, and what other
sessions sent, drained once per tick through :class:`world.recorder.RecordFilter`).

Held readings: a reading the run's plan lets it hold (``RunPlan.held_readings``: every
reader a pure node of that reading alone) is left out in a tick where it equals the last
one sent, and the robot's ``sense/unchanged`` names it instead, with the time it was last
sent (published before the readings). It is sent anyway once every :data:`HOLD_TICKS`
ticks, a repair: in real time a message may be lost in transit, and a field lost while its
reading is held would be missing until the reading changes. (Its readers take any stamp in
bounds, ``cekm_swarm.protocol.stamps.ANY_STAMP``, so they need no refresh to stay inside
a window.) The keys take the cycle's ticks in turn (:attr:`TickPublisher.phase`), so a
team's refreshes do not all wake their modules in one tick (when every reading was sent
again every 8 ticks, all in one tick, that burst was the deadline misses of 32 robots).
A stalled tick published again sends every reading, and so does the next tick for a
robot one of whose nodes (re)joined the run (:meth:`TickPublisher.rejoined`): a restarted
node that holds no value yet gets one at once."""

from __future__ import annotations

import logging
from collections import deque
from typing import Any

import zenoh

from cekm_swarm.protocol import Clock, KeySpace, Unchanged, WorldState, encode, with_stamp
from cekm_swarm.ticks import TICK_S

from .recorder import RECORD_QUEUE, RecordFilter
from .run_episode import RunEpisode
from .sense import SENDER, SenseEncoder, TickReadings

log = logging.getLogger("world.publisher")

HOLD_TICKS = 63
"""The cycle of a held reading's refresh (63 ticks, 8 s): it is sent at least once in it."""


class TickPublisher:
    """Publish and log one run's ticks (set up by the world server once its session is open)."""

    def __init__(self, keys: KeySpace, world: Any, episode: RunEpisode, sends: dict[str, set[str]] | None,
                 record_filter: RecordFilter, held: dict[str, set[str]] | None = None) -> None:
        self.keys, self.world, self.episode = keys, world, episode
        self.sends = sends  # robot -> the sense keys its graph reads (None: every one of the task)
        self.held = {r: h for r, h in (held or {}).items() if h}  # robot -> the readings it may leave out
        self.last_sent: dict[str, tuple[Any, float]] = {}  # held reading key -> (what it said, when it was sent)
        self.left_out = 0  # readings left out, unchanged
        self.phase: dict[str, int] = {}  # held reading key -> its tick of the refresh cycle, in turn as first seen
        self._rejoined: deque[str] = deque()  # robots to send every reading to next tick (any thread appends)
        self.map_every: dict[str, int] = {}  # robot -> its map versions' period: every reading sent as one starts
        self.record_filter = record_filter
        self.pubs: Any = None  # runtime.bridge.Publishers
        self.recorder: Any = None  # runtime.mcap_log.McapRecorder
        self.views: Any = None  # Foxglove views, when foxglove-sdk is installed
        self.view_every = 1  # ticks between two ticks' views (a lean log: recorder.LEAN_VIEW_TICKS)
        self.record_sub: Any = None  # Zenoh subscriber with a ring channel (RECORD_QUEUE)
        self.recorded = 0
        self.record_full = 0  # drains that found the recording queue full (its oldest samples lost)
        self.republished = 0
        self.last_target: dict[str, bytes] = {}  # the latest target reading's payload, per robot
        self.last_messages: dict[str, list[tuple[str, Any]]] = {}  # the episode's latest other readings, per robot
        self._encoders: dict[str, SenseEncoder] = {}
        self._unrecorded: list[tuple[str, bytes, float]] = []
        self._unviewed: tuple[float, dict[str, Any]] | None = None  # the tick's (t, state) for the views
        self._world_msgs: list[tuple[str, Any]] = []  # the tick's clock and state, sent again on a stall

    # ------------------------------------------------------------------ sending

    def _send(self, key: str, msg: Any) -> None:
        """Publish ``msg``; it is logged by :meth:`record_sent` (the record subscription
        sees only other sessions)."""
        self._put(key, encode(msg), msg.stamp)

    def _put(self, key: str, payload: bytes, stamp: float) -> None:
        self.pubs.put(key, payload)
        self._unrecorded.append((key, payload, stamp))

    def _encoder(self, robot: str) -> SenseEncoder:
        enc = self._encoders.get(robot)
        if enc is None:
            w = self.world
            enc = self._encoders[robot] = SenseEncoder(self.keys, robot, w.sensor_angles, w.body_radius)
        return enc

    def _sense(self, rd: TickReadings, leave_out: set[str] | frozenset[str] = frozenset()) -> list[tuple[str, bytes]]:
        return self._encoder(rd.robot)(rd, leave_out)

    def _refresh_due(self, key: str, cycle: int) -> bool:
        """Whether held reading ``key`` is sent anyway at this tick of the refresh cycle: the
        keys take the cycle's ticks in turn, in the order they were first held."""
        return self.phase.setdefault(key, len(self.phase) % HOLD_TICKS) == cycle

    def _unchanged(self, rd: TickReadings, contents: list[tuple[str, Any]], more: list[tuple[str, Any]],
                   held: set[str]) -> set[str]:
        """The robot's held readings equal to the last ones sent (``contents``: its readings
        as :meth:`SenseEncoder.contents` gives them): left out of this tick, and named in its
        ``sense/unchanged`` (sent now); the others become the last ones sent. One pass, no
        call per reading: with hundreds of robots this is the world's largest own cost."""
        t, last, phase = rd.t, self.last_sent, self.phase
        oldest = t - (HOLD_TICKS + 0.5) * TICK_S  # sent before this: due again
        cycle = self.episode.tick % HOLD_TICKS
        same: list[tuple[str, float]] = []
        for key, content in contents:
            if key not in held:
                continue
            was = last.get(key)
            if was is not None and was[0] == content and was[1] > oldest:
                due = phase.get(key)  # its tick of the refresh cycle, taken in turn when first held
                if due is None:
                    due = phase[key] = len(phase) % HOLD_TICKS
                if due != cycle:
                    same.append((key, was[1]))
                    continue
            last[key] = (content, t)
        for rel, msg in more:
            key = self.keys.node_key(rd.robot, rel)
            if key in held:
                was = last.get(key)
                if (was is not None and was[1] > oldest and not self._refresh_due(key, cycle)
                        and with_stamp(was[0], t) == msg):
                    same.append((key, was[1]))
                else:
                    last[key] = (msg, t)
        if not same:
            return set()
        cut = len(self.keys.root) + len(rd.robot) + 2
        self._send(self.keys.sense_unchanged(rd.robot),
                   Unchanged(t, SENDER, tuple([k[cut:] for k, _ in same]), tuple([s for _, s in same])))
        self.left_out += len(same)
        return {k for k, _ in same}

    def _wanted(self, robot: str) -> set[str] | None:
        return None if self.sends is None else self.sends[robot]

    def rejoined(self, robot: str) -> None:
        """A node of ``robot`` (re)joined the run: the next tick sends all its readings, so
        the values held downstream of them exist again (safe from any thread)."""
        self._rejoined.append(robot)

    def publish(self, readings: list[TickReadings]) -> dict[str, Any]:
        """The tick's readings, clock and state (in this order); returns the state."""
        ep = self.episode
        # a map version starts: what sees something is sent again (docs/learning.md)
        for r, p in self.map_every.items():
            if ep.tick % p == 1 % p:
                head = f"{self.keys.root}/{r}/"
                for key in [k for k, (c, _) in self.last_sent.items() if k.startswith(head) and c is not None]:
                    del self.last_sent[key]
        while self._rejoined:
            head = f"{self.keys.root}/{self._rejoined.popleft()}/"
            for key in [k for k in self.last_sent if k.startswith(head)]:
                del self.last_sent[key]
        for rd in readings:
            want = self._wanted(rd.robot)
            more = ep.messages(rd.robot)
            held = self.held.get(rd.robot)
            enc = self._encoder(rd.robot)
            contents = enc.contents(rd)
            leave_out: set[str] = set()
            if held is not None:
                leave_out = self._unchanged(rd, contents, more, held)
            target_key = enc.target_key
            for key, payload in enc.encode(rd.t, contents, leave_out):
                if want is None or key in want:
                    self._put(key, payload, rd.t)
                if key == target_key:
                    self.last_target[rd.robot] = payload
            if more:
                self.last_messages[rd.robot] = more
            self._send_more(rd.robot, more, want, leave_out)
        st = self.world.state()
        self._world_msgs = [(self.keys.world_clock(), Clock(ep.t, SENDER, ep.tick)),
                            (self.keys.world_state(), WorldState(ep.t, SENDER, st["robots"], st["targets"],
                                                                 st["obstacles"]))]
        for key, msg in self._world_msgs:
            self._send(key, msg)
        self._unviewed = (ep.t, st)
        return st

    def _send_more(self, robot: str, more: list[tuple[str, Any]], want: set[str] | None,
                   leave_out: set[str] | frozenset[str] = frozenset()) -> None:
        for rel, msg in more:
            key = self.keys.node_key(robot, rel)
            if (want is None or key in want) and key not in leave_out:
                self._send(key, msg)

    def republish(self, readings: list[TickReadings], waiting: list[str]) -> None:
        """The stalled tick's readings again (and each robot's latest target or tracking
        reading), for the robots still waiting, and the tick's clock and state (a node that
        reads only those, K-means' global goal, sends its outputs again on them): a
        restarted node catches up."""
        n = len(self.world.sensor_angles)
        for rd in readings:
            if rd.robot not in waiting:
                continue
            want = self._wanted(rd.robot)
            for key, payload in self._sense(rd)[:n]:
                if want is None or key in want:
                    self._put(key, payload, rd.t)
                if key in self.last_sent:  # sent again now: a reading left out later refers to this one
                    self.last_sent[key] = (self.last_sent[key][0], rd.t)
            last = self.last_target.get(rd.robot)
            if last is not None and (want is None or self.keys.sense_target(rd.robot) in want):
                self._put(self.keys.sense_target(rd.robot), last, rd.t)
            self._send_more(rd.robot, self.last_messages.get(rd.robot, []), want)  # tracking: the latest pose, targets
        for key, msg in self._world_msgs:
            self._send(key, msg)
        self.record_sent()
        self.republished += 1

    # ------------------------------------------------------------------ logging

    def record_sent(self) -> None:
        for key, payload, stamp in self._unrecorded:
            self.recorder.write(key, payload, stamp)
        self.recorded += len(self._unrecorded)
        self._unrecorded.clear()

    def record_tick(self, now: float) -> None:
        """Write the tick's log: what the world sent, its views, and what other sessions
        sent since the last drain (at sim time ``now``)."""
        self.record_sent()
        if self._unviewed is not None:
            t, st = self._unviewed
            self._unviewed = None
            if self.views is not None and self.episode.tick % self.view_every == 0:
                self.views.write_state(t, st)
                self.episode.draw(self.views, t, st)
        self.drain(now)

    def drain(self, now: float) -> None:
        """Record what other sessions sent under ``<root>/**`` since the last drain: log time
        ``now``, the server's sim time; publish time the message's checked stamp. One batch
        a tick: no thread wakes up per message."""
        put = zenoh.SampleKind.PUT
        check = self.record_filter.check
        taken = 0
        while (sample := self.record_sub.try_recv()) is not None:
            taken += 1
            if sample.kind != put:
                continue
            key, payload = str(sample.key_expr), sample.payload.to_bytes()
            stamp = check(key, payload, now)
            if stamp is not None:
                self.recorder.write(key, payload, now, stamp)
                self.recorded += 1
        if taken >= RECORD_QUEUE:
            self.record_full += 1
            if self.record_full == 1:
                log.warning("the recording queue was full at sim time %.3f s (%d samples since the last drain): "
                            "its oldest may have been lost, uncounted", now, taken)
