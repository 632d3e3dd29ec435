"""The obstacle-free training arena of section 4.1 as a fast kinematic plant.

Section 4.1 needs millions of robot steps (6 networks x 5 trials x 100,000 steps plus
tests), so it runs on this exact-arc kinematic model of the differential drive rather
than on the pymunk world of section 4.2; the robot, noise and sensor model are the same
(docs/design.md section 2). The arena has walls: the robot's centre is kept at least one body
radius inside, and a step that touched a wall is not learned from (docs/design.md section 3).
These are plain numba functions, shared by the reference and the fast trial runners.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import ParameterError
from ..models.fast import wrap
from ..robot import KHEPERA, STEP_S, SUBSTEP_S, SUBSTEPS_PER_STEP, quantize_speed


@dataclass(frozen=True)
class Arena:
    """A square arena [0, size]^2 and the robot that moves in it.

    speed_unit: 0 (the default) gives continuous wheel speeds. A positive unit, e.g. the
    Khepera's 8 mm/s (:class:`cekm_swarm.robot.Khepera`), executes wheel speeds as whole
    multiples of it, so a command under half a unit executes as no motion. In a 1.024 s
    step the smallest move is then a 4.1 mm pivot or a 0.31 rad spin, larger than the
    region where a command is under half a unit, and robots circle their targets
    (docs/reproduction-4.1.md section 1), so it is an option. When a robot has stopped is
    the stop rule's (:mod:`.stopping`).

    target_resolution: the target sensor rounds d to it (the Khepera-like robot's 1 mm); 0
    leaves d unrounded, so that the goal state d = 0 is never sensed.
    """

    size: float = 5.0
    target_margin: float = 0.05  # targets at least this far from the edge
    body_radius: float = KHEPERA.body_radius
    axle: float = KHEPERA.axle
    v_max: float = KHEPERA.v_max
    step_s: float = STEP_S
    substeps: int = SUBSTEPS_PER_STEP
    target_resolution: float = KHEPERA.target_resolution
    speed_unit: float = 0.0  # see the class docstring

    def __post_init__(self) -> None:
        if not (math.isfinite(self.target_resolution) and 0.0 <= self.target_resolution < 0.1):
            raise ParameterError(f"Arena.target_resolution must be 0 (distances not rounded) or a positive distance "
                                 f"below 0.1 m, got {self.target_resolution!r}")
        if not (math.isfinite(self.speed_unit) and 0.0 <= self.speed_unit < self.v_max):
            raise ParameterError(f"Arena.speed_unit must be 0 (continuous) or a positive speed below v_max "
                                 f"({self.v_max:.4f} m/s), got {self.speed_unit!r}")

    @property
    def quantized(self) -> bool:
        """Whether executed wheel speeds are whole multiples of speed_unit."""
        return self.speed_unit > 0.0

    @property
    def substep_s(self) -> float:
        return self.step_s / self.substeps

    @property
    def centre(self) -> tuple[float, float]:
        return (self.size / 2.0, self.size / 2.0)

    def vector(self) -> np.ndarray:
        """The float64 vector the kernels read (layout: A_* below)."""
        return np.array([self.size, self.body_radius, self.axle, self.v_max, self.substep_s,
                         float(self.substeps), self.target_resolution, self.speed_unit])


A_SIZE, A_RADIUS, A_AXLE, A_VMAX, A_DT, A_NSUB, A_RES, A_UNIT = range(8)
assert abs(SUBSTEP_S * SUBSTEPS_PER_STEP - STEP_S) < 1e-12


quantize = njit(cache=True)(quantize_speed)
"""numba copy of :func:`cekm_swarm.robot.quantize_speed` (one formula, two callers)."""


@njit(cache=True)
def executed_command(c0, c1, arena):
    """What the wheels execute for command (c0, c1): clipped to c*, then quantized to the
    speed unit (arena[A_UNIT] = 0: unchanged). Both 0 is a stop."""
    v_max = arena[A_VMAX]
    c0 = min(max(c0, -v_max), v_max)
    c1 = min(max(c1, -v_max), v_max)
    return quantize(c0, arena[A_UNIT], v_max), quantize(c1, arena[A_UNIT], v_max)


@njit(cache=True)
def sense_target(x, y, th, tx, ty, n0, n1, res):
    """Target sensor: the target in the robot frame, each coordinate times its noise
    factor, as (alpha, d) with d rounded to the resolution (res 0: not rounded); alpha = 0
    when d is 0."""
    dx = tx - x
    dy = ty - y
    c = math.cos(th)
    s = math.sin(th)
    lx = (c * dx + s * dy) * n0
    ly = (-s * dx + c * dy) * n1
    d = math.sqrt(lx * lx + ly * ly)
    if res > 0.0:
        d = math.floor(d / res + 0.5) * res
    if d == 0.0:
        return 0.0, 0.0
    return math.atan2(ly, lx), d


@njit(cache=True)
def move_arc(x, y, th, s, c, vl, vr, dt, axle):
    """Exact differential-drive arc over dt from heading th with s, c = sin th, cos th.

    Returns x, y, theta (unwrapped), its sine and cosine, and the arc length; passing the
    sine and cosine along saves half the trigonometry of a step of sub-steps.
    """
    v = 0.5 * (vl + vr)
    om = (vr - vl) / axle
    if abs(om) > 1e-12:
        th2 = th + om * dt
        s2 = math.sin(th2)
        c2 = math.cos(th2)
        r = v / om
        return x + r * (s2 - s), y - r * (c2 - c), th2, s2, c2, abs(v) * dt
    return x + v * dt * c, y + v * dt * s, th, s, c, abs(v) * dt


@njit(cache=True)
def move(x, y, th, vl, vr, dt, axle):
    """Exact differential-drive arc over dt; returns x, y, theta (unwrapped), arc length."""
    x, y, th, _, _, ds = move_arc(x, y, th, math.sin(th), math.cos(th), vl, vr, dt, axle)
    return x, y, th, ds


@njit(cache=True)
def keep_inside(x, y, lo, hi):
    """The arena walls: clamp the centre into [lo, hi]^2; True when a wall was touched."""
    touched = False
    if x < lo:
        x, touched = lo, True
    elif x > hi:
        x, touched = hi, True
    if y < lo:
        y, touched = lo, True
    elif y > hi:
        y, touched = hi, True
    return x, y, touched


@njit(cache=True)
def displacement(x0, y0, th0, x1, y1, dth):
    """v: the step's displacement in polar form in the robot frame at its start.

    Below 1e-4 m, alpha_v = dtheta / 2 (the chord direction's limit), so pure turns
    still train the d = 0 neurons (docs/design.md section 3, item 2).
    """
    dx = x1 - x0
    dy = y1 - y0
    c = math.cos(th0)
    s = math.sin(th0)
    lx = c * dx + s * dy
    ly = -s * dx + c * dy
    d = math.sqrt(lx * lx + ly * ly)
    if d < 1e-4:
        return wrap(0.5 * dth), d
    return math.atan2(ly, lx), d


@njit(cache=True)
def drive(pose, c0, c1, wheel_noise, arena, tx, ty, eps, t_eps, path_eps, t_start, path_start):
    """Execute command (c0, c1) for one step of substeps, each wheel times its noise factor.

    Updates pose (x, y, theta) in place and returns (path length, touched a wall, dtheta).
    When eps is non-empty, records for each eps[e] not yet reached (t_eps[e] is NaN) the
    time and path length at the first sub-step within eps[e] of the target (tx, ty).
    """
    lo = arena[A_RADIUS]
    hi = arena[A_SIZE] - arena[A_RADIUS]
    dt = arena[A_DT]
    axle = arena[A_AXLE]
    x, y, th = pose[0], pose[1], pose[2]
    th0 = th
    s = math.sin(th)
    c = math.cos(th)
    path = 0.0
    touched = False
    ne = eps.shape[0]
    for k in range(wheel_noise.shape[0]):
        x, y, th, s, c, ds = move_arc(x, y, th, s, c, c0 * wheel_noise[k, 0], c1 * wheel_noise[k, 1], dt, axle)
        x, y, hit = keep_inside(x, y, lo, hi)
        touched = touched or hit
        path += ds
        if ne > 0:
            dist = math.sqrt((x - tx) ** 2 + (y - ty) ** 2)
            if dist <= eps[ne - 1]:
                for e in range(ne):
                    if dist <= eps[e] and math.isnan(t_eps[e]):
                        t_eps[e] = t_start + (k + 1) * dt
                        path_eps[e] = path_start + path
    pose[0], pose[1], pose[2] = x, y, wrap(th)
    return path, touched, th - th0


def draw_targets(rng: np.random.Generator, count: int, arena: Arena) -> np.ndarray:
    """Uniform random targets at least target_margin from the arena's edge."""
    return rng.uniform(arena.target_margin, arena.size - arena.target_margin, size=(count, 2))
