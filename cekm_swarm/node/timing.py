"""When a node runs and what it sees: the one rule of :mod:`cekm_swarm.graph.plan`, for a
node in its own process (lockstep and real time) and for a whole graph in one process.

* :func:`gather` builds a step's inputs at tick k from any store of received values, by
  the rule (delay 0: the producer's latest run at or before k; delay 1: strictly before).
* :class:`~cekm_swarm.node.direct_gate.DirectGate`: a stateless node of one key runs on
  every value as it comes, in both modes.
* :class:`LockstepGate`: a node runs at a due tick once it holds every value the rule
  names from every live producer, whatever order they arrive in; ticks run in increasing
  order. A value that arrives again for what the last run used (the world re-publishes a
  stalled tick so a restarted module catches up) makes it send that run's outputs again;
  ``resend(keys)`` gives its recent runs' outputs again, for a reader of them that
  (re)appeared. A delayed value nobody can send again (:func:`lost_on_restart`: its own
  previous output, a world reading of a tick before) is left out of its first run, as
  before tick 0 (:class:`~.restart.FirstRun`). A restarted process (one whose first run was after
  tick 0, or that has not run yet) gives up any other delayed value still missing once a
  trigger's value of the tick it waits at comes again (:class:`~.restart.GiveUp`): the world
  re-publishing a stalled tick, a second or more later, means that value's producer
  restarted too and has nothing of that tick to send again (two teammates' tracking
  modules killed together waited for each other's share for good; in waves, a later run
  waited for one only the producer's previous life had). The gate names those keys
  (``ran_without``), and the run may no longer equal ``cekm run``; a process that has run
  since tick 0 never gives up.
* :class:`RealtimeGate`: a node runs at its newest due tick as soon as every live
  same-tick producer has delivered (or at once, with what came, when a later tick
  begins), with the latest value of each source; a value older than its staleness limit
  counts as missing.
* ``hold(key, k, since)`` (both gates): the source's value of tick ``since`` stands for
  tick ``k`` as well, restamped: its producer is a pure node whose one reading was
  unchanged at k, so the world left that reading out and the producer did not run
  (:meth:`cekm_swarm.graph.plan.RunPlan.held_readings`). ``hold_all`` takes every hold
  of one ``Unchanged`` message and looks for runs once, after them all.

Plain Python, free of Zenoh (fed by :mod:`.process` and :mod:`.inprocess`). A ``Nothing``
is a value: the reader sees None (no entry in a many-key port) and does not wait for it.
"""

from __future__ import annotations

import copy
import logging
from collections import deque
from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass, field
from typing import Any

from msgspec import Struct

from cekm_swarm.graph.plan import Binding, NodePlan, needed_tick
from cekm_swarm.protocol import Nothing
from cekm_swarm.ticks import TICK_S, tick_of, tick_time

from .api import Inputs, NotReady
from .restart import FirstRun, GiveUp, lost_on_restart
from .runner import Runner

log = logging.getLogger("cekm_swarm.node")

KEEP_TICKS = 64
"""Ticks of received values a gate keeps behind its last run (a bound whatever arrives)."""

RESEND_RUNS = 4
"""Runs whose outputs a gate keeps to send again to a reader of them that (re)appears."""

Drop = Callable[[str, str], None]
"""Called with (source key, reason) for a value a gate refuses (the shell counts it)."""


def restamp(msg: Any, t: float) -> Any:
    """``msg`` as its pure producer would have sent it at tick time ``t``: a shallow copy,
    not checked again (``msg`` was checked when received; ``t`` is a tick's time)."""
    out = msg.__copy__() if isinstance(msg, Struct) else copy.copy(msg)  # type: ignore[attr-defined]  # msgspec's stub omits Struct.__copy__
    out.stamp = t
    return out


def _never(owner: str) -> bool:
    return False


def _kept(key: str, tick: int) -> bool:
    return False


