"""The guard: a command kept off what the ranges hit in the last ticks (docs/fields.md, "The
ninth round").

Twelve rays 30 degrees apart leave gaps, and a doorway's jamb end is a point that falls into
them: a ray sees it, the obstacle field turns the robot away, the next ray misses it, the
target field turns the robot back, and a side of the body closes on the corner that no ray
sees at that tick. The guard remembers the hit points of the last ``memory`` ticks in the
dead-reckoned frame (:mod:`~.dead_reckoning`), less those a ray of this tick sees free space
through (something that moved away). If the motor EKM's command would bring the body within
``margin`` of a remembered hit within ``horizon`` seconds (nearer than it is already, when it
is nearer than ``margin`` now), the command is replaced by the nearest one, on a grid of
wheel speeds, that does not. A turn in place never closes on anything, so there always is
one.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .bounds import check_bounds
from .dead_reckoning import Pose
from .movers import seen_free


@dataclass(frozen=True)
class GuardParams:
    """memory: ticks whose hit points are remembered (0: no guard); margin: the clearance (m)
    a command must keep from them; horizon: seconds of motion checked; step: seconds between
    the instants checked; speeds: wheel speeds per wheel on the replacements' grid (odd, so
    that a wheel at rest is on it: the pivots); eps: how near (m) a ray of this tick must
    pass a remembered hit, short of its own free length, to clear it."""

    memory: int = 6
    margin: float = 0.01
    horizon: float = 0.384
    step: float = 0.064
    speeds: int = 9
    eps: float = 0.006

    def check(self) -> GuardParams:
        """Itself, or ValueError naming the first parameter out of range."""
        check_bounds("guard", self, positive=("horizon", "step", "eps"), nonnegative=("memory", "margin"))
        if self.speeds < 3 or self.speeds % 2 == 0:
            raise ValueError(f"guard: speeds must be an odd whole number >= 3, got {self.speeds!r}")
        return self


def remembered(hits: Sequence[np.ndarray], rays: np.ndarray, eps: float) -> np.ndarray:
    """The hit points of earlier ticks (each rows x, y) that no ray of this tick (rows origin
    x, y, direction x, y, the length surely free) passes within ``eps`` of short of its free
    length: what is still there, as far as this tick can tell. Rows x, y."""
    points = np.concatenate([h for h in hits if len(h)]) if any(len(h) for h in hits) else np.zeros((0, 2))
    return points[~seen_free(points, rays, eps)]


def clearances(pose: Pose, commands: np.ndarray, points: np.ndarray, body: float, axle: float,
               horizon: float, step: float) -> np.ndarray:
    """For each wheel command (rows v_l, v_r), the least distance (m) between the body (a
    disc of radius ``body``) and a point over ``horizon`` s of executing it, now included."""
    x0, y0, th0 = pose
    v = 0.5 * (commands[:, 0] + commands[:, 1])
    omega = (commands[:, 1] - commands[:, 0]) / axle
    x, y, th = np.full(len(commands), x0), np.full(len(commands), y0), np.full(len(commands), th0)
    least = np.full(len(commands), np.inf)
    for _ in range(int(round(horizon / step)) + 1):
        d = np.hypot(points[:, 0][None, :] - x[:, None], points[:, 1][None, :] - y[:, None])
        least = np.minimum(least, d.min(axis=1) - body)
        x, y, th = x + v * step * np.cos(th), y + v * step * np.sin(th), th + omega * step
    return least


def guard(pose: Pose, command: tuple[float, float], points: np.ndarray, body: float, axle: float, v_max: float,
          params: GuardParams) -> tuple[float, float]:
    """The command, or the nearest command on a grid of wheel speeds within +-``v_max`` that
    keeps the body ``margin`` off every point (or, where it is nearer now, no nearer) over
    ``horizon`` s."""
    if not len(points):
        return command
    p = params
    gaps = np.hypot(points[:, 0] - pose[0], points[:, 1] - pose[1]) - body
    reach = max(v_max, abs(command[0]), abs(command[1])) * p.horizon  # the farthest the centre moves
    near = gaps < p.margin + reach
    if not near.any():  # nothing the body could come within margin of: most ticks
        return command
    points, now = points[near], float(gaps.min())
    c = np.array([command], dtype=np.float64)
    own = clearances(pose, c, points, body, axle, p.horizon, p.step)[0]
    floor = min(p.margin, now)
    if own >= floor:
        return command
    s = np.linspace(-v_max, v_max, p.speeds)
    grid = np.stack(np.meshgrid(s, s, indexing="ij"), axis=-1).reshape(-1, 2)
    grid = grid[(grid[:, 0] != 0.0) | (grid[:, 1] != 0.0)]  # not stop: the same command would come again
    safe = grid[clearances(pose, grid, points, body, axle, p.horizon, p.step) >= floor - 1e-12]
    best = safe[np.argmin(np.hypot(safe[:, 0] - c[0, 0], safe[:, 1] - c[0, 1]))]
    return float(best[0]), float(best[1])


@dataclass
class Guard:
    """The hit points of the last ``memory`` ticks, and the check of a command against them."""

    params: GuardParams = GuardParams()
    seen: deque[np.ndarray] = field(default_factory=deque)  # each tick's hit points, rows x, y
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # remembered at the last update

    def update(self, hits: np.ndarray, rays: np.ndarray) -> np.ndarray:
        """One tick's hit points and rays (as :func:`remembered` takes them); returns the points
        remembered now, this tick's hits among them."""
        self.seen.append(hits)
        while len(self.seen) > self.params.memory:
            self.seen.popleft()
        self.points = remembered(list(self.seen), rays, self.params.eps)
        return self.points

    def command(self, pose: Pose, command: tuple[float, float], body: float, axle: float,
                v_max: float) -> tuple[float, float]:
        """:func:`guard` of the command against the points remembered at the last update."""
        if self.params.memory == 0:
            return command
        return guard(pose, command, self.points, body, axle, v_max, self.params)
