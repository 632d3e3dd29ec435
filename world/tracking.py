"""The world's side of multi-robot tracking (Fig. 13): what each robot's own sensors give
it, and the ground-truth observation metric.

* :func:`tracking_sense` builds a robot's two tracking messages from the simulation: its
  pose (``sense/pose``: the true pose, as an external localization system would give it)
  and every target within its target sensing range (``sense/targets``: (alpha, d) in the
  robot's frame, with the target sensor's noise model of :meth:`World.target_reading`).
  The target sensor is read for every target in scenario order, in range or not, so the
  noise stream a robot draws from never depends on what it sees.
* :class:`ObservationMeter` measures Parker's observation metric A: at every tick, the
  fraction of targets within the target sensing range of at least one robot (true
  distances, no noise), averaged over the run's ticks; per target; as a time series;
  and the spread of the robots and of the targets (mean pairwise distance) over time, the
  measure of "the robots move apart when the targets part".

Ground truth lives here because the world must not import controller code, and the
experiments may import the world.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from cekm_swarm.protocol.messages import SensePose, SenseTargets
from cekm_swarm.ticks import TARGET_EVERY, TICK_S, tick_time

from .progress import RobotProgress
from .rows import Rows
from .scenario_spec import ScenarioError
from .sense import SENDER, TickReadings
from .sim import World


def is_tracking(scenario: Any) -> bool:
    """A tracking scenario: it has targets and none of its robots has a goal."""
    return bool(scenario.targets) and bool(scenario.robots) and all(r.goal is None for r in scenario.robots)


def run_kind(scenario: Any, checkpoints: Any = ()) -> str:
    """``"tracking"`` or ``"navigation"``: what a run of ``scenario`` is. Raises
    :class:`ScenarioError`, naming the file and the robot, for a scenario that is neither,
    so that it is refused before anything starts: robots with goals beside robots without
    (with targets), a navigation robot with no goal (and no checkpoints, whose ids are
    ``checkpoints``' keys), or a tracking scenario whose robots sense targets at any
    distance (every target always observed: Parker's A is 1 whatever the robots do)."""
    if is_tracking(scenario):
        if not math.isfinite(scenario.target_range):
            raise ScenarioError(f"{scenario.source}: sensors.target_range: a tracking scenario (no robot has a goal) "
                                f"needs a finite target sensing range, got {scenario.target_range} (the default when "
                                f"[sensors] leaves it out); e.g. target_range = 0.5")
        return "tracking"
    for i, r in enumerate(scenario.robots):
        if r.goal is None and r.id not in checkpoints:
            with_goal = [q.id for q in scenario.robots if q.goal is not None]
            if with_goal:
                why = (f"robot {r.id!r} has none while {', '.join(map(repr, with_goal))} "
                       f"{'has' if len(with_goal) == 1 else 'have'} one: a scenario is for tracking (no robot "
                       "has a goal) or for navigation (every robot has one)")
            else:
                why = (f"robot {r.id!r} has none and the scenario has no targets to track: a navigation run needs "
                       "a goal (a target id) for every robot")
            raise ScenarioError(f"{scenario.source}: robots[{i}].goal: {why}")
    return "navigation"


def tracking_sense(world: World, robot: str, stamp: float) -> tuple[SensePose, SenseTargets]:
    """The robot's ``sense/pose`` and ``sense/targets`` messages at ``stamp``."""
    pose = SensePose(stamp, SENDER, world.pose(robot))
    seen = {}
    for tid in world.target_ids:
        alpha, d, visible = world.target_reading(robot, tid)
        if visible:
            seen[tid] = (alpha, d)
    return pose, SenseTargets(stamp, SENDER, seen)


def _path_length(path: Rows) -> float:
    """Sum of the steps between consecutive (t, x, y, theta) rows, in order (``sum`` of a
    generator: the same additions as over a list)."""
    rows = iter(path)
    prev = next(rows, None)

    def steps() -> Iterator[float]:
        nonlocal prev
        for b in rows:
            assert prev is not None  # a path with a row after the first
            yield math.hypot(b[1] - prev[1], b[2] - prev[2])
            prev = b

    return sum(steps())


def mean_pairwise(points: list[tuple[float, float]]) -> float:
    """Mean distance over all pairs of points (0 for fewer than two)."""
    n = len(points)
    if n < 2:
        return 0.0
    total = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            total += math.hypot(points[i][0] - points[j][0], points[i][1] - points[j][1])
    return total / (n * (n - 1) / 2)


@dataclass
class ObservationMeter:
    """Parker's observation metric A, sampled once per tick (call :meth:`sample`)."""

    targets: list[str]
    robots: list[str]
    seen: dict[str, int] = field(default_factory=dict)
    series: Rows = field(default_factory=lambda: Rows(4))  # per tick: t, A, robot spread, target spread

    def sample(self, world: World, t: float) -> dict[str, list[str]]:
        """Record tick ``t`` of ``world``; returns who observes which target now."""
        state = world.state()
        return self.sample_positions(t, {r: (p["x"], p["y"]) for r, p in state["robots"].items()},
                                     {k: (p["x"], p["y"]) for k, p in state["targets"].items()}, world.target_range)

    def sample_positions(self, t: float, robots: dict[str, tuple[float, float]],
                         targets: dict[str, tuple[float, float]], target_range: float) -> dict[str, list[str]]:
        """Record tick ``t`` from true positions: a target is observed when it is within
        ``target_range`` of at least one robot. Returns who observes which target."""
        obs = {tid: [r for r, rp in robots.items() if math.hypot(tp[0] - rp[0], tp[1] - rp[1]) <= target_range]
               for tid, tp in targets.items()}
        m = len(self.targets)
        watched = [tid for tid in self.targets if obs.get(tid)]
        for tid in watched:
            self.seen[tid] = self.seen.get(tid, 0) + 1
        self.series.append((t, len(watched) / m if m else 0.0, mean_pairwise(list(robots.values())),
                            mean_pairwise(list(targets.values()))))
        return obs

    @property
    def t(self) -> list[float]:
        return self.series.column(0)

    @property
    def fraction(self) -> list[float]:
        return self.series.column(1)

    @property
    def A(self) -> float:
        """The fraction of targets observed by at least one robot, averaged over the ticks."""
        fraction = self.fraction
        return sum(fraction) / len(fraction) if fraction else 0.0

    def summary(self) -> dict[str, Any]:
        """The ``tracking`` object of ``outcome.json``."""
        n = len(self.series)
        k = max(1, n // 10)
        t, fraction, robot_spread, target_spread = (self.series.column(j) for j in range(4))

        def head_tail(xs: list[float]) -> tuple[float, float]:
            return (sum(xs[:k]) / k, sum(xs[-k:]) / k) if xs else (0.0, 0.0)

        rs0, rs1 = head_tail(robot_spread)
        ts0, ts1 = head_tail(target_spread)
        return {
            "A": sum(fraction) / n if n else 0.0,
            "A_per_target": {tid: (self.seen.get(tid, 0) / n if n else 0.0) for tid in self.targets},
            "robots": len(self.robots),
            "targets": len(self.targets),
            "ticks": n,
            "spread": {
                "what": "mean pairwise distance (m), averaged over the first and the last tenth of the run",
                "robots_start": rs0, "robots_end": rs1, "targets_start": ts0, "targets_end": ts1,
                "robots_moved_apart_m": rs1 - rs0, "targets_moved_apart_m": ts1 - ts0,
            },
            "series": {"t": t, "A": fraction, "robot_spread": robot_spread, "target_spread": target_spread},
        }


class TrackingEpisode:
    """The world's side of a tracking run, tick by tick, for the world server: the same
    order of readings as the in-process runner
    (:func:`cekm_swarm.experiments.tracking_run.run_tracking`), so a distributed lockstep
    run equals it bit for bit. At tick k, for every robot in
    order: its pose, its 12 distance readings and, on even ticks, :func:`tracking_sense`;
    Parker's A is sampled first, from the true positions. The interface is
    :class:`world.episode.Episode`'s (``readings``, ``apply``, ``advance``, ``done``,
    ``outcome``, ``progress``), plus ``sense`` (this tick's tracking messages per robot)
    and ``meter``."""

    task = "tracking"

    def __init__(self, world: World, max_ticks: int) -> None:
        self.world = world
        self.max_ticks = max_ticks  # the last tick: sampled, but no path point (as the in-process runner)
        self.tick = 0
        self.progress = {r: RobotProgress([]) for r in world.robot_ids}
        self.meter = ObservationMeter(list(world.target_ids), list(world.robot_ids))
        self.sense: dict[str, tuple[SensePose, SenseTargets]] = {}
        self.observed_by: dict[str, list[str]] = {}  # at the current tick: target id -> robots within range

    @property
    def t(self) -> float:
        return tick_time(self.tick)

    @property
    def target_due(self) -> bool:
        return self.tick % TARGET_EVERY == 0

    def readings(self) -> list[TickReadings]:
        w, t = self.world, self.t
        self.observed_by = self.meter.sample(w, t)
        out = []
        self.sense = {}
        for r in w.robot_ids:
            x, y, th = w.pose(r)
            if self.tick < self.max_ticks:
                self.progress[r].path.append((t, x, y, th))
            ranges = w.range_readings(r)
            if self.target_due:
                self.sense[r] = tracking_sense(w, r, t)
            out.append(TickReadings(r, t, ranges, None))
        return out

    def apply(self, commands: dict[str, tuple[float, float]]) -> None:
        for r, (v_l, v_r) in commands.items():
            self.world.set_wheels(r, v_l, v_r)
            self.progress[r].commands.append((v_l, v_r))

    def advance(self) -> None:
        self.world.advance(TICK_S)
        self.tick += 1

    @property
    def done(self) -> bool:
        return False  # a tracking run ends at its max time

    def messages(self, robot: str) -> list[tuple[str, Any]]:
        """On target ticks the robot's targets and pose (``sense/targets``, ``sense/pose``)."""
        sensed = self.sense.get(robot)
        return [] if sensed is None else [("sense/targets", sensed[1]), ("sense/pose", sensed[0])]

    def summary(self) -> dict[str, Any]:
        return {"tracking": self.meter.summary()}

    def to_goal(self, robot: str) -> float | None:
        return None

    def draw(self, views: Any, t: float, state: dict[str, Any]) -> None:
        views.write_tracking(t, state, self.world.target_range, self.observed_by)

    def outcome(self) -> dict[str, dict[str, Any]]:
        """Per robot, as ``cekm run`` on a tracking scenario writes it: path length, collisions, final pose."""
        out = {}
        for r, p in self.progress.items():
            path = p.path
            length = _path_length(path)
            st = self.world.stats(r)
            out[r] = {"path_length_m": length, "collisions": int(st["collisions"]),
                      "final_pose": list(path[-1][1:]) if path else None,
                      "left_arena_s": st["left_arena_s"]}  # pushed through a boundary wall (None: never)
        return out


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def tracking_summary(tracking: dict[str, Any], collisions: int) -> str:
    """One line of a tracking run's result (its ``tracking`` block: Parker's A, per target,
    and how the team and the targets spread), the same from ``cekm run`` and ``cekm launch``."""
    per = ", ".join(f"{k} {v:.2f}" for k, v in tracking["A_per_target"].items())
    sp = tracking["spread"]
    return (f"A = {tracking['A']:.3f} ({_count(tracking['robots'], 'robot')}, {_count(tracking['targets'], 'target')}; "
            f"per target: {per}); robots apart {sp['robots_start']:.2f} -> {sp['robots_end']:.2f} m while targets "
            f"{sp['targets_start']:.2f} -> {sp['targets_end']:.2f} m; collisions {collisions}")

