"""A-CMOMMT (Parker, "Distributed algorithms for multi-robot observation of multiple moving
targets", Autonomous Robots 12(3), 2002): the tracking baseline, from its published
description.

A robot sums weighted local force vectors:

* to each target it knows of within the predictive tracking range do4: magnitude
  :func:`target_force` (piecewise linear: -1 at 0, 0 at do1, +1 at do2, +1 to the
  sensing range do3, 0 at do4), along the direction to the target; targets it senses
  itself, and targets its teammates report (that is how it knows of targets beyond its
  own range, up to do4);
* weight 1 for a target no other robot observes, ``watched_weight`` otherwise;
* from each teammate: :func:`robot_force` (-1 up to dr1, rising to 0 at dr2), along the
  direction to the teammate (so away from it);
* with no target force at all, a unit force toward the search goal (the same search
  behaviour as every tracking controller, :meth:`.team.TeamView.search_goal`);
* each tick, repulsion from what the 12 distance sensors see (the obstacle handling).

The summed force F, in the robot's frame, becomes wheel speeds: omega = turn_gain * phi
(phi the direction of F), forward speed v* min(|F|, 1) cos(phi) when |phi| < pi/2, both
wheels clipped to c*. Distances are fractions of the target sensing range R
(:class:`~cekm_swarm.models.params.ACMOMMTParams`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..models.params import ACMOMMTParams
from .readings import RangeReading
from .team import TeamView, observers_other, to_robot, to_world


def target_force(d: float, R: float, p: ACMOMMTParams) -> float:
    """Magnitude of the robot-to-target force at distance d (positive: attraction)."""
    do1, do2, do3, do4 = p.do1 * R, p.do2 * R, p.do3 * R, p.do4 * R
    if d <= do1:
        return -1.0 + d / do1
    if d <= do2:
        return (d - do1) / (do2 - do1)
    if d <= do3:
        return 1.0
    if d <= do4:
        return (do4 - d) / (do4 - do3)
    return 0.0


def robot_force(d: float, R: float, p: ACMOMMTParams) -> float:
    """Magnitude of the robot-to-robot force at distance d (negative: repulsion)."""
    dr1, dr2 = p.dr1 * R, p.dr2 * R
    if d <= dr1:
        return -1.0
    if d <= dr2:
        return -(dr2 - d) / (dr2 - dr1)
    return 0.0


@dataclass(frozen=True)
class ForceActivity:
    """The summed target, teammate and search force at one target tick, in the robot's frame."""

    stamp: float
    fx: float
    fy: float
    searching: bool


@dataclass
class ACMOMMT:
    """The A-CMOMMT controller of one robot."""

    robot: str
    target_range: float
    sensor_range: float
    body_radius: float
    axle: float
    v_max: float
    params: ACMOMMTParams = field(default_factory=ACMOMMTParams)
    search_reached: float = 0.5
    wander_ahead_m: float = 0.3

    def localize(self, t: float, pose: tuple[float, float, float], sensed: dict[str, tuple[float, float]],
                 view: TeamView) -> ForceActivity:
        p, R = self.params, self.target_range
        team = view.teammates(t)
        own = {tid: to_world(pose, a, d) for tid, (a, d) in sensed.items()}
        view.update_memory(t, own, team)
        fx = fy = 0.0
        known = False
        for tid in sorted(sensed):
            alpha, d = sensed[tid]
            w = 1.0 if observers_other(tid, team) == 0 else p.watched_weight
            f = w * target_force(d, R, p)
            fx += f * math.cos(alpha)
            fy += f * math.sin(alpha)
            known = True
        reported: dict[str, tuple[float, float]] = {}
        for sh in team.values():
            for tid, xy in sh.targets.items():
                if tid not in sensed and tid not in reported:
                    reported[tid] = xy
        for tid in sorted(reported):
            alpha, d = to_robot(pose, reported[tid])
            if d <= p.do4 * R:
                f = p.watched_weight * target_force(d, R, p)
                fx += f * math.cos(alpha)
                fy += f * math.sin(alpha)
                known = True
        for sh in team.values():
            alpha, d = to_robot(pose, (sh.pose[0], sh.pose[1]))
            f = robot_force(d, R, p)
            fx += f * math.cos(alpha)
            fy += f * math.sin(alpha)
        if not known:
            goal = view.search_goal(t, pose, own, team, self.search_reached * R, self.wander_ahead_m)
            alpha, _ = to_robot(pose, goal)
            fx += math.cos(alpha)
            fy += math.sin(alpha)
        return ForceActivity(t, fx, fy, not known)

    def integrate(self, act: ForceActivity | None, ranges: list[RangeReading]) -> tuple[float, float]:
        """The held force plus the obstacle repulsion of this tick's readings, as wheel speeds."""
        if act is None:
            return 0.0, 0.0
        return force_wheels(act.fx, act.fy, ranges, self.body_radius, self.sensor_range, self.axle, self.v_max,
                            self.params.obstacle_gain, self.params.turn_gain)


def force_wheels(fx: float, fy: float, ranges: list[RangeReading], body_radius: float, sensor_range: float,
                 axle: float, v_max: float, obstacle_gain: float, turn_gain: float) -> tuple[float, float]:
    """A force (fx, fy) in the robot's frame plus each distance sensor's obstacle repulsion,
    gain * (1 - r / range) away from it, as wheel speeds: omega = turn_gain * phi, forward
    speed v* min(|F|, 1) cos(phi) when |phi| < pi/2, both wheels clipped to c*. A-CMOMMT's
    motor, which the K-means baselines reuse to reach their goals."""
    for r in ranges:
        if r.d is None:
            continue
        surface = max(r.d - body_radius, 0.0)
        m = obstacle_gain * max(0.0, 1.0 - surface / sensor_range)
        fx -= m * math.cos(r.alpha)
        fy -= m * math.sin(r.alpha)
    mag = math.hypot(fx, fy)
    if mag < 1e-9:
        return 0.0, 0.0
    phi = math.atan2(fy, fx)
    v = v_max * min(mag, 1.0) * max(0.0, math.cos(phi))
    omega = turn_gain * phi
    half = 0.5 * omega * axle
    return min(max(v - half, -v_max), v_max), min(max(v + half, -v_max), v_max)
