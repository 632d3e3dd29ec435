"""The world server's two clock policies: when a tick's commands are taken.

* :class:`LockstepClock`: the world advances only when every robot's answer for the tick
  is in; after ``republish`` s without it, the tick's readings go out again for the robots
  still waiting (a restarted node catches up).
* :class:`RealtimeClock`: ticks follow the wall clock, which (when the nodes are known to
  listen) starts once every robot has answered tick 0 (at most :data:`FIRST_TICK_WAIT_S`:
  a start-up burst is not a missed deadline). At each tick boundary the latest command of
  each robot is applied; a robot whose commands have stopped is stopped (the dead-man),
  and a robot whose latest command is older than the tick has missed its deadline (older
  than ``deadline_ticks`` ticks, on a link whose round trip is longer than a tick).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from typing import Any

from cekm_swarm.ticks import TICK_S

from .inbox import CommandInbox
from .outcome import RunStats
from .publisher import TickPublisher
from .sense import TickReadings

RECORD_BY = 0.75
"""Real time: the fraction of a tick by which the world writes the tick's log if some
robot's command is still missing (it writes it as soon as every command is in). Written
right after the readings went out, the log (about a seventh of the world's CPU, some 5 ms
a tick with 16 robots) landed in the burst in which every robot's nodes compete for the
two cores."""

FIRST_TICK_WAIT_S = 10.0
"""Real time: how long the world waits for every robot's answer to tick 0 before its wall
clock starts anyway."""


def late_ticks(t: float, stamp: float) -> int:
    """How many ticks a command stamped ``stamp`` lags the tick at ``t`` (0: it is that
    tick's own command): the deadline rule's measure and ``command_age_ticks``'."""
    return round((t - stamp) / TICK_S)


def missed_deadline(t: float, stamp: float | None, deadline_ticks: int = 0) -> bool:
    """The deadline rule: the command applied at the tick at ``t`` (stamped ``stamp``; None:
    the robot never sent one) is a miss when it lags the tick by more than ``deadline_ticks``
    ticks. 0, the default, asks each tick's own command by the end of that tick."""
    return stamp is None or late_ticks(t, stamp) > deadline_ticks


RTO_MIN_S = 0.2
"""Linux's least TCP retransmission timeout: a lost segment is sent again a round trip plus
this after it first left (and everything behind it on the connection waits for it)."""


def link_deadline_ticks(one_way_delay: float, jitter: float = 0.0, *, lossy: bool = True,
                        compute: float = 0.02) -> int:
    """The deadline allowance (``--deadline-ticks``) a TCP link of this one-way delay needs
    so that only what really went wrong counts as a miss. A tick's readings leave at its
    start, cross the link, the robot computes (``compute`` s) and its command crosses back,
    due by the end of tick k + N, (N + 1) ticks later. On a ``lossy`` link each crossing may
    also wait one retransmission (a round trip plus :data:`RTO_MIN_S`): the two crossings
    lose packets independently, so the allowance covers one on each. 50 ms one way, lossy:
    5 (0.77 s); without loss: 0. docs/faults.md, 'Real time under delay and loss'."""
    if one_way_delay < 0 or jitter < 0 or compute < 0:
        raise ValueError(f"delay, jitter and compute must be >= 0 s, got {one_way_delay}, {jitter}, {compute}")
    crossing = one_way_delay + jitter
    if lossy:
        crossing += 2 * one_way_delay + RTO_MIN_S
    return max(0, math.ceil((2 * crossing + compute) / TICK_S) - 1)


class Stopped(Exception):
    """The run was stopped (a signal, missing nodes) while a clock waited."""


class _Clock:
    def __init__(self, inbox: CommandInbox, publisher: TickPublisher, episode: Any, stats: RunStats,
                 stop: asyncio.Event, arrived: asyncio.Event) -> None:
        self.inbox, self.publisher, self.episode, self.stats = inbox, publisher, episode, stats
        self.stop, self.arrived = stop, arrived

    def opened(self) -> None:
        """The tick's readings are out: log now or later (the policy decides)."""

    async def _await_answers(self, until: float) -> None:
        """Wait until every robot's command for the current tick is in, the run is stopped,
        or the loop's clock reaches ``until`` (the inbox wakes us once per tick)."""
        loop = asyncio.get_running_loop()
        inbox = self.inbox
        while not inbox.answered() and not self.stop.is_set() and loop.time() < until:
            self.arrived.clear()
            if inbox.answered():  # a command in between: its wake-up came before the clear
                break
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.arrived.wait(), max(0.0, until - loop.time()))