def gather(node: NodePlan, k: int, lookup: Callable[[str, int], Any], skip: Callable[[str], bool] = _never,
           lost: Callable[[str, int], bool] = _kept) -> tuple[Inputs, list[str]]:
    """The inputs of ``node``'s run at tick ``k``, by the rule, from ``lookup(key, tick)``
    (a message or None); and the keys still missing (a source whose owner ``skip`` names,
    a gone teammate, is not missing; nor a value ``lost(key, tick)`` says nobody can send
    again). Many-key ports hold what is there, in source order."""
    values: dict[str, Any] = {}
    missing: list[str] = []
    for b in node.bindings:
        delay = b.delay
        if b.many:
            got = {}
            for s in b.sources:
                n = needed_tick(k, s.period, delay)
                if n is None or skip(s.owner):
                    continue
                m = lookup(s.key, n)
                if m is not None:
                    got[s.label] = m
                elif not lost(s.key, n):
                    missing.append(s.key)
            values[b.port] = {lab: m for lab, m in got.items() if type(m) is not Nothing}  # Nothing: no entry
        else:
            s = b.sources[0]
            n = needed_tick(k, s.period, delay)
            m = None if n is None else lookup(s.key, n)
            if m is None and n is not None and not skip(s.owner) and not lost(s.key, n):
                missing.append(s.key)
            values[b.port] = None if type(m) is Nothing else m
    return Inputs(values), missing


@dataclass(frozen=True)
class GateCounts:
    """What a gate counted, for the node's report: values that came again for the last
    run (lockstep), stale values left out and due ticks given up (real time), and the
    delayed keys a restarted process ran without (lockstep, :class:`~.restart.GiveUp`)."""

    repeats: int = 0
    stale: dict[str, int] = field(default_factory=dict)
    not_ready: int = 0
    ran_without: tuple[str, ...] = ()


def _triggers(node: NodePlan) -> frozenset[str]:
    """Keys whose value of a tick opens that tick: every same-tick source, and the clock."""
    keys = {s.key for b in node.bindings if b.delay == 0 for s in b.sources}
    return frozenset(keys | ({node.clock_key} if node.clock_key is not None else set()))


