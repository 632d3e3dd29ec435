"""pymunk construction shared by the world and the scenario checks (internal)."""

from __future__ import annotations

import math
from typing import Any

import pymunk

from .scenario_spec import ObstacleSpec, Scenario

# Shape-filter categories (bits). Rays use their own category and see the rest.
CAT_STATIC = 1 << 0  # walls and static obstacles
CAT_MOVING = 1 << 1  # moving obstacles
CAT_ROBOT = 1 << 2  # robot bodies
CAT_RAY = 1 << 3  # sensor rays / clearance queries (never a shape)
MASK_ALL = 0xFFFFFFFF
MASK_SEEN = CAT_STATIC | CAT_MOVING | CAT_ROBOT

# Collision types.
CT_ROBOT = 1
CT_STATIC = 2
CT_MOVING = 3

FRICTION_STATIC = 0.5
FRICTION_ROBOT = 0.3


def _static_shapes(body: pymunk.Body, sc: Scenario) -> list[tuple[pymunk.Shape, str]]:
    """Shapes for walls and static obstacles on ``body``, each with its item key."""
    out: list[tuple[pymunk.Shape, str]] = []
    for w in sc.walls:
        out.append((pymunk.Poly(body, list(w.outline)), w.source))
    for o in sc.obstacles:
        if o.motion is not None:
            continue
        key = f"{o.source} ({o.id})"
        if o.shape == "disc":
            assert o.center is not None and o.radius is not None
            out.append((pymunk.Circle(body, o.radius, offset=o.center), key))
        else:
            for part in o.parts:
                out.append((pymunk.Poly(body, list(part)), key))
    for s, _ in out:
        s.filter = pymunk.ShapeFilter(categories=CAT_STATIC, mask=MASK_ALL)
        s.collision_type = CT_STATIC
        s.friction = FRICTION_STATIC
        s.elasticity = 0.0
    return out


def moving_obstacle_shapes(body: pymunk.Body, o: ObstacleSpec) -> list[pymunk.Shape]:
    """Shapes of a moving obstacle, local to its (kinematic) body."""
    if o.shape == "disc":
        assert o.radius is not None
        shapes: list[pymunk.Shape] = [pymunk.Circle(body, o.radius)]
    else:
        shapes = [pymunk.Poly(body, list(part)) for part in o.parts]
    for s in shapes:
        s.filter = pymunk.ShapeFilter(categories=CAT_MOVING, mask=MASK_ALL)
        s.collision_type = CT_MOVING
        s.friction = FRICTION_STATIC
        s.elasticity = 0.0
    return shapes


def add_static(space: pymunk.Space, sc: Scenario) -> dict[pymunk.Shape, str]:
    """Add walls and static obstacles to ``space``; returns shape -> item key."""
    pairs = _static_shapes(space.static_body, sc)
    space.add(*(s for s, _ in pairs))
    return {s: k for s, k in pairs}


class StaticIndex:
    """Nearest-item queries against walls, static obstacles and moving obstacles at
    t = 0 (used to refuse scenarios whose robots start inside something)."""

    def __init__(self, sc: Scenario) -> None:
        self.space = pymunk.Space()
        self.keys = add_static(self.space, sc)
        for o in sc.obstacles:
            if o.motion is None:
                continue
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position = o.motion.position(0.0)
            shapes = moving_obstacle_shapes(body, o)
            self.space.add(body, *shapes)
            for s in shapes:
                self.keys[s] = f"{o.source} ({o.id}) at t = 0"
        self.space.step(1e-9)  # let the spatial index see the kinematic shapes

    def nearest(self, x: float, y: float) -> tuple[float, str] | None:
        """(distance from (x, y) to the nearest surface, negative inside; item key)."""
        q = self.space.point_query_nearest((x, y), math.inf, pymunk.ShapeFilter())
        if q is None or q.shape is None:
            return None
        return q.distance, self.keys[q.shape]


def add_robots(space: pymunk.Space, scenario: Scenario, item_of: dict[Any, str], mass: float, radius: float,
               traction_force: float,
               traction_torque: float) -> tuple[list[pymunk.Body], list[pymunk.Circle], list[pymunk.Body]]:
    """Each robot a dynamic circle driven through a kinematic control body joined by a
    ``PivotJoint`` (max_bias 0, finite max_force) and a ``GearJoint`` (pymunk's tank
    pattern): (robot bodies, their shapes, their control bodies), in scenario order."""
    bodies, shapes, controls = [], [], []
    moment = pymunk.moment_for_circle(mass, 0.0, radius)
    for i, r in enumerate(scenario.robots):
        b = pymunk.Body(mass, moment)
        b.position = (r.start[0], r.start[1])
        b.angle = r.start[2]
        s = pymunk.Circle(b, radius)
        s.filter = pymunk.ShapeFilter(group=i + 1, categories=CAT_ROBOT, mask=MASK_ALL)
        s.collision_type = CT_ROBOT
        s.friction = FRICTION_ROBOT
        s.elasticity = 0.0
        space.add(b, s)
        bodies.append(b)
        shapes.append(s)
        item_of[s] = f"robot {r.id}"
    for b in bodies:
        c = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        c.position = b.position
        c.angle = b.angle
        pivot = pymunk.PivotJoint(c, b, (0.0, 0.0), (0.0, 0.0))
        pivot.max_bias = 0.0
        pivot.max_force = traction_force
        gear = pymunk.GearJoint(c, b, 0.0, 1.0)
        gear.max_bias = 0.0
        gear.max_force = traction_torque
        space.add(c, pivot, gear)
        controls.append(c)
    return bodies, shapes, controls
