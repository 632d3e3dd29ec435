"""A robot's pose dead-reckoned from its own wheel commands (docs/fields.md, the seventh
round): what the trail field remembers places in and the movers' detector lays its rays in,
with no node needing the world's pose."""

from __future__ import annotations

import math
from dataclasses import dataclass

Pose = tuple[float, float, float]  # x, y (m), heading (rad) in the robot's own start frame


def executed(v_l: float, v_r: float, v_max: float) -> tuple[float, float]:
    """The wheel command as the wheels execute it: each wheel's speed clamped to +-v_max."""
    return min(max(v_l, -v_max), v_max), min(max(v_r, -v_max), v_max)


@dataclass
class DeadReckoning:
    """The pose reached by executing every wheel command from the last call to the next."""

    pose: Pose = (0.0, 0.0, 0.0)
    _t: float | None = None

    def move(self, t: float, v_l: float, v_r: float, axle: float) -> None:
        """The wheel command (v_l, v_r) executed from the last call to ``t`` (a differential
        drive with ``axle``, the heading at the interval's middle); the first call only sets
        the clock."""
        if self._t is not None and t > self._t:
            dt = t - self._t
            x, y, th = self.pose
            v, omega = 0.5 * (v_l + v_r), (v_r - v_l) / axle
            mid = th + 0.5 * omega * dt
            self.pose = (x + v * dt * math.cos(mid), y + v * dt * math.sin(mid), th + omega * dt)
        self._t = t
