"""The Khepera-like robot the paper uses (docs/design.md section 2). SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass

STEP_S = 1.024  # one target-reaching time step (section 4.1)
SUBSTEP_S = 0.032  # Webots' basic time step; wheel slip noise is drawn this often
SUBSTEPS_PER_STEP = 32
TARGET_PERIOD_S = 0.256  # target localization module period (section 3.1)
OBSTACLE_PERIOD_S = 0.128  # obstacle localization module period (section 3.1)


@dataclass(frozen=True)
class Khepera:
    """Body and wheel constants of the simulated Khepera.

    ``v_max`` is c* of Eq. 11: 0.16 m is the farthest the robot moves in one 1.024 s step.

    ``speed_unit``: the Khepera's wheel speeds are whole numbers of encoder pulses per
    10 ms, and one pulse is 0.08 mm of wheel travel, so a speed command moves in steps of
    0.08 mm / 10 ms = 8 mm/s (K-Team, Khepera User Manual, serial command 'D' "set speed";
    the same figures in RoadNarrows' Khepera II driver: 8 mm/s per pulse/10 ms, 0.08 mm
    per odometer tick). A commanded speed is executed as the nearest multiple of the unit,
    so a command under half a unit (4 mm/s) is a stop (:func:`quantize_speed`).
    """

    body_radius: float = 0.03
    axle: float = 0.053
    v_max: float = 0.16 / STEP_S
    n_range_sensors: int = 12
    sensor_range: float = 0.17  # from the body surface
    range_resolution: float = 0.005
    target_resolution: float = 0.001
    wheel_noise: float = 0.1  # executed = commanded * (1 + U(-0.1, 0.1))
    sensor_noise: float = 0.1
    speed_unit: float = 0.008  # m/s: one encoder pulse per 10 ms


def quantize_speed(c: float, unit: float, v_max: float) -> float:
    """The wheel speed a Khepera executes for command c: the nearest whole multiple of
    ``unit`` (half a unit rounds away from zero), at most v_max in magnitude; unit <= 0
    leaves c unchanged (continuous wheel speeds). Pure Python, so numba kernels can call
    a jitted copy of the same formula (:func:`cekm_swarm.experiments.arena.quantize`)."""
    if unit <= 0.0:
        return c
    n = min(math.floor(abs(c) / unit + 0.5), math.floor(v_max / unit + 1e-9))
    return math.copysign(n * unit, c) if n > 0 else 0.0


KHEPERA = Khepera()