@dataclass
class LockstepGate:
    """A node's lockstep timing (see the module docstring). ``put(key, msg)`` returns the
    messages to send now; ``teammate(robot, alive)`` marks a teammate gone or back."""

    runner: Runner
    drop: Drop = lambda key, why: None
    done: int = -1
    last_out: list[tuple[str, Any]] = field(default_factory=list)
    recent_out: deque[list[tuple[str, Any]]] = field(default_factory=lambda: deque(maxlen=RESEND_RUNS))
    used: dict[str, int] = field(default_factory=dict)
    gone: set[str] = field(default_factory=set)
    store: dict[str, dict[int, Any]] = field(default_factory=dict)
    candidates: set[int] = field(default_factory=set)
    repeats: int = 0
    holds: int = 0
    pending_holds: dict[str, dict[int, list[int]]] = field(default_factory=dict)  # key -> since -> [ticks]

    def __post_init__(self) -> None:
        self.node = self.runner.plan
        self.trigger = _triggers(self.node)
        self.watched = {s.key for b in self.node.bindings for s in b.sources}
        self.sources = {s.key: (s, b.delay) for b in self.node.bindings for s in b.sources}
        self._needs = [(s.key, s.period, b.delay, s.owner) for b in self.node.bindings for s in b.sources]
        self._waiting: dict[int, tuple[str, int, str]] = {}  # candidate tick -> a value it still lacks
        self.first_run = FirstRun(lost_on_restart(self.node))
        self._lost_keys = self.first_run.lost_keys
        self.give_up = GiveUp({key: s for key, (s, delay) in self.sources.items() if delay == 1})

    @property
    def born(self) -> int | None:
        """The tick of this process's first run (None before it)."""
        return self.first_run.born

    @property
    def ran_without(self) -> tuple[str, ...]:
        """The delayed keys a run of this (restarted) process went without (module docstring)."""
        return self.give_up.ran_without

    def counts(self) -> GateCounts:
        return GateCounts(repeats=self.repeats, ran_without=self.ran_without)

    def _lost(self, key: str, n: int) -> bool:
        """Whether ``key``'s value of tick ``n`` predates this process's first run and nobody
        sends it again, or is a delayed value given up for (module docstring). Asked for
        most values a run waits for: the rules are asked only when they can apply (a key
        they may lose; a process that has given up)."""
        return ((key in self._lost_keys and self.first_run.lost(key, n))
                or (self.give_up.gave_up_at is not None and self.give_up.lost(key, n)))

    def _has(self, key: str, n: int) -> bool:
        return n in self.store.get(key, ())

    def _lacks(self, c: int) -> bool:
        """Whether the run at tick ``c`` still lacks a value, the one it lacked last time
        looked at first: most arrivals complete no run, and this spares building their inputs."""
        store, gone, w = self.store, self.gone, self._waiting.get(c)
        if w is not None and w[2] not in gone and w[1] not in store.get(w[0], ()) and not self._lost(w[0], w[1]):
            return True
        for key, period, delay, owner in self._needs:
            n = needed_tick(c, period, delay)
            if n is not None and owner not in gone and n not in store.get(key, ()) and not self._lost(key, n):
                self._waiting[c] = (key, n, owner)
                return True
        self._waiting.pop(c, None)
        return False

    def hold(self, key: str, k: int, since: int) -> list[tuple[str, Any]]:
        """``key``'s value of tick ``since`` stands for tick ``k`` (module docstring)."""
        return self.hold_all(((key, k, since),))

    def hold_all(self, holds: Iterable[tuple[str, int, int]]) -> list[tuple[str, Any]]:
        """Every ``(key, k, since)`` of one ``Unchanged`` message, then one look for runs
        (a run at tick c reads only values of c and before, so the order is the same as
        one hold after another; the looks in between found nothing new)."""
        opened = False
        for key, k, since in holds:
            if self._hold_one(key, k, since):
                self._open_candidates(key, k)
                opened = True
        return self._advance() if opened else []

    def _hold_one(self, key: str, k: int, since: int) -> bool:
        """Restamp the value standing for ``k``; False when there is none (yet) or it is too old."""
        if key not in self.watched or k <= self.done or k <= since:
            return False
        held = self.store.setdefault(key, {})
        if k not in held:
            msg = held.get(since)
            if msg is None:  # the value of since, or one standing for a tick after it, restamped
                later = [t for t in held if since < t < k]
                msg = held[max(later)] if later else None
            if msg is None:  # not here yet (or lost with a restart: the world's re-publishing brings it)
                self.pending_holds.setdefault(key, {}).setdefault(since, []).append(k)
                return False
            held[k] = restamp(msg, tick_time(k))
            self.holds += 1
        return True

    def _opened(self, key: str, k: int) -> list[tuple[str, Any]]:
        self._open_candidates(key, k)
        return self._advance()

    def _open_candidates(self, key: str, k: int) -> None:
        """A trigger's value of tick ``k`` opens tick k, if the node is due then. Only k: a
        later tick is opened by its own values (every due tick has a same-tick source of a
        period dividing it, or the world's clock: ``graph.resolve.timed_by``), so the node
        never answers a tick before the world has begun it."""
        if key in self.trigger and k > self.done and self.node.due(k):
            self.candidates.add(k)

    def _lookup(self, key: str, tick: int) -> Any:
        return self.store.get(key, {}).get(tick)

    def put(self, key: str, msg: Any) -> list[tuple[str, Any]]:
        k = tick_of(msg.stamp)
        if key not in self.watched and key not in self.trigger:
            return []
        if k <= self.done and key in self.used and self.used[key] == k:
            self.repeats += 1
            return list(self.last_out)  # a value again for what the last run used: send that run again
        if key in self.trigger and k > self.done and self.first_run.maybe_restarted:
            self.give_up.trigger_came(key, k)
        if key in self.watched and self.done >= 0:
            source, delay = self.sources[key]
            first = needed_tick(self.done + 1, source.period, delay)
            if first is not None and k < first:
                self.drop(key, f"a value of t={tick_time(k)}, which no run after t={tick_time(self.done)} reads")
                return []
        if key in self.watched:
            held = self.store.setdefault(key, {})
            held[k] = msg
            waiting = self.pending_holds.get(key)
            if waiting and k in waiting:  # ticks that were waiting for this value to stand for them
                later = waiting.pop(k)
                for c in later:
                    if c > self.done and c not in held:
                        held[c] = restamp(msg, tick_time(c))
                        self.holds += 1
                out = self._opened(key, k)
                for c in later:
                    out += self._opened(key, c)
                return out
            if len(held) > KEEP_TICKS:
                for old in sorted(held)[:len(held) - KEEP_TICKS]:
                    del held[old]
        return self._opened(key, k)

    def teammate(self, robot: str, alive: bool) -> list[tuple[str, Any]]:
        if alive:
            self.gone.discard(robot)
            return []
        self.gone.add(robot)
        return self._advance()

    def _advance(self) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        while self.candidates:
            ready = None
            for c in sorted(self.candidates):
                if self._lacks(c):
                    continue
                inputs, missing = gather(self.node, c, self._lookup, self.gone.__contains__, self._lost)
                if not missing:
                    ready = (c, inputs)
                    break
            if ready is None:
                return out
            c, inputs = ready
            give_up = self.give_up
            if give_up.gave_up_at is not None:  # (the restart rules asked only when they apply)
                give_up.before_run(c, self._has, self.first_run, self.gone)
            sent = self.runner.run(c, inputs)
            self.done = c
            if self.first_run.born is None:
                self.first_run.ran(c)
            if give_up.seen:
                give_up.ran(c)
            self.last_out = sent
            self.recent_out.append(sent)
            self.used = {key: n for key, (src, delay) in self.sources.items()
                         if delay == 0 and (n := needed_tick(c, src.period, 0)) is not None}
            self.candidates = {x for x in self.candidates if x > c}
            self._waiting = {x: w for x, w in self._waiting.items() if x > c}
            if c % 8 == 0:  # what no later run reads: dropped now and then (KEEP_TICKS bounds it anyway)
                self._forget(c)
            out += sent
        return out

    def _forget(self, c: int) -> None:
        """Values no run after tick ``c`` can read (older than every source's need at c)
        but each source's latest (a held reading's next tick stands on it), and holds
        waiting for a value older than that (the value never came)."""
        for b in self.node.bindings:
            for s in b.sources:
                n = needed_tick(c, s.period, b.delay)
                held = self.store.get(s.key)
                if held and n is not None:
                    newest = max(held)
                    for old in [t for t in held if t < n and t != newest]:
                        del held[old]
                waiting = self.pending_holds.get(s.key)
                if waiting:
                    for since in [x for x, ticks in waiting.items() if max(ticks) <= c]:
                        del waiting[since]

    def resend(self, keys: Collection[str] | None = None) -> list[tuple[str, Any]]:
        """The recent runs' outputs (on ``keys``, or all), oldest first: what a (re)started
        reader of them asks for. A delayed reader (a teammate reading the previous run's
        share, a node of the robot reading it with ``delay = 1``) needs a run before the
        one it is stalled at, which it missed while down; a same-tick reader may need the
        last run, sent while it was down, whose inputs nobody sends again (they were the
        tick before the stalled one)."""
        return [m for run in self.recent_out for m in run if keys is None or m[0] in keys]


