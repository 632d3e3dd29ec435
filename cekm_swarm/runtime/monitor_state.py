"""What ``cekm monitor`` knows of a run: :class:`MonitorState`, fed with (key, payload,
arrival time) and tested without Zenoh.

What it keeps comes typed from the protocol's decoder (a ``world/state`` whose robots lack
a finite x, y or theta does not decode: it is dropped and counted like any malformed
message). Per robot a :class:`RobotView` (pose, goal, last wheel command, the
sense-to-command latency); per key its arrival times; the liveliness tokens alive; in a
tracking run each robot's latest :class:`Observation` of the targets. Drawing it is
:mod:`cekm_swarm.runtime.monitor_view`'s; subscribing, :mod:`cekm_swarm.runtime.monitor`'s.
"""

from __future__ import annotations

import math
import re
import threading
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from cekm_swarm.protocol import (
    DEFAULT_KEYS,
    WORLD,
    DropCounter,
    KeyKind,
    KeySpace,
    MapVersion,
    SenseRange,
    SenseTarget,
    SenseTargets,
    Share,
    WheelCommand,
    WorldState,
)

from .topics import HzStats, hz_stats

STALE_AFTER = 3.0
"""Seconds without a world state after which the monitor says so."""

MAX_KEYS = 4096
"""Keys whose rates the monitor tracks; messages on keys beyond these are counted only (a
publisher inventing keys cannot grow the monitor without bound)."""

MAX_ROBOTS = 512
"""Robots the monitor tracks; others are counted in ``untracked``."""

FRESH = 1.0
"""A world state younger than this (s) means the run is going, whatever the tokens say."""

OBSERVATION_SPAN = 2.0
"""Sim seconds: a robot's share or sense/targets older than this against the newest world
state no longer counts as observing (a robot whose modules died stops observing)."""


def natural_key(name: str) -> tuple[Any, ...]:
    """Sort key that orders ids as a person does: t1, t2, t10 (not t1, t10, t2)."""
    return tuple(int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name))


@dataclass
class RobotView:
    """What the monitor knows of one robot."""

    robot: str
    pose: tuple[float, float, float] | None = None
    goal: tuple[float, float] | None = None
    in_contact: bool = False
    command: tuple[float, float] | None = None
    command_stamp: float | None = None
    map: tuple[int, int, float] | None = None  # a learning robot's map: version, steps learned, error (m/s)
    latencies: deque[float] = field(default_factory=lambda: deque(maxlen=200))  # seconds
    sense_first: dict[float, float] = field(default_factory=dict)  # stamp -> wall time of the first sense message

    @property
    def status(self) -> str:
        if self.command is None:
            return "waiting"
        if self.command == (0.0, 0.0):
            if self.pose is not None and self.goal is not None and math.dist(self.pose[:2], self.goal) < 0.01:
                return "reached"
            return "stopped"
        return "moving"

    def latency_ms(self, q: float) -> float:
        if not self.latencies:
            return math.nan
        xs = sorted(self.latencies)
        return 1e3 * xs[min(len(xs) - 1, int(q * len(xs)))]


@dataclass
class Observation:
    """The targets one robot observes, from its latest message of one ``source``."""

    stamp: float
    targets: frozenset[str]
    source: str  # "share" (what the robot reports) or "sense" (what the world says it senses)


