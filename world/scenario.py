"""Scenario files: TOML schema, loading and strict validation.

A scenario with any error is refused before anything starts: :class:`ScenarioError`
names the file, the field path (``obstacles[1].motion.radius``) and what is wrong.
The schema reference is ``world/scenarios/README.md``.
"""

from __future__ import annotations

import copy
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from cekm_swarm.robot import KHEPERA

from .motion import Motion, ScriptedMotion

Point = tuple[float, float]

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"

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

_ID_RE = re.compile(r"^[A-Za-z0-9_-]+$")


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


# ------------------------------------------------------------------ public loading


def scenario_names() -> list[str]:
    """Names of the shipped scenarios (files in ``world/scenarios``)."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def resolve_scenario_path(path_or_name: str | Path) -> Path:
    """A file path, or a bare name resolved to ``world/scenarios/<name>.toml``."""
    p = Path(path_or_name)
    if p.is_file():
        return p
    name = str(path_or_name)
    if _ID_RE.match(name):
        q = SCENARIO_DIR / f"{name}.toml"
        if q.is_file():
            return q
    if p.is_dir():
        raise ScenarioError(f"{path_or_name}: is a directory, not a scenario file")
    raise ScenarioError(
        f"{path_or_name}: no such scenario file or shipped scenario name (shipped: {', '.join(scenario_names())})"
    )


def load_scenario(path_or_name: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Load and validate a scenario.

    ``path_or_name``: a TOML file path, or a shipped name like ``"concave"``.
    ``overrides``: optional ``{field path: value}`` applied to the raw TOML before
    validation, e.g. ``{"obstacles[0].width": 0.5, "sensors.range": 0.25}`` (used by
    parameter sweeps); overridden values are validated like the file's own.
    """
    path = resolve_scenario_path(path_or_name)
    fname = str(path)
    try:
        with open(path, "rb") as f:
            raw = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{fname}: TOML syntax error: {e}") from None
    if overrides:
        raw = copy.deepcopy(raw)
        for k, v in overrides.items():
            _apply_override(raw, k, v, fname)
    return parse_scenario(raw, source=fname, default_name=path.stem)


def parse_scenario(raw: Mapping[str, Any], source: str = "<dict>", default_name: str = "scenario") -> Scenario:
    """Validate an already-parsed TOML document (a dict) into a :class:`Scenario`."""
    from .scenario_parser import Parser

    return Parser(source).scenario(raw, default_name)


# ------------------------------------------------------------------ overrides

_TOKEN_RE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


def _apply_override(raw: dict[str, Any], key: str, value: Any, fname: str) -> None:
    steps: list[str | int] = []
    for tok in key.split("."):
        m = _TOKEN_RE.match(tok)
        if not m:
            raise ScenarioError(f"{fname}: override {key!r}: malformed field path")
        steps.append(m.group(1))
        steps.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    cur: Any = raw
    for i, s in enumerate(steps[:-1]):
        nxt = steps[i + 1]
        if isinstance(s, int):
            if not isinstance(cur, list) or s >= len(cur):
                raise ScenarioError(f"{fname}: override {key!r}: index [{s}] does not exist")
            cur = cur[s]
        else:
            if not isinstance(cur, dict):
                raise ScenarioError(f"{fname}: override {key!r}: {s!r} is not inside a table")
            if s not in cur:
                cur[s] = [] if isinstance(nxt, int) else {}
            cur = cur[s]
    last = steps[-1]
    if isinstance(last, int):
        if not isinstance(cur, list) or last >= len(cur):
            raise ScenarioError(f"{fname}: override {key!r}: index [{last}] does not exist")
        cur[last] = value
    else:
        if not isinstance(cur, dict):
            raise ScenarioError(f"{fname}: override {key!r}: {last!r} is not inside a table")
        cur[last] = value


