"""The gate of a node that runs on every value as it comes (an obstacle localization
module): the rule of :mod:`cekm_swarm.node.timing` for a stateless node of one key."""

from __future__ import annotations

from collections import deque
from collections.abc import Collection, Iterable
from typing import Any

from cekm_swarm.graph.plan import NodePlan
from cekm_swarm.protocol import Nothing
from cekm_swarm.ticks import tick_of

from .api import Inputs
from .runner import Runner
from .timing import RESEND_RUNS, Drop, GateCounts


class DirectGate:
    """The gate of a node that keeps no state and reads one key of its own period at the
    same tick (an obstacle localization module: ``sense/range/j`` every tick): the rule
    then is to run on every value as it comes, in lockstep and in real time alike. A value
    that comes again (the world re-publishing a stalled tick) runs again and gives the
    same outputs, which is the catch-up the other gates do by sending again; its recent
    runs' outputs are kept for a reader of them that (re)appears (:meth:`resend`)."""

    def __init__(self, runner: Runner, drop: Drop = lambda key, why: None) -> None:
        self.runner, self.drop = runner, drop
        node = runner.plan
        (b,) = node.bindings
        (self.source,) = b.sources
        self.key, self.port = self.source.key, b.port
        self.repeats = 0
        self.recent_out: deque[list[tuple[str, Any]]] = deque(maxlen=RESEND_RUNS)

    @staticmethod
    def fits(node: NodePlan) -> bool:
        """Whether ``node`` may take this gate."""
        if node.stateful or node.clock_key is not None or len(node.bindings) != 1:
            return False
        b = node.bindings[0]
        return (len(b.sources) == 1 and b.delay == 0 and not b.team and not b.many
                and b.sources[0].period == node.period)

    def put(self, key: str, msg: Any) -> list[tuple[str, Any]]:
        if key != self.key:
            return []
        sent = self.runner.run(tick_of(msg.stamp), Inputs({self.port: None if type(msg) is Nothing else msg}))
        self.recent_out.append(sent)
        return sent

    def hold(self, key: str, k: int, since: int) -> list[tuple[str, Any]]:
        return []  # its one input is a reading: a held reading is a run left out, nothing to do

    def hold_all(self, holds: Iterable[tuple[str, int, int]]) -> list[tuple[str, Any]]:
        return []

    def teammate(self, robot: str, alive: bool) -> list[tuple[str, Any]]:
        return []

    def resend(self, keys: Collection[str] | None = None) -> list[tuple[str, Any]]:
        """The recent runs' outputs (on ``keys``, or all), oldest first (a reader reading
        them with ``delay = 1`` that restarted needs a run before the stalled tick's)."""
        return [m for run in self.recent_out for m in run if keys is None or m[0] in keys]

    def counts(self) -> GateCounts:
        return GateCounts(repeats=self.repeats)
