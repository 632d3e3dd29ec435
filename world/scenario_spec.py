"""A scenario as plain data: the validated specs of its robots, walls, obstacles and
targets (:class:`Scenario`), the defaults a scenario file may leave out, and
:class:`ScenarioError`. Loading is :mod:`world.scenario`; the field-by-field validation
:mod:`world.scenario_parser`."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cekm_swarm.robot import KHEPERA

from .motion import Motion, ScriptedMotion

Point = tuple[float, float]

#: Robot body radius (m); used by the loader's overlap checks and by the world.
BODY_RADIUS = KHEPERA.body_radius
#: Default wall thickness (m).
DEFAULT_WALL_THICKNESS = 0.02
#: Default distance-sensor range from the body surface (m).
DEFAULT_SENSOR_RANGE = KHEPERA.sensor_range
#: Wheel speed unit of the Khepera's motor controller (m/s): speeds are set in whole
#: encoder pulses per 10 ms, and one pulse is 0.08 mm of wheel travel, so one unit is
#: 8 mm/s (K-Team's Khepera user manual). ``[plant] speed_unit`` defaults to it.
WHEEL_SPEED_UNIT = KHEPERA.speed_unit
#: Default of ``[plant] speed_unit`` (0: continuous wheel speeds).
DEFAULT_SPEED_UNIT = 0.0
#: Default inset of a random-walk target's bounds from the arena bounds (m).
RANDOM_WALK_INSET = 0.05

ID_RE = re.compile(r"^[A-Za-z0-9_-]+$")
"""An id or a shipped scenario's name: letters, digits, ``_`` and ``-``."""


class ScenarioError(ValueError):
    """A scenario file (or an override) is invalid. The message names the file, the
    field path and the problem."""


# --------------------------------------------------------------------------- specs


@dataclass(frozen=True)
class RobotSpec:
    """A robot: id, start pose (x, y, theta) and optional goal (a target id)."""

    id: str
    start: tuple[float, float, float]
    goal: str | None


@dataclass(frozen=True)
class TargetSpec:
    """A target (a point, not a body): initial position and motion model."""

    id: str
    position: Point
    motion: Motion
    source: str


@dataclass(frozen=True)
class WallSpec:
    """A static wall: rectangle around segment a-b, ``thickness`` wide, square ends."""

    a: Point
    b: Point
    thickness: float
    known: bool
    source: str
    outline: tuple[Point, ...]


@dataclass(frozen=True)
class ObstacleSpec:
    """A static or moving obstacle.

    Static obstacles have ``motion`` None and their ``outline``/``parts`` in world
    coordinates (discs: ``center``/``radius``). Moving obstacles (disc or box) have a
    scripted ``motion``; their outline/parts are local to the point on the path.
    """

    id: str
    shape: str  # "disc" | "box" | "polygon" | "concave"
    known: bool
    source: str
    params: Mapping[str, Any] = field(hash=False)
    radius: float | None
    center: Point | None
    outline: tuple[Point, ...] | None
    parts: tuple[tuple[Point, ...], ...]
    motion: ScriptedMotion | None


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (immutable plain data)."""

    name: str
    description: str
    source: str
    seed: int
    bounds: tuple[float, float, float, float]
    boundary_walls: bool
    wall_thickness: float
    sensor_range: float
    target_range: float
    robots: tuple[RobotSpec, ...]
    walls: tuple[WallSpec, ...]
    obstacles: tuple[ObstacleSpec, ...]
    targets: tuple[TargetSpec, ...]
    speed_unit: float = DEFAULT_SPEED_UNIT  # [plant]: wheel speeds are whole multiples of it; 0 = continuous
    plan_checkpoints: bool = False  # plan checkpoints on the known walls and feed them as goals (Fig. 12)
    retarget: bool = False  # a new random target when a robot stops at its own (section 4.1's training; world.training)
    explore: bool = False  # with retarget: exploration noise on the executed wheel speeds (world.training)

    @property
    def robot_ids(self) -> list[str]:
        return [r.id for r in self.robots]

    def robot(self, robot_id: str) -> RobotSpec:
        for r in self.robots:
            if r.id == robot_id:
                return r
        raise KeyError(f"unknown robot id {robot_id!r} (known: {self.robot_ids})")
