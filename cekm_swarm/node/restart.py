"""What a restarted lockstep node process may run without (the restart rules of
:class:`~.timing.LockstepGate`, module docstring of :mod:`.timing`): the delayed values from
before its first run that nobody sends again (:func:`lost_on_restart`, :class:`FirstRun`),
and the delayed values it gives up once the tick it waits at is re-published (:class:`GiveUp`).
Plain state, no I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass, field

from cekm_swarm.graph.plan import WORLD_OWNER, NodePlan, Source, needed_tick


def lost_on_restart(node: NodePlan) -> frozenset[str]:
    """The delayed sources of ``node`` whose values of the ticks before a (re)started
    process's first run nobody sends again: its own outputs read back with ``delay = 1``
    (it sent them itself, in its life before) and the world's readings read with
    ``delay = 1`` (the world sends a stalled tick again, not the one before it). Every
    other producer is a node that sends its recent outputs again when a reader of them
    (re)appears (:meth:`~.timing.LockstepGate.resend`). A restarted node with such a source starts
    without those values, as at tick 0, so the run may no longer equal ``cekm run``."""
    own = set(node.outputs.values())
    return frozenset(s.key for b in node.bindings if b.delay == 1 for s in b.sources
                     if s.key in own or s.owner == WORLD_OWNER)


@dataclass
class FirstRun:
    """The first run of this process, and the delayed values from before it that nobody
    sends again (:func:`lost_on_restart`): a run leaves them out, as before tick 0."""

    lost_keys: frozenset[str]
    born: int | None = None  # the tick of this process's first run
    # not known to have run from tick 0: it has not run yet, or first ran after it (a plain
    # attribute, not a property: the gate asks on every value that opens a tick)
    maybe_restarted: bool = True

    def lost(self, key: str, n: int) -> bool:
        """Whether ``key``'s value of tick ``n`` predates the first run and is not coming."""
        return key in self.lost_keys and (self.born is None or n < self.born)

    def ran(self, c: int) -> None:
        if self.born is None:
            self.born = c
            self.maybe_restarted = c > 0


@dataclass
class GiveUp:
    """A restarted process gives up the delayed values still missing once a trigger's
    value of a tick it waits at comes again, re-published (module docstring), and names
    the keys a run went without."""

    delayed: dict[str, Source]  # every delayed source: key -> source
    seen: dict[str, set[int]] = field(default_factory=dict)  # trigger key -> ticks not yet run whose value came
    gave_up_at: int | None = None  # the latest tick whose trigger's value came again while it waited
    without: set[str] = field(default_factory=set)  # delayed keys a run went without, having given up

    def trigger_came(self, key: str, k: int) -> None:
        """A trigger's value of tick ``k`` (not run yet): a second one is a re-published tick."""
        seen = self.seen.setdefault(key, set())
        if k in seen and (self.gave_up_at is None or k > self.gave_up_at):
            self.gave_up_at = k  # this tick again, re-published: what a restarted process lacks is not coming
        seen.add(k)

    def lost(self, key: str, n: int) -> bool:
        """Whether ``key``'s value of tick ``n`` is a delayed value given up for."""
        return self.gave_up_at is not None and n < self.gave_up_at and key in self.delayed

    def before_run(self, c: int, has: Callable[[str, int], bool], first: FirstRun, gone: Collection[str]) -> None:
        """The run at tick ``c`` goes without the given-up delayed values it lacks: name them."""
        if self.gave_up_at is None:
            return
        self.without.update(
            key for key, s in self.delayed.items()
            if key not in first.lost_keys and s.owner not in gone
            and (n := needed_tick(c, s.period, 1)) is not None and n < self.gave_up_at and not has(key, n))

    def ran(self, c: int) -> None:
        if self.seen:
            self.seen = {key: {x for x in seen if x > c} for key, seen in self.seen.items()}

    @property
    def ran_without(self) -> tuple[str, ...]:
        """The delayed keys a run went without, having given up (sorted)."""
        return tuple(sorted(self.without))


__all__ = ["FirstRun", "GiveUp", "lost_on_restart"]