@dataclass
class RealtimeGate:
    """A node's real-time timing (see the module docstring).

    ``latest`` holds each source's newest value with the tick it stands for; a held value
    keeps its message as it came and is restamped only when a run reads it (one copy per
    run, not one per source and tick)."""

    runner: Runner
    drop: Drop = lambda key, why: None
    latest: dict[str, tuple[int, Any]] = field(default_factory=dict)
    open_tick: int = -1  # the newest due tick seen
    done: int = -1
    gone: set[str] = field(default_factory=set)
    stale_drops: dict[str, int] = field(default_factory=dict)
    _stale_now: set[str] = field(default_factory=set)
    holds: int = 0
    pending_holds: dict[str, tuple[int, int]] = field(default_factory=dict)  # key -> (since, tick)

    def __post_init__(self) -> None:
        self.node = self.runner.plan
        self.trigger = _triggers(self.node)
        self.watched = {s.key for b in self.node.bindings for s in b.sources}
        self.binding_of: dict[str, tuple[Binding, Any]] = {s.key: (b, s) for b in self.node.bindings for s in b.sources}
        self._age = {s.key: _max_age(b.stale_s) for b in self.node.bindings for s in b.sources}
        # what a tick waits for: each same-tick source (key, period, max age in ticks)
        self._same_tick = [(s.key, s.period, self._age[s.key]) for b in self.node.bindings if b.delay == 0
                           for s in b.sources]
        self._period = self.node.period
        self.runner.skip_not_ready = True  # a missing input may make a real-time run impossible
        self.not_ready = 0  # due ticks given up: the node was not ready when the next one began

    def put(self, key: str, msg: Any) -> list[tuple[str, Any]]:
        k = tick_of(msg.stamp)
        out = self._open(key, k) if key in self.trigger else []
        if key in self.watched:
            held = self.latest.get(key)
            if held is not None and k < held[0]:
                self.drop(key, f"stamp {msg.stamp} older than the latest from this source ({tick_time(held[0])})")
                return out
            waiting = self.pending_holds.pop(key, None)
            if waiting is not None and waiting[0] == k and waiting[1] > k:  # it stands for a later tick too
                self.latest[key] = (waiting[1], msg)
                self.holds += 1
            else:
                self.latest[key] = (k, msg)
        if self.open_tick > self.done and self._complete(self.open_tick):
            out += self._run(self.open_tick)
        return out

    def _open(self, key: str, k: int) -> list[tuple[str, Any]]:
        """A trigger's value of tick ``k``: a later tick begins (the open one runs with what came)."""
        c = k - k % self._period
        if c > self.open_tick:
            out = self._run(self.open_tick) if self.open_tick > self.done else []
            if self.open_tick > self.done:  # still not ready: the tick is given up
                self.not_ready += 1
            self.open_tick = c
            return out
        return []

    def hold(self, key: str, k: int, since: int) -> list[tuple[str, Any]]:
        """``key``'s value of tick ``since`` stands for tick ``k`` (module docstring)."""
        return self.hold_all(((key, k, since),))

    def hold_all(self, holds: Iterable[tuple[str, int, int]]) -> list[tuple[str, Any]]:
        """Every ``(key, k, since)`` of one ``Unchanged`` message, then one look whether the open tick is complete."""
        out: list[tuple[str, Any]] = []
        latest, trigger, watched = self.latest, self.trigger, self.watched
        for key, k, since in holds:
            if key not in watched or k <= since:
                continue
            if key in trigger and k - k % self._period > self.open_tick:
                out += self._open(key, k)
            held = latest.get(key)
            if held is not None and since <= held[0] < k:  # the value of since, or one standing for a tick since
                latest[key] = (k, held[1])
                self.holds += 1
            elif held is None or held[0] < since:  # the value it stands for is still on its way
                self.pending_holds[key] = (since, k)
        if self.open_tick > self.done and self._complete(self.open_tick):
            out += self._run(self.open_tick)
        return out

    def teammate(self, robot: str, alive: bool) -> list[tuple[str, Any]]:
        if alive:
            self.gone.discard(robot)
        else:
            self.gone.add(robot)
            for key, (_, s) in self.binding_of.items():
                if s.owner == robot:
                    self.latest.pop(key, None)
        return []

    def _complete(self, c: int) -> bool:
        latest = self.latest
        for key, period, age in self._same_tick:
            held = latest.get(key)
            if held is None or c - held[0] > age:
                continue  # not heard from within its limit: not waited for
            if held[0] < c - c % period:
                return False
        return True

    def _lookup_at(self, c: int) -> Callable[[str, int], Any]:
        latest, age, binding_of = self.latest, self._age, self.binding_of

        def lookup(key: str, tick: int) -> Any:
            held = latest.get(key)
            if held is None:
                return None
            t = held[0]
            if t > c or (t == c and binding_of[key][0].delay == 1):
                return None
            if c - t > age[key]:
                self._stale(key, t, c)
                return None
            if self._stale_now:
                self._stale_now.discard(key)
            msg = held[1]
            stamp = tick_time(t)
            if msg.stamp != stamp and tick_of(msg.stamp) != t:  # a held value: restamped for the tick it stands for
                msg = restamp(msg, stamp)
                latest[key] = (t, msg)
            return msg

        return lookup

    def _stale(self, key: str, tick: int, c: int) -> None:
        if key not in self._stale_now:
            self._stale_now.add(key)
            self.stale_drops[key] = self.stale_drops.get(key, 0) + 1
            log.warning("%s: stale input left out: %s (stamp %.3f at tick %.3f)", self.node.label, key,
                        tick_time(tick), tick_time(c))

    def _run(self, c: int) -> list[tuple[str, Any]]:
        inputs, _ = gather(self.node, c, self._lookup_at(c), self.gone.__contains__)
        done, self.done = self.done, c  # a run that fails is not tried again
        try:
            return self.runner.run(c, inputs)
        except NotReady:  # the tick runs when more of it comes, or is given up when the next begins
            self.done = done
            return []

    def resend(self, keys: Collection[str] | None = None) -> list[tuple[str, Any]]:
        return []  # real time waits for nothing: a restarted reader takes the next values

    def counts(self) -> GateCounts:
        return GateCounts(stale=dict(self.stale_drops), not_ready=self.not_ready)


def _max_age(stale_s: float) -> int | float:
    """The most ticks a value may lag the tick that reads it and still count: the largest
    n with n * TICK_S <= stale_s (a float tolerance of 1e-9 s)."""
    if stale_s == float("inf"):
        return stale_s
    n = int((stale_s + 1e-9) / TICK_S) + 1
    while n * TICK_S > stale_s + 1e-9:
        n -= 1
    return n


__all__ = ["gather", "lost_on_restart", "GateCounts", "LockstepGate", "RealtimeGate", "KEEP_TICKS", "RESEND_RUNS"]