class LockstepClock(_Clock):
    def __init__(self, *args: Any, republish: float) -> None:
        super().__init__(*args)
        self.republish = republish

    def opened(self) -> None:
        self.publisher.record_tick(self.inbox.now)  # the nodes compute now, and the log is written meanwhile

    async def commands(self, readings: list[TickReadings]) -> dict[str, tuple[float, float]]:
        t = self.episode.t
        loop = asyncio.get_running_loop()
        next_republish = loop.time() + self.republish
        while True:
            waiting = self.inbox.waiting(t)
            if not waiting:
                return self.inbox.commands()
            if self.stop.is_set():
                raise Stopped
            self.arrived.clear()
            timeout = next_republish - loop.time()
            if timeout <= 0:
                self.stats.event("republish", t, {"waiting": waiting})
                self.publisher.republish(readings, waiting)
                next_republish = loop.time() + self.republish
                continue
            with contextlib.suppress(TimeoutError):  # woken when the tick is answered, or by a stop (sets both)
                await asyncio.wait_for(self.arrived.wait(), timeout)


class RealtimeClock(_Clock):
    def __init__(self, *args: Any, deadman: Any, wait_first: bool, deadline_ticks: int = 0) -> None:
        super().__init__(*args)
        self.deadman = deadman
        self.deadline_ticks = deadline_ticks  # a command for tick k is on time until the end of tick k + this
        self.wait_first = wait_first
        self.start: float | None = None

    async def _first_answers(self) -> float:
        """Wait (at most :data:`FIRST_TICK_WAIT_S`) until every robot's command for tick 0
        is in, and return the loop time at which the wall clock starts: tick 0's deadline
        is then a tick later. The first message every process handles, and the router's
        first routing of every key, cost a start-up burst of a few hundred ms (16 robots:
        0.3 s). How long it took is ``first_tick_ms`` in ``outcome.json``."""
        loop = asyncio.get_running_loop()
        await self._await_answers(loop.time() + FIRST_TICK_WAIT_S)
        waiting = self.inbox.waiting(self.inbox.now)
        if waiting and not self.stop.is_set():
            self.stats.event("first_tick_unanswered", self.episode.t,
                             {"after_s": FIRST_TICK_WAIT_S, "waiting": waiting})
        sent = self.inbox.published_at(self.inbox.now)
        self.stats.first_tick_s = time.monotonic() - (time.monotonic() if sent is None else sent)
        return loop.time()

    async def commands(self, readings: list[TickReadings]) -> dict[str, tuple[float, float]]:
        loop = asyncio.get_running_loop()
        ep = self.episode
        if self.start is None:  # the wall clock starts once tick 0 is answered (or now, when
            # the world was not told to wait for the nodes: none may listen yet)
            self.start = await self._first_answers() if self.wait_first else loop.time()
        boundary = self.start + (ep.tick + 1) * TICK_S
        await self._await_answers(boundary - (1 - RECORD_BY) * TICK_S)  # the tick's burst
        self.publisher.record_tick(self.inbox.now)
        try:
            await asyncio.wait_for(self.stop.wait(), max(0.0, boundary - loop.time()))
            raise Stopped
        except TimeoutError:
            pass
        now = time.monotonic()
        commands = {}
        for r in self.inbox.robots:
            c = self.inbox.latest.get(r)
            if missed_deadline(ep.t, None if c is None else c.stamp, self.deadline_ticks):
                self.stats.missed(ep.tick)
            was_stopped = self.deadman.stopped[r]
            stop, newly = self.deadman.check(r, now, TICK_S)
            if stop or c is None:
                commands[r] = (0.0, 0.0)
                if newly:
                    self.stats.event("deadman", ep.t, {"robot": r, "silent_s": round(now - self.deadman.last[r], 4),
                                                       "limit_s": self.deadman.limit, "wall": time.time()})
            else:
                commands[r] = (c.v_l, c.v_r)
                self.stats.applied(late_ticks(ep.t, c.stamp))
                if was_stopped:  # its commands are back: it drives on
                    self.stats.event("deadman_resumed", ep.t, {"robot": r, "wall": time.time()})
        return commands
