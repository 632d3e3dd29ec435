"""The Khepera-like robot the paper uses (docs/design.md section 2). SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

# The robot's clocks, re-exported from their one home (cekm_swarm.ticks).
from .ticks import SUBSTEP_S as SUBSTEP_S
from .ticks import TARGET_PERIOD_S as TARGET_PERIOD_S

STEP_S = 1.024  # one target-reaching time step (section 4.1)
SUBSTEPS_PER_STEP = 32


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


def centre_distance(surface_range: float, body_radius: float) -> float | None:
    """A distance sensor's surface range as the obstacle input's d_j (section 3.1): the
    distance from the robot's centre, range plus body radius; None when it sees nothing
    (a range that is not finite). The one home of this conversion, for the world's sense
    messages and the controller's readings alike."""
    return surface_range + body_radius if math.isfinite(surface_range) else None


@dataclass(frozen=True)
class RobotBody:
    """What a robot's controller knows of its own body and sensors (a node's
    :attr:`cekm_swarm.node.Context.body`): taken from the scenario by whoever starts the
    controller (``cekm run``, ``cekm launch``), so no node needs the world.

    * ``body_radius``: the body's radius (m);
    * ``axle``: the distance between the wheels (m);
    * ``v_max``: the fastest a wheel turns (m/s, c* of Eq. 11): the world clamps a wheel
      speed beyond it to it, without a word;
    * ``sensor_angles``: each distance sensor's direction relative to the heading (rad,
      counter-clockwise positive), sensor j at index j;
    * ``sensor_range``: how far a distance sensor sees beyond the body surface (m); a
      reading's ``d`` is measured from the robot's centre, so it is at most
      ``body_radius + sensor_range``;
    * ``target_range``: the target sensor's range (m; inf: unlimited);
    * :attr:`sensors`: how many distance sensors it has."""

    body_radius: float = KHEPERA.body_radius
    axle: float = KHEPERA.axle
    v_max: float = KHEPERA.v_max
    sensor_range: float = KHEPERA.sensor_range
    sensor_angles: tuple[float, ...] = tuple(
        math.atan2(math.sin(2 * math.pi * j / KHEPERA.n_range_sensors),
                   math.cos(2 * math.pi * j / KHEPERA.n_range_sensors))
        for j in range(KHEPERA.n_range_sensors))
    target_range: float = math.inf

    @property
    def sensors(self) -> int:
        """How many distance sensors the robot has."""
        return len(self.sensor_angles)

    def to_dict(self) -> dict[str, Any]:
        return {"body_radius": self.body_radius, "axle": self.axle, "v_max": self.v_max,
                "sensor_range": self.sensor_range, "sensor_angles": list(self.sensor_angles),
                "target_range": None if math.isinf(self.target_range) else self.target_range}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> RobotBody:
        tr = doc.get("target_range")
        return cls(float(doc["body_radius"]), float(doc["axle"]), float(doc["v_max"]), float(doc["sensor_range"]),
                   tuple(float(a) for a in doc["sensor_angles"]), math.inf if tr is None else float(tr))