class MonitorState:
    """Everything the monitor shows, updated from (key, payload, arrival time)."""

    def __init__(self, keys: KeySpace = DEFAULT_KEYS, window: float = 5.0) -> None:
        self.keys = keys
        self.window = window
        self.robots: dict[str, RobotView] = {}
        self.arrivals: dict[str, deque[float]] = {}
        self.last_stamp: dict[str, float] = {}
        self.alive: set[str] = set()
        self.sim_time = math.nan
        self.world_at: float | None = None  # arrival time of the newest world state
        self.world_token_seen = False
        self.targets: dict[str, tuple[float, float]] = {}  # target id -> (x, y), from the newest world state
        self.shares: dict[str, Observation] = {}  # robot -> its latest share
        self.sensed: dict[str, Observation] = {}  # robot -> its latest sense/targets
        self.untracked = 0  # messages on keys (or robots) beyond MAX_KEYS (MAX_ROBOTS)
        self.drops = DropCounter("monitor", keys=keys)
        self.expected: tuple[str, ...] | None = None  # one robot's nodes, from the run's graph (None: not known)
        self.graph: str | None = None  # the run's graph's name
        self.run_id: str | None = None  # the run whose figures are shown (its world server's token)
        self._lock = threading.Lock()

    def _new_run(self) -> None:
        """A new run began (another world server's run id, or sim time went back: a new run
        or a replay): forget the previous run's robots, latencies, rates and observations,
        so no figure of it stays on screen."""
        self.robots.clear()
        self.arrivals.clear()
        self.last_stamp.clear()
        self.shares.clear()
        self.sensed.clear()
        self.targets = {}
        self.sim_time = math.nan
        self.world_at = None

    def robot(self, rid: str) -> RobotView | None:
        """The view of robot ``rid``, made on first sight; None beyond :data:`MAX_ROBOTS`."""
        v = self.robots.get(rid)
        if v is None:
            if len(self.robots) >= MAX_ROBOTS:
                self.untracked += 1
                return None
            v = self.robots[rid] = RobotView(rid)
        return v

    def observe(self, key: str, payload: bytes, at: float) -> None:
        """One received message: decoded and checked (a malformed one is counted and dropped)."""
        with self._lock:
            q = self._arrived(key, at)
            if q is None:
                return
            msg = self.drops.decode(key, payload)
            if msg is None:
                return
            try:
                parsed = self.keys.parse(key)
            except Exception:  # decode accepted the key, so this does not happen; never crash on it
                return
            robot = parsed.robot if parsed.robot != WORLD else None
            if isinstance(msg, WorldState):  # typed: every robot has a finite pose (protocol.messages)
                self._world_state(key, q, msg, at)
                return
            self.last_stamp[key] = msg.stamp
            if robot:
                self._robot_message(robot, msg, at)

    def _arrived(self, key: str, at: float) -> deque[float] | None:
        """The key's arrival times, ``at`` added and those older than the window gone (None:
        one key too many, counted as untracked)."""
        q = self.arrivals.get(key)
        if q is None:
            if len(self.arrivals) >= MAX_KEYS:
                self.untracked += 1
                return None
            q = self.arrivals[key] = deque()
        q.append(at)
        while q and at - q[0] > self.window:
            q.popleft()
        return q

    def _world_state(self, key: str, q: deque[float], msg: WorldState, at: float) -> None:
        if math.isfinite(self.sim_time) and msg.stamp < self.sim_time:  # a new run or replay
            self._new_run()
            self.arrivals[key] = q
        self.targets = {tid: (t.x, t.y) for tid, t in msg.targets.items()}
        self.last_stamp[key] = msg.stamp
        self.sim_time = msg.stamp
        self.world_at = at
        for rid, r in msg.robots.items():
            v = self.robot(rid)
            if v is None:
                continue
            v.pose, v.in_contact = (r.x, r.y, r.theta), r.in_contact
            if r.goal is not None:
                v.goal = r.goal

    def _robot_message(self, robot: str, msg: Any, at: float) -> None:
        """A robot's share or sensed targets, its map version, its readings (for the
        sense-to-command latency) and its wheel command."""
        if isinstance(msg, (Share, SenseTargets)):
            book = self.shares if isinstance(msg, Share) else self.sensed
            if robot in book or self.robot(robot) is not None:
                book[robot] = Observation(msg.stamp, frozenset(msg.targets),
                                          "share" if isinstance(msg, Share) else "sense")
            return
        if isinstance(msg, MapVersion):  # a learning robot (docs/learning.md)
            mv = self.robot(robot)
            if mv is not None:
                mv.map = (msg.version, msg.applied, msg.error)
            return
        v = self.robot(robot) if isinstance(msg, (SenseRange, SenseTarget, WheelCommand)) else None
        if v is None:
            return
        if isinstance(msg, (SenseRange, SenseTarget)):
            v.sense_first.setdefault(round(msg.stamp, 6), at)
            if len(v.sense_first) > 64:
                for s in sorted(v.sense_first)[:-64]:
                    del v.sense_first[s]
        elif isinstance(msg, WheelCommand):
            v.command = (msg.v_l, msg.v_r)
            v.command_stamp = msg.stamp
            first = v.sense_first.get(round(msg.stamp, 6))
            if first is not None:
                v.latencies.append(at - first)

    def is_tracking(self) -> bool:
        """A tracking run: targets in the world state, and shares or sense/targets seen."""
        return bool(self.targets) and bool(self.shares or self.sensed)

    def observations(self) -> dict[str, Observation]:
        """{robot: what it observes now}: the newer (by stamp) of its latest share and its
        latest sense/targets (the share on a tie), skipping those older than
        :data:`OBSERVATION_SPAN` sim seconds against the newest world state."""
        with self._lock:
            out: dict[str, Observation] = {}
            for rid in set(self.shares) | set(self.sensed):
                cands = [o for o in (self.shares.get(rid), self.sensed.get(rid)) if o is not None]
                best = max(cands, key=lambda o: (o.stamp, o.source == "share"))
                if math.isfinite(self.sim_time) and self.sim_time - best.stamp > OBSERVATION_SPAN:
                    continue
                out[rid] = best
            return out

    def tracking(self, robots: set[str] | None = None) -> dict[str, Any]:
        """The tracking status: ``targets`` {id: {x, y, observed_by}} (observers among
        ``robots`` if given), ``observed`` (targets observed by at least one robot of the
        whole team) out of ``total`` (the world's targets), ``A`` their ratio, and
        ``per_robot`` {robot: targets it sees, source}."""
        obs = self.observations()
        with self._lock:
            targets = dict(self.targets)
        by: dict[str, list[str]] = {tid: [] for tid in targets}
        for rid in sorted(obs, key=natural_key):
            for tid in obs[rid].targets:
                by.setdefault(tid, []).append(rid)
        observed = sum(1 for tid in targets if by[tid])

        def shown(r: str) -> bool:
            return robots is None or r in robots

        return {
            "targets": {tid: {"x": targets[tid][0] if tid in targets else None,
                              "y": targets[tid][1] if tid in targets else None,
                              "observed_by": [r for r in by[tid] if shown(r)]} for tid in sorted(by, key=natural_key)},
            "observed": observed, "total": len(targets), "A": observed / len(targets) if targets else None,
            "per_robot": {rid: {"sees": len(o.targets), "source": o.source}
                          for rid, o in sorted(obs.items(), key=lambda kv: natural_key(kv[0])) if shown(rid)},
        }

    def set_alive(self, tokens: set[str]) -> None:
        """The liveliness tokens alive now (of any run: ``<root>/<owner>/alive/<module>[/<run>]``)."""
        with self._lock:
            self.alive = set(tokens)
            run = self.world_run()
            if run is not None and run != self.run_id:
                if self.run_id is not None:  # the next run's world server: the last one's figures go
                    self._new_run()
                self.run_id = run
        if self._world_alive():
            self.world_token_seen = True

    def _world_alive(self) -> bool:
        return "server" in self._alive_modules().get(WORLD, set())

    def runs(self) -> list[str]:
        """The run ids in the liveliness tokens alive now."""
        out = set()
        for t in self.alive:
            try:
                run = self.keys.parse(t).run
            except Exception:
                continue
            if run:
                out.add(run)
        return sorted(out)

    def phase(self, now: float) -> str:
        """``waiting for the world``, ``waiting for the modules`` (the world server is up and
        holds tick 0 until every module is alive), ``running``, ``replay`` (world states with
        no world server alive), ``no world state for N s`` or ``run ended`` (the world
        server's token went away, or the states stopped with no module left)."""
        world_alive = self._world_alive()
        modules_alive = any(owner != WORLD for owner in self._alive_modules())
        if self.world_at is None:
            if self.world_token_seen and not world_alive:
                return "run ended"
            return "waiting for the modules" if world_alive else "waiting for the world"
        age = now - self.world_at
        if age <= FRESH:
            return "running" if world_alive or modules_alive else "replay"
        if self.world_token_seen and not world_alive:
            return "run ended"
        if age > STALE_AFTER:
            if not world_alive and not modules_alive:
                return "run ended"
            return f"no world state for {age:.0f} s"
        return "running"

    def key_stats(self, now: float) -> list[HzStats]:
        with self._lock:
            return [hz_stats(k, [t for t in q if now - t <= self.window], now) if q else
                    HzStats(k, 0, 0.0, math.nan, math.nan, math.nan, math.nan, math.inf)
                    for k, q in sorted(self.arrivals.items())]

    def _alive_modules(self) -> dict[str, set[str]]:
        """{owner: module names} of the liveliness tokens alive now (parsed by the key space)."""
        out: dict[str, set[str]] = {}
        for t in self.alive:
            try:
                parsed = self.keys.parse(t)
            except Exception:
                continue
            if parsed.kind is KeyKind.ALIVE and parsed.robot and parsed.module:
                out.setdefault(parsed.robot, set()).add(parsed.module)
        return out

    def module_tokens(self) -> int:
        """How many robots' module tokens are alive now (the world server's not counted)."""
        return sum(len(m) for owner, m in self._alive_modules().items() if owner != WORLD)

    def modules_alive(self, rid: str) -> tuple[int, list[str]]:
        """(number alive, the names of the missing ones) of a robot's nodes: those of the
        run's graph (all that are alive when the graph is not known)."""
        names = self._alive_modules().get(rid, set())
        if self.expected is None:
            return len(names), []
        return len(names & set(self.expected)), [m for m in self.expected if m not in names]

    def world_run(self) -> str | None:
        """The run id of the world server alive now (its token's last chunk)."""
        for t in self.alive:
            try:
                parsed = self.keys.parse(t)
            except Exception:
                continue
            if parsed.kind is KeyKind.ALIVE and parsed.robot == WORLD and parsed.run:
                return parsed.run
        return None
