"""Motion models for moving obstacles and targets.

Scripted models (:class:`Fixed`, :class:`CircleMotion`, :class:`LineMotion`) are pure
functions of sim time, so a moving obstacle is always exactly where its script says.
:class:`RandomWalk` is stateful and draws from the world's target-noise stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

Point = tuple[float, float]


@dataclass(frozen=True)
class Fixed:
    """Does not move."""

    kind = "fixed"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "fixed"}


@dataclass(frozen=True)
class CircleMotion:
    """Uniform motion on a circle: angle(t) = phase + s * angular_speed * t with
    s = +1 for ``ccw`` (anticlockwise, angle increases) and -1 for ``cw``."""

    center: Point
    radius: float
    angular_speed: float  # rad/s, >= 0
    phase: float = 0.0  # rad
    direction: str = "ccw"
    kind = "circle"

    def angle(self, t: float) -> float:
        s = 1.0 if self.direction == "ccw" else -1.0
        return self.phase + s * self.angular_speed * t

    def position(self, t: float) -> Point:
        a = self.angle(t)
        return (self.center[0] + self.radius * math.cos(a), self.center[1] + self.radius * math.sin(a))

    def to_dict(self) -> dict[str, Any]:
        return {
            "type": "circle",
            "center": list(self.center),
            "radius": self.radius,
            "angular_speed": self.angular_speed,
            "phase": self.phase,
            "direction": self.direction,
        }


@dataclass(frozen=True)
class LineMotion:
    """Back and forth between ``a`` and ``b`` at constant ``speed``. ``phase`` is the
    fraction of a full back-and-forth cycle at t = 0 (0: at a heading to b; 0.5: at b
    heading to a)."""

    a: Point
    b: Point
    speed: float  # m/s, > 0
    phase: float = 0.0  # in [0, 1)
    kind = "line"

    def position(self, t: float) -> Point:
        ax, ay = self.a
        bx, by = self.b
        length = math.hypot(bx - ax, by - ay)
        s = math.fmod(self.phase * 2.0 * length + self.speed * t, 2.0 * length)
        if s < 0.0:
            s += 2.0 * length
        f = s / length if s <= length else (2.0 * length - s) / length
        return (ax + (bx - ax) * f, ay + (by - ay) * f)

    def to_dict(self) -> dict[str, Any]:
        return {"type": "line", "a": list(self.a), "b": list(self.b), "speed": self.speed, "phase": self.phase}


@dataclass(frozen=True)
class RandomWalk:
    """Constant ``speed`` along a heading that diffuses: each sub-step of length dt,
    heading += turn_noise * sqrt(dt) * N(0, 1) (turn_noise in rad/sqrt(s)). The walker
    reflects off the edges of ``bounds`` = (xmin, ymin, xmax, ymax), so it stays inside."""

    speed: float
    turn_noise: float
    heading: float  # initial heading, rad
    bounds: tuple[float, float, float, float]
    kind = "random_walk"

    def step(self, x: float, y: float, heading: float, dt: float,
             rng: np.random.Generator) -> tuple[float, float, float]:
        """One sub-step from (x, y, heading); returns the new (x, y, heading)."""
        heading += self.turn_noise * math.sqrt(dt) * float(rng.standard_normal())
        x += self.speed * dt * math.cos(heading)
        y += self.speed * dt * math.sin(heading)
        xmin, ymin, xmax, ymax = self.bounds
        if x < xmin:
            x, heading = 2.0 * xmin - x, math.pi - heading
        elif x > xmax:
            x, heading = 2.0 * xmax - x, math.pi - heading
        if y < ymin:
            y, heading = 2.0 * ymin - y, -heading
        elif y > ymax:
            y, heading = 2.0 * ymax - y, -heading
        # a step longer than the box is impossible for sane scenarios; clamp anyway
        x = min(max(x, xmin), xmax)
        y = min(max(y, ymin), ymax)
        return x, y, math.remainder(heading, 2.0 * math.pi)

    def to_dict(self) -> dict[str, Any]:
        return {
            "type": "random_walk",
            "speed": self.speed,
            "turn_noise": self.turn_noise,
            "heading": self.heading,
            "bounds": list(self.bounds),
        }


Motion = Fixed | CircleMotion | LineMotion | RandomWalk
ScriptedMotion = CircleMotion | LineMotion
