"""The Khepera-like robot the paper uses (docs/design.md section 2). SI units."""

from __future__ import annotations

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


KHEPERA = Khepera()
