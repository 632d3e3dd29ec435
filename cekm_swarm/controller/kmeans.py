"""K-means tracking baselines (Luke, Sullivan, Panait and Balan, "Tunably decentralized
algorithms for cooperative target observation", AAMAS 2005; MASON's CTO application,
``KMeansEngine``): pure functions of plain values (docs/tracking.md).

Each update (every target tick, 0.256 s):

* every known target is assigned to its nearest robot (:func:`assign`; the robots'
  positions as the robot knows them);
* a robot with assigned targets moves its goal toward their mean:
  goal <- (1 - alpha) goal + alpha mean, alpha = 0.25 (:func:`update_goal`; KMeansEngine's
  ALFA). The goal is kept while the robot has no target, as KMeansEngine keeps it;
* a robot with no target drives to a random waypoint (uniform within wander_radius * R of
  where it is) and holds it for wander_hold_s or until it is within wander_reached * R;
* the goal pulls with a force of magnitude min(d / (v* arrive_s), 1) toward it, which
  A-CMOMMT's motor (:func:`.acmommt.force_wheels`: obstacle repulsion, turn gain, wheel
  limits) turns into wheel speeds.

Two variants differ only in what is known: ``kmeans`` knows a target while the robot or
a teammate senses it (its own sensing and the teammates' shares: the information cekm
has) and the teammates' positions from their shares; ``kmeans-global`` knows every
target's and robot's true position (the world's state: Luke et al.'s centralized upper
baseline).
"""

from __future__ import annotations

import math
import random
import zlib
from dataclasses import dataclass, field

from ..models.params import KMeansParams
from .team import to_robot, to_world

Point = tuple[float, float]
Pose = tuple[float, float, float]


def assign(targets: dict[str, Point], robots: dict[str, Point]) -> dict[str, str]:
    """Each target's nearest robot, {target id: robot id} (squared distance; a tie goes to
    the robot first in id order, so every robot computes the same labels)."""
    order = sorted(robots)
    labels = {}
    for tid in sorted(targets):
        tx, ty = targets[tid]
        best, best_d = None, math.inf
        for r in order:
            rx, ry = robots[r]
            d = (tx - rx) ** 2 + (ty - ry) ** 2
            if d < best_d:
                best, best_d = r, d
        if best is not None:
            labels[tid] = best
    return labels


def cluster_mean(targets: dict[str, Point], labels: dict[str, str], robot: str) -> Point | None:
    """The mean position of the targets assigned to ``robot``; None when it has none."""
    mine = [targets[t] for t in sorted(labels) if labels[t] == robot]
    if not mine:
        return None
    return (sum(p[0] for p in mine) / len(mine), sum(p[1] for p in mine) / len(mine))


def update_goal(goal: Point | None, mean: Point, alpha: float) -> Point:
    """goal <- (1 - alpha) goal + alpha mean; a robot with no goal yet takes the mean."""
    if goal is None:
        return mean
    return ((1.0 - alpha) * goal[0] + alpha * mean[0], (1.0 - alpha) * goal[1] + alpha * mean[1])


def local_view(pose: Pose, sensed: dict[str, tuple[float, float]],
               teammates: dict[str, tuple[Pose, dict[str, Point]]]) -> tuple[dict[str, Point], dict[str, Point]]:
    """What the local variant knows: the robots' positions (its own, each teammate's from its
    share) and the targets sensed by itself or a teammate (its own sighting first, then the
    teammates' in id order), both in the world frame."""
    targets = {tid: to_world(pose, a, d) for tid, (a, d) in sorted(sensed.items())}
    robots = {}
    for r in sorted(teammates):
        tpose, seen = teammates[r]
        robots[r] = (tpose[0], tpose[1])
        for tid in sorted(seen):
            targets.setdefault(tid, seen[tid])
    return robots, targets


def usable_shares(shares: dict[str, tuple[float, Pose, dict[str, Point]]], t: float,
                  timeout_s: float) -> dict[str, tuple[Pose, dict[str, Point]]]:
    """The teammates' shares {robot: (stamp, pose, targets)} a tick at t uses: stamped before
    t (the previous target tick's, as every tracking controller) and at most timeout_s old."""
    return {r: (pose, seen) for r, (stamp, pose, seen) in sorted(shares.items())
            if stamp < t and t - stamp <= timeout_s}


@dataclass(frozen=True)
class GoalForce:
    """One update's output: the pull toward the goal (or waypoint) in the robot's frame."""

    stamp: float
    fx: float
    fy: float
    aim: Point  # the goal or waypoint, world frame
    searching: bool  # no assigned target: driving to a random waypoint


@dataclass
class KMeansTracker:
    """One robot's K-means goal (the engine run from its own view of the team)."""

    robot: str
    target_range: float
    v_max: float
    params: KMeansParams = field(default_factory=KMeansParams)
    goal: Point | None = None
    waypoint: Point | None = None
    waypoint_since: float = 0.0
    _rng: random.Random | None = None

    def update(self, t: float, pose: Pose, robots: dict[str, Point], targets: dict[str, Point]) -> GoalForce:
        """One K-means step: ``robots`` {id: (x, y)} the teammates (this robot's own position
        is ``pose``'s), ``targets`` {id: (x, y)} every known target."""
        everyone = dict(robots)
        everyone[self.robot] = (pose[0], pose[1])
        mean = cluster_mean(targets, assign(targets, everyone), self.robot)
        if mean is not None:
            self.goal = update_goal(self.goal, mean, self.params.alpha)
            self.waypoint = None
            aim = self.goal
        else:
            aim = self._wander(t, pose)
        alpha, d = to_robot(pose, aim)
        mag = min(d / (self.v_max * self.params.arrive_s), 1.0)
        return GoalForce(t, mag * math.cos(alpha), mag * math.sin(alpha), aim, mean is None)

    def _wander(self, t: float, pose: Pose) -> Point:
        """The random waypoint, drawn afresh when it is reached or has been held long enough."""
        p, R = self.params, self.target_range
        if self._rng is None:  # seeded from the robot and where it starts: the same in every run of it
            self._rng = random.Random(zlib.crc32(f"{self.robot}:{pose[0]:.6f}:{pose[1]:.6f}".encode()))
        wp = self.waypoint
        if (wp is None or t - self.waypoint_since >= p.wander_hold_s
                or math.hypot(wp[0] - pose[0], wp[1] - pose[1]) <= p.wander_reached * R):
            rho = p.wander_radius * R * math.sqrt(self._rng.random())
            phi = self._rng.uniform(-math.pi, math.pi)
            self.waypoint = wp = (pose[0] + rho * math.cos(phi), pose[1] + rho * math.sin(phi))
            self.waypoint_since = t
        return wp
