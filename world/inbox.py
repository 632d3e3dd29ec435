"""The world's command inbox: each robot's latest answer to a tick (its wheel command), taken
on Zenoh's receiving thread, checked (a believable stamp of a tick already out, not older
than the robot's latest), with when it was heard (the dead-man) and how long after the
tick's readings it came (sense-to-command latency). The tick loop reads it whole."""

from __future__ import annotations

import collections
import time
from collections.abc import Callable

from cekm_swarm.protocol import DropCounter, WheelCommand
from cekm_swarm.protocol.stamps import PAST_S, stamp_problem
from cekm_swarm.runtime.bridge import Received
from cekm_swarm.runtime.percentiles import Samples

from .deadman import Deadman

SENT_KEPT = 64
"""Ticks whose publication time the inbox keeps (for the latency of late answers)."""


class CommandInbox:
    """Answers of the run's robots, by answer key (``RunPlan.answer_key``)."""

    def __init__(self, robots: list[str], answer_keys: dict[str, str], drops: DropCounter, deadman: Deadman) -> None:
        self.robots = robots
        self.answer_keys = answer_keys  # key -> robot
        self.drops = drops
        self.deadman = deadman
        self.latest: dict[str, WheelCommand] = {}
        self.late_commands = 0
        self.now = 0.0  # the sim time of the tick whose readings are out (read by Zenoh's thread)
        self.sent_at: dict[float, float] = {}
        self.latencies = Samples()  # s from publishing a tick's readings to its answer (fixed memory)
        self._pending: collections.deque[tuple[str, float, float]] = collections.deque()
        self._seen: dict[tuple[str, float], float] = {}
        self._answered: set[str] = set()  # robots heard for the tick at ``now`` (a count, checked when full)
        self.wake: Callable[[], None] = lambda: None  # set by the run: wakes the tick loop

    def opened(self, t: float) -> None:
        """The tick at sim time ``t`` is out: answers from here on may be for it."""
        self._answered = set()  # before ``now`` moves: an answer taken meanwhile is checked again in answered()
        self.now = t
        self.sent_at[t] = time.monotonic()
        if len(self.sent_at) > SENT_KEPT:
            self.sent_at.pop(next(iter(self.sent_at)))

    def on_command(self, rec: Received) -> None:
        """An answer sample, on Zenoh's receiving thread: keep the robot's latest command,
        note when it was heard (dead-man) and how long after its tick's readings it came;
        wake the tick loop once the tick is answered. Touches only what the loop reads whole."""
        robot = self.answer_keys.get(rec.key)
        if robot is None:
            if rec.kind == "put":
                self.drops.drop(rec.key, "no robot of this run has this key")
            return
        if rec.kind != "put":
            return
        msg = self.drops.decode(rec.key, rec.payload)
        if not isinstance(msg, WheelCommand):
            return
        why = stamp_problem(msg.stamp, self.now, PAST_S, 0.0)  # a command is for a tick already out
        if why is not None:
            self.drops.drop(rec.key, why)
            return
        if (old := self.latest.get(robot)) is not None and msg.stamp < old.stamp:
            self.late_commands += 1  # believable but superseded (a motor's repeat for a re-published tick)
            return
        self.latest[robot] = msg
        if msg.stamp == self.now:
            self._answered.add(robot)
        self.deadman.heard(robot, rec.at)
        sent = self.sent_at.get(msg.stamp)
        if sent is not None:
            self._pending.append((robot, msg.stamp, rec.at - sent))
        if self.answered():  # one wake-up of the tick loop per tick, not per robot
            self.wake()

    def waiting(self, t: float) -> list[str]:
        """The robots whose latest command is not for the tick at sim time ``t``."""
        return [r for r in self.robots if (c := self.latest.get(r)) is None or c.stamp != t]

    def answered(self) -> bool:
        """Every robot's latest command is for the current tick (on Zenoh's thread, per
        command): a count of the robots heard for it, and the whole check only once the count
        is full (an answer taken while the tick turned may be counted for the wrong one), so
        a tick's answers cost O(robots), not O(robots^2)."""
        if len(self._answered) < len(self.robots):
            return False
        now, latest = self.now, self.latest
        return all((c := latest.get(r)) is not None and c.stamp == now for r in self.robots)

    def commands(self) -> dict[str, tuple[float, float]]:
        """Every robot's latest wheel speeds (lockstep: the tick's answers)."""
        return {r: (self.latest[r].v_l, self.latest[r].v_r) for r in self.robots}

    def collect_latency(self, t: float, keep: bool) -> None:
        """Each robot's latency for tick ``t``: to the last command stamped ``t`` heard so far
        (in real time the motor may send several per tick); ``keep`` False for tick 0 in
        real time (the start-up burst: ``first_tick_ms``)."""
        seen = self._seen
        while self._pending:
            robot, stamp, lat = self._pending.popleft()
            seen[(robot, stamp)] = lat
        for r in self.robots:
            answered = seen.pop((r, t), None)
            if answered is not None and keep:
                self.latencies.append(answered)
        for k in [k for k in seen if k[1] <= t]:
            del seen[k]

    def published_at(self, t: float) -> float | None:
        return self.sent_at.get(t)

