"""What a tracking robot knows of its team and the targets, and the one search behaviour
every tracking controller uses (docs/tracking.md).

Inputs are plain values (the modules turn messages into them): the robot's own pose and
sensed targets, and its teammates' :class:`TeammateShare` (a ``share`` message's content).
Lockstep semantics: at a tick of sim time t a robot uses
the teammates' shares stamped before t (they publish on the same target ticks, so that is
the previous target tick's: one tick of communication delay); a share stamped t or
later waits for the next tick. That makes a distributed run deterministic: it waits for
exactly those shares.

Search behaviour (when a robot has no target to track at full weight): go to the last
reported position of a target that nobody observes now (the nearest such position);
once within ``search_reached * R`` of it without seeing the target, forget it. With no
such position, wander: the search goal is ``wander_ahead_m`` straight ahead, so the
robot drives on and the obstacle (and teammate) fields turn it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class TeammateShare:
    """What a robot tells its team each target tick: its ``pose`` (x, y, theta) and the
    targets it sees, ``targets`` = {target id: (x, y)} in the world frame, at sim time ``stamp``."""

    stamp: float
    pose: tuple[float, float, float]
    targets: dict[str, tuple[float, float]]


def to_world(pose: tuple[float, float, float], alpha: float, d: float) -> tuple[float, float]:
    """A point sensed at (alpha, d) in the robot's frame, in the world frame."""
    x, y, th = pose
    return (x + d * math.cos(th + alpha), y + d * math.sin(th + alpha))


def to_robot(pose: tuple[float, float, float], p: tuple[float, float]) -> tuple[float, float]:
    """A world point as (alpha, d) in the robot's frame, alpha in (-pi, pi]."""
    x, y, th = pose
    dx, dy = p[0] - x, p[1] - y
    d = math.hypot(dx, dy)
    if d == 0.0:
        return (0.0, 0.0)
    a = math.atan2(dy, dx) - th
    a = math.atan2(math.sin(a), math.cos(a))
    if a <= -math.pi:
        a = math.pi
    return (a, d)


@dataclass
class TeamView:
    """The latest share of every teammate, and the last reported position of every target."""

    me: str
    share_timeout_s: float = 1.0
    memory_s: float = 30.0
    shares: dict[str, TeammateShare] = field(default_factory=dict)
    memory: dict[str, tuple[float, float, float]] = field(default_factory=dict)  # id: (x, y, stamp)

    def receive(self, robot: str, share: TeammateShare) -> None:
        """A teammate's share arrived (own shares and older ones than held are ignored)."""
        if robot == self.me:
            return
        held = self.shares.get(robot)
        if held is None or share.stamp >= held.stamp:
            self.shares[robot] = share

    def drop(self, robot: str) -> None:
        """The teammate is gone (its liveliness tokens vanished): out of every field at once."""
        self.shares.pop(robot, None)

    def teammates(self, t: float) -> dict[str, TeammateShare]:
        """The shares usable at tick t: stamped before t and not older than the timeout."""
        return {r: s for r, s in sorted(self.shares.items())
                if s.stamp < t and t - s.stamp <= self.share_timeout_s}

    def update_memory(self, t: float, own: dict[str, tuple[float, float]], team: dict[str, TeammateShare]) -> None:
        """Remember where each target was last reported (own sightings win over teammates')."""
        for s in team.values():
            for tid, xy in s.targets.items():
                held = self.memory.get(tid)
                if held is None or s.stamp >= held[2]:
                    self.memory[tid] = (xy[0], xy[1], s.stamp)
        for tid, xy in own.items():
            self.memory[tid] = (xy[0], xy[1], t)
        for tid in [k for k, v in self.memory.items() if t - v[2] > self.memory_s]:
            del self.memory[tid]

    def search_goal(self, t: float, pose: tuple[float, float, float], own: dict[str, tuple[float, float]],
                    team: dict[str, TeammateShare], reached: float, ahead: float) -> tuple[float, float]:
        """The search goal in the world frame (see the module's docstring)."""
        watched = set(own)
        for s in team.values():
            watched.update(s.targets)
        best, best_d = None, math.inf
        for tid in sorted(self.memory):
            if tid in watched:
                continue
            x, y, _ = self.memory[tid]
            d = math.hypot(x - pose[0], y - pose[1])
            if d <= reached:
                del self.memory[tid]  # searched there: not found
                continue
            if d < best_d:
                best, best_d = (x, y), d
        if best is not None:
            return best
        return (pose[0] + ahead * math.cos(pose[2]), pose[1] + ahead * math.sin(pose[2]))


def observers_nearer(tid: str, my_d: float, team: dict[str, TeammateShare]) -> int:
    """How many teammates observe target ``tid`` and are nearer to it than this robot's
    ``my_d`` (each by its own share: its pose and where it sees the target)."""
    n = 0
    for s in team.values():
        xy = s.targets.get(tid)
        if xy is not None:
            px, py, _ = s.pose
            if math.hypot(xy[0] - px, xy[1] - py) < my_d:
                n += 1
    return n


def observers_other(tid: str, team: dict[str, TeammateShare]) -> int:
    """How many teammates observe target ``tid`` (by their shares)."""
    return sum(1 for s in team.values() if tid in s.targets)
