"""What the world sends each tick and what it logs: per robot the readings its graph reads
(the world's :mod:`world.sense` encoders, and the episode's other readings), the clock and the ground-truth state; a stalled
lockstep tick published again for the robots still waiting; and the tick's log (what the
world sent, its Foxglove views, and what other sessions sent, drained once per tick
through :class:`world.recorder.RecordFilter`)."""

from __future__ import annotations

from typing import Any

import zenoh

from cekm_swarm.protocol import Clock, KeySpace, WorldState, encode

from .episode import RunEpisode, TickReadings
from .recorder import RecordFilter
from .sense import SENDER, SenseEncoder


class TickPublisher:
    """Publish and log one run's ticks (set up by the world server once its session is open)."""

    def __init__(self, keys: KeySpace, world: Any, episode: RunEpisode, sends: dict[str, set[str]] | None,
                 record_filter: RecordFilter) -> None:
        self.keys, self.world, self.episode = keys, world, episode
        self.sends = sends  # robot -> the sense keys its graph reads (None: every one of the task)
        self.record_filter = record_filter
        self.pubs: Any = None  # runtime.bridge.Publishers
        self.recorder: Any = None  # runtime.mcap_log.McapRecorder
        self.views: Any = None  # Foxglove views, when foxglove-sdk is installed
        self.record_sub: Any = None  # Zenoh subscriber with a ring channel (RECORD_QUEUE)
        self.recorded = 0
        self.republished = 0
        self.last_target: dict[str, bytes] = {}  # the latest target reading's payload, per robot
        self.last_messages: dict[str, list[tuple[str, Any]]] = {}  # the episode's latest other readings, per robot
        self._encoders: dict[str, SenseEncoder] = {}
        self._unrecorded: list[tuple[str, bytes, float]] = []
        self._unviewed: tuple[float, dict[str, Any]] | None = None  # the tick's (t, state) for the views

    # ------------------------------------------------------------------ sending

    def _send(self, key: str, msg: Any) -> None:
        """Publish ``msg``; it is logged by :meth:`record_sent` (the record subscription
        sees only other sessions)."""
        self._put(key, encode(msg), msg.stamp)

    def _put(self, key: str, payload: bytes, stamp: float) -> None:
        self.pubs.put(key, payload)
        self._unrecorded.append((key, payload, stamp))

    def _sense(self, rd: TickReadings) -> list[tuple[str, bytes]]:
        enc = self._encoders.get(rd.robot)
        if enc is None:
            w = self.world
            enc = self._encoders[rd.robot] = SenseEncoder(self.keys, rd.robot, w.sensor_angles, w.body_radius)
        return enc(rd)

    def _wanted(self, robot: str) -> set[str] | None:
        return None if self.sends is None else self.sends[robot]

    def publish(self, readings: list[TickReadings]) -> dict[str, Any]:
        """The tick's readings, clock and state (in this order); returns the state."""
        ep = self.episode
        for rd in readings:
            want = self._wanted(rd.robot)
            for key, payload in self._sense(rd):
                if want is None or key in want:
                    self._put(key, payload, rd.t)
            if rd.target is not None:
                self.last_target[rd.robot] = payload  # the last one: the target's
            more = ep.messages(rd.robot)
            if more:
                self.last_messages[rd.robot] = more
            self._send_more(rd.robot, more, want)
        self._send(self.keys.world_clock(), Clock(ep.t, SENDER, ep.tick))
        st = self.world.state()
        self._send(self.keys.world_state(), WorldState(ep.t, SENDER, st["robots"], st["targets"], st["obstacles"]))
        self._unviewed = (ep.t, st)
        return st

    def _send_more(self, robot: str, more: list[tuple[str, Any]], want: set[str] | None) -> None:
        for rel, msg in more:
            key = self.keys.node_key(robot, rel)
            if want is None or key in want:
                self._send(key, msg)

    def republish(self, readings: list[TickReadings], waiting: list[str]) -> None:
        """The stalled tick's readings again (and each robot's latest target or tracking
        reading), for the robots still waiting: a restarted node catches up."""
        n = len(self.world.sensor_angles)
        for rd in readings:
            if rd.robot not in waiting:
                continue
            want = self._wanted(rd.robot)
            for key, payload in self._sense(rd)[:n]:
                if want is None or key in want:
                    self._put(key, payload, rd.t)
            last = self.last_target.get(rd.robot)
            if last is not None and (want is None or self.keys.sense_target(rd.robot) in want):
                self._put(self.keys.sense_target(rd.robot), last, rd.t)
            self._send_more(rd.robot, self.last_messages.get(rd.robot, []), want)  # tracking: the latest pose, targets
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
            if self.views is not None:
                self.views.write_state(t, st)
                self.episode.draw(self.views, t, st)
        self.drain(now)

    def drain(self, now: float) -> None:
        """Record what other sessions sent under ``<root>/**`` since the last drain: log time
        ``now``, the server's sim time; publish time the message's checked stamp. One batch
        a tick: no thread wakes up per message."""
        put = zenoh.SampleKind.PUT
        check = self.record_filter.check
        while (sample := self.record_sub.try_recv()) is not None:
            if sample.kind != put:
                continue
            key, payload = str(sample.key_expr), sample.payload.to_bytes()
            stamp = check(key, payload, now)
            if stamp is not None:
                self.recorder.write(key, payload, now, stamp)
                self.recorded += 1
