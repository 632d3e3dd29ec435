"""What a robot's controller receives: plain sensor readings (the message protocol's content)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cekm_swarm.robot import centre_distance


@dataclass(frozen=True)
class TargetReading:
    """The target sensor: egocentric (alpha, d) of the target, and whether it is in range."""

    alpha: float
    d: float
    visible: bool = True

    @property
    def usable(self) -> bool:
        return self.visible and math.isfinite(self.alpha) and math.isfinite(self.d)

    @property
    def at_goal(self) -> bool:
        """The goal state u(T) = (alpha, 0) (section 3.1)."""
        return self.usable and self.d == 0.0


@dataclass(frozen=True)
class RangeReading:
    """One distance sensor: its fixed direction alpha_j and the obstacle's distance from the
    robot's centre (surface range plus body radius), or None when it sees nothing."""

    index: int
    alpha: float
    d: float | None


def range_readings(surface_ranges: np.ndarray, sensor_angles: np.ndarray, body_radius: float) -> list[RangeReading]:
    """Sensor surface ranges (NaN = nothing seen) as obstacle inputs u_j = (alpha_j, d_j) from the centre."""
    out = []
    for j, (r, a) in enumerate(zip(surface_ranges, sensor_angles, strict=True)):
        out.append(RangeReading(j, float(a), centre_distance(float(r), body_radius)))
    return out
