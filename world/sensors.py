"""The robots' sensors in the world: the 12 distance sensors (ray casts from the robot's
centre, the surface range times (1 + U(-0.1, 0.1)), quantized to 5 mm; docs/design.md
section 2) and the target sensor (the target in the robot's frame, each coordinate times
(1 + U(-0.1, 0.1)), as (alpha, d) with d rounded to 1 mm), each robot with noise streams
of its own, so reading a sensor more or less often never changes another stream."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cekm_swarm.robot import KHEPERA

from . import chipmunk as cp

NOISE = KHEPERA.sensor_noise
"""Relative half-width of the uniform sensor noise."""
RANGE_RESOLUTION = KHEPERA.range_resolution
"""Distance-sensor resolution (m)."""
TARGET_RESOLUTION = KHEPERA.target_resolution
"""Target-sensor distance resolution (m)."""
NOISE_BLOCK = 12 * 64
"""Range-noise draws made at a time (the values equal drawing 12 at a time)."""


class RangeSensors:
    """The distance sensors of every robot of one space (a robot's own shape is skipped
    by its shape filter's group, i + 1)."""

    def __init__(self, space: Any, n: int, angles: np.ndarray, body_radius: float, sensor_range: float,
                 rngs: list[np.random.Generator], ray_category: int, seen_mask: int) -> None:
        self._sp = cp.cp_space(space)
        self.n, self.radius, self.range = n, body_radius, sensor_range
        self.rngs = rngs
        self.ray_len = body_radius + sensor_range + 1e-9
        self.dirs = [(math.cos(a), math.sin(a)) for a in angles]
        self.filters = [cp.shape_filter(i + 1, ray_category, seen_mask) for i in range(n)]
        self._info, self._pinfo = cp.segment_info(), cp.point_info()
        self.clear = [math.inf] * n  # each robot's smallest clearance so far
        self.near = [True] * n  # something within sensor range now
        self._noise: list[list[float]] = [[] for _ in range(n)]
        self._noise_at = [0] * n

    def update_clearance(self, px: list[float], py: list[float]) -> None:
        """Nearest surface to each robot at its pose: the minimum clearance, and whether
        anything is within sensor range (if nothing is, a read needs no ray casts)."""
        q, sp, info, r = cp.point_query_nearest, self._sp, self._pinfo, self.radius
        see = self.range + 1e-9
        clear, near, filters = self.clear, self.near, self.filters
        for i in range(self.n):
            ci = clear[i]
            q(sp, (px[i], py[i]), r + (ci if ci > see else see), filters[i], info)
            c = info.distance - r
            near[i] = c <= see
            if c < ci:
                clear[i] = c

    def cast(self, i: int, x: float, y: float, th: float) -> list[float]:
        """True surface range along each ray (m, >= 0; beyond range when it hits nothing).
        Rays start at the centre, so a surface touching the body reads 0."""
        L = self.ray_len
        if not self.near[i]:
            return [L] * len(self.dirs)
        c, s = math.cos(th) * L, math.sin(th) * L
        q, sp, f, info = cp.segment_query_first, self._sp, self.filters[i], self._info
        start = cp.vect(x, y)
        r = self.radius
        out: list[float] = []
        app = out.append
        for cj, sj in self.dirs:
            q(sp, start, (x + c * cj - s * sj, y + s * cj + c * sj), 0.0, f, info)
            d = info.alpha * L - r
            app(d if d > 0.0 else 0.0)
        return out

    def _noise_draws(self, i: int) -> list[float]:
        k, buf, m = self._noise_at[i], self._noise[i], len(self.dirs)
        if k + m > len(buf):
            buf = self._noise[i] = self.rngs[i].uniform(-NOISE, NOISE, NOISE_BLOCK).tolist()
            k = 0
        self._noise_at[i] = k + m
        return buf[k: k + m]

    def true_ranges(self, i: int, x: float, y: float, th: float) -> np.ndarray:
        lim = self.range
        return np.array([d if d <= lim else math.nan for d in self.cast(i, x, y, th)])

    def readings(self, i: int, x: float, y: float, th: float) -> np.ndarray:
        """The noisy, quantized readings (m), NaN when nothing is within range (a reading
        may exceed the range by up to the 10 % noise)."""
        lim, res, nan = self.range, RANGE_RESOLUTION, math.nan
        u = self._noise_draws(i)
        return np.array([round(d * (1.0 + e) / res) * res if d <= lim else nan
                         for d, e in zip(self.cast(i, x, y, th), u, strict=True)])


def target_reading(rng: np.random.Generator, pose: tuple[float, float, float], target: tuple[float, float],
                   target_range: float) -> tuple[float, float, bool]:
    """(alpha, d, visible) of ``target`` from ``pose``: the target sensor (see the module
    docstring); alpha = 0 when the rounded d is 0; NaN, NaN, False beyond the range. The
    noise is drawn whether the target is visible or not, so the stream never depends on it."""
    x, y, th = pose
    dx, dy = target[0] - x, target[1] - y
    c, s = math.cos(th), math.sin(th)
    lx = c * dx + s * dy
    ly = -s * dx + c * dy
    u = rng.uniform(-NOISE, NOISE, 2)
    nx = lx * (1.0 + float(u[0]))
    ny = ly * (1.0 + float(u[1]))
    if not math.hypot(dx, dy) <= target_range:
        return (math.nan, math.nan, False)
    d = round(math.hypot(nx, ny) / TARGET_RESOLUTION) * TARGET_RESOLUTION
    if d == 0.0:
        return (0.0, 0.0, True)
    a = math.atan2(ny, nx)
    if a <= -math.pi:
        a = math.pi
    return (a, d, True)
