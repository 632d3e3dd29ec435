"""A real-time node on a timer of its own rate (a graph's ``timer = S``): it runs every S
seconds of wall time, not when its inputs of a tick are in.

Each run is at the newest tick the node has heard of (any input's value, or the world's
clock, to which such a node always listens), with the newest value of each input as
:class:`~.timing.RealtimeGate` gives it (its staleness limit applied; a delayed input's
value of that same tick is not yet its own); its outputs are stamped with that tick. It
runs at most once a tick: a timer due while no new tick has begun skips that run
(``idle``), as its inputs cannot have changed; a run late on its timer (a slow step, a
busy host) is not made up, the next is one period after it. In lockstep and in ``cekm run``
the timer is not used: the node runs at its ``every`` (or its inputs' rate), so the run
stays reproducible.

Plain Python, free of Zenoh: :meth:`TimerGate.fire` is called by the node's process
(:mod:`.process`) from its timer thread, under the node's lock; :class:`Timer` is that
thread's schedule."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

from cekm_swarm.graph.plan import NodePlan

from .timing import RealtimeGate


@dataclass
class TimerGate(RealtimeGate):
    """:class:`~.timing.RealtimeGate` whose runs come from :meth:`fire`, not from arrivals."""

    clock_key: str | None = None
    idle: int = 0  # timer fires with no new tick: nothing to run

    def __post_init__(self) -> None:
        super().__post_init__()
        self._period = 1  # every value's tick is the newest tick heard of
        self.trigger = frozenset(self.watched | ({self.clock_key} if self.clock_key is not None else set()))

    def _open(self, key: str, k: int) -> list[tuple[str, Any]]:
        self.open_tick = max(self.open_tick, k)
        return []

    def _complete(self, c: int) -> bool:
        return False  # never on an arrival: on the timer

    def fire(self) -> list[tuple[str, Any]]:
        """The timer is due: run at the newest tick heard of, once."""
        if self.open_tick <= self.done:
            self.idle += 1
            return []
        return self._run(self.open_tick)

    @staticmethod
    def fits(node: NodePlan, mode: str) -> bool:
        """Whether ``node`` runs on its timer in ``mode`` (real time, a ``timer`` declared)."""
        return mode == "realtime" and node.decl.timer is not None


@dataclass
class Timer:
    """The wall times of a timer of period ``period_s``, on a fixed grid from its first
    :meth:`wait`: each returns how long to wait for the next grid time not yet past (a
    run late by more than a period is not made up: the times it missed are skipped)."""

    period_s: float
    due: float = -1.0

    def wait(self, now: float | None = None) -> float:
        now = time.monotonic() if now is None else now
        p = self.period_s
        if self.due < 0:
            self.due = now + p
        else:
            self.due += p
            if self.due < now:
                self.due += p * math.ceil((now - self.due) / p)
        return max(0.0, self.due - now)
