"""The scenario loader's field-by-field validation (:func:`world.scenario.parse_scenario`):
every refusal is a :class:`~world.scenario.ScenarioError` naming the file, the field path
(``obstacles[1].motion.radius``) and what is wrong."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NoReturn, get_args

from cekm_swarm.protocol.errors import KeySpaceError
from cekm_swarm.protocol.keys import validate_robot_id
from cekm_swarm.protocol.schema import EntryId, TargetId

from . import geometry as geo
from ._physics import StaticIndex
from .motion import CircleMotion, Fixed, LineMotion, Motion, RandomWalk, ScriptedMotion
from .scenario_spec import (
    BODY_RADIUS,
    DEFAULT_SENSOR_RANGE,
    DEFAULT_SPEED_UNIT,
    DEFAULT_WALL_THICKNESS,
    ID_RE,
    RANDOM_WALK_INSET,
    ObstacleSpec,
    Point,
    RobotSpec,
    Scenario,
    ScenarioError,
    TargetSpec,
    WallSpec,
)

# ------------------------------------------------------------------ validation


def _max_length(id_type: Any) -> int:
    """The longest string the protocol's id type takes (its one declaration, protocol.schema)."""
    return next(a.max_length for a in get_args(id_type)[1:] if getattr(a, "max_length", None) is not None)


class Parser:
    """Validates a parsed scenario document field by field; every refusal names the file and the field path."""

    def __init__(self, source: str) -> None:
        self.file = source

    # -- primitives -------------------------------------------------------------
    def fail(self, path: str, msg: str) -> NoReturn:
        raise ScenarioError(f"{self.file}: {path}: {msg}")

    def table(self, v: Any, path: str, required: tuple[str, ...], optional: tuple[str, ...]) -> dict[str, Any]:
        if not isinstance(v, dict):
            self.fail(path, f"must be a table, got {_tname(v)}")
        for k in v:
            if k not in required and k not in optional:
                allowed = ", ".join(sorted(set(required + optional)))
                self.fail(_join(path, k), f"unknown key (allowed here: {allowed})")
        for k in required:
            if k not in v:
                self.fail(_join(path, k), "missing (required)")
        return v

    def number(
        self,
        v: Any,
        path: str,
        *,
        gt: float | None = None,
        ge: float | None = None,
        lt: float | None = None,
        le: float | None = None,
        allow_inf: bool = False,
    ) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(path, f"must be a number, got {_tname(v)}")
        x = float(v)
        if math.isnan(x):
            self.fail(path, "must be a number, got nan")
        if math.isinf(x) and not (allow_inf and x > 0):
            self.fail(path, "must be finite" if not allow_inf else "must be finite or +inf")
        if gt is not None and not x > gt:
            self.fail(path, f"out of range: {x} (must be > {gt})")
        if ge is not None and not x >= ge:
            self.fail(path, f"out of range: {x} (must be >= {ge})")
        if lt is not None and not x < lt:
            self.fail(path, f"out of range: {x} (must be < {lt})")
        if le is not None and not x <= le:
            self.fail(path, f"out of range: {x} (must be <= {le})")
        return x

    def integer(self, v: Any, path: str, *, ge: int | None = None) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(path, f"must be an integer, got {_tname(v)}")
        if ge is not None and v < ge:
            self.fail(path, f"out of range: {v} (must be >= {ge})")
        return int(v)

    def boolean(self, v: Any, path: str) -> bool:
        if not isinstance(v, bool):
            self.fail(path, f"must be true or false, got {_tname(v)}")
        return v

    def string(self, v: Any, path: str) -> str:
        if not isinstance(v, str):
            self.fail(path, f"must be a string, got {_tname(v)}")
        return v

    def ident(self, v: Any, path: str, max_length: int | None = None) -> str:
        s = self.string(v, path)
        if not ID_RE.match(s):
            self.fail(path, f"invalid id {s!r} (letters, digits, '_' and '-' only)")
        if max_length is not None and len(s) > max_length:
            self.fail(path, f"id of {len(s)} characters: at most {max_length} (it travels in the run's messages)")
        return s

    def robot_id(self, v: Any, path: str) -> str:
        """A robot id as the key space takes it (a Zenoh key segment of every key of the robot)."""
        s = self.ident(v, path)
        try:
            return validate_robot_id(s)
        except KeySpaceError as exc:
            self.fail(path, f"{exc.problem} (it names the robot's keys)")

    def enum(self, v: Any, path: str, choices: tuple[str, ...]) -> str:
        s = self.string(v, path)
        if s not in choices:
            self.fail(path, f"unknown value {s!r} (expected one of: {', '.join(choices)})")
        return s

    def vector(self, v: Any, path: str, n: int, what: str) -> tuple[float, ...]:
        if not isinstance(v, list):
            self.fail(path, f"must be an array {what}, got {_tname(v)}")
        if len(v) != n:
            self.fail(path, f"must have {n} numbers {what}, got {len(v)}")
        return tuple(self.number(x, f"{path}[{i}]") for i, x in enumerate(v))

    def point(self, v: Any, path: str) -> Point:
        x, y = self.vector(v, path, 2, "[x, y]")
        return (x, y)

    def items(self, v: Any, path: str) -> list[Any]:
        if not isinstance(v, list):
            self.fail(path, f"must be an array of tables ([[{path}]]), got {_tname(v)}")
        return v

    # -- document --------------------------------------------------------------------
    def scenario(self, raw: Mapping[str, Any], default_name: str) -> Scenario:
        doc = self.table(
            dict(raw),
            "",
            ("arena", "robots"),
            ("name", "description", "seed", "plan_checkpoints", "retarget", "explore", "sensors", "plant", "targets",
             "walls", "obstacles"),
        )
        name = self.string(doc.get("name", default_name), "name")
        description = self.string(doc.get("description", ""), "description")
        seed = self.integer(doc.get("seed", 0), "seed", ge=0)
        plan, retarget, explore = (self.boolean(doc.get(k, False), k)
                                   for k in ("plan_checkpoints", "retarget", "explore"))
        if explore and not retarget:
            self.fail("explore", "training exploration noise needs retarget = true (section 4.1's training)")
        bounds, boundary, wall_t = self.arena(doc["arena"])

        sensors = self.table(doc.get("sensors", {}), "sensors", (), ("range", "target_range"))
        sensor_range = self.number(sensors.get("range", DEFAULT_SENSOR_RANGE), "sensors.range", gt=0.0, le=5.0)
        target_range = self.number(
            sensors.get("target_range", math.inf), "sensors.target_range", gt=0.0, allow_inf=True
        )

        plant = self.table(doc.get("plant", {}), "plant", (), ("speed_unit",))
        speed_unit = self.number(plant.get("speed_unit", DEFAULT_SPEED_UNIT), "plant.speed_unit", ge=0.0, le=0.05)

        ids: dict[str, str] = {}

        def claim(ident: str, path: str) -> None:
            if ident in ids:
                self.fail(path, f"duplicate id {ident!r} (already used by {ids[ident]})")
            ids[ident] = path.rsplit(".", 1)[0]

        robots = self.robots(doc["robots"], bounds, claim)
        targets = [self.target(tr, f"targets[{i}]", bounds, claim)
                   for i, tr in enumerate(self.items(doc.get("targets", []), "targets"))]
        for i, r in enumerate(robots):
            if r.goal is not None and not any(tg.id == r.goal for tg in targets):
                known = ", ".join(tg.id for tg in targets) or "none"
                self.fail(f"robots[{i}].goal", f"unknown target id {r.goal!r} (targets: {known})")
        walls = _boundary_walls(bounds, wall_t) if boundary else []
        walls += [self.wall(w, f"walls[{i}]", wall_t) for i, w in enumerate(self.items(doc.get("walls", []), "walls"))]
        obstacles = [self.obstacle(o, f"obstacles[{i}]", i, claim, bounds)
                     for i, o in enumerate(self.items(doc.get("obstacles", []), "obstacles"))]

        sc = Scenario(
            name=name,
            description=description,
            source=self.file,
            seed=seed,
            bounds=(bounds[0], bounds[1], bounds[2], bounds[3]),
            boundary_walls=boundary,
            wall_thickness=wall_t,
            sensor_range=sensor_range,
            target_range=target_range,
            robots=tuple(robots),
            walls=tuple(walls),
            obstacles=tuple(obstacles),
            targets=tuple(targets),
            speed_unit=speed_unit,
            plan_checkpoints=plan, retarget=retarget, explore=explore,
        )
        self.check_outside(sc)
        self.check_overlaps(sc)
        return sc

    def arena(self, a: Any) -> tuple[tuple[float, ...], bool, float]:
        """``[arena]``: its bounds, whether it has boundary walls, and their thickness."""
        arena = self.table(a, "arena", ("bounds",), ("boundary_walls", "wall_thickness"))
        bounds = self.vector(arena["bounds"], "arena.bounds", 4, "[xmin, ymin, xmax, ymax]")
        if not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
            self.fail("arena.bounds", f"must satisfy xmin < xmax and ymin < ymax, got {list(bounds)}")
        boundary = self.boolean(arena.get("boundary_walls", True), "arena.boundary_walls")
        wall_t = self.number(arena.get("wall_thickness", DEFAULT_WALL_THICKNESS), "arena.wall_thickness",
                             gt=0.0, le=1.0)
        return bounds, boundary, wall_t

    def robots(self, raw: Any, bounds: tuple[float, ...], claim: Any) -> list[RobotSpec]:
        """``[[robots]]``: at least one, each inside the arena with its whole body."""
        robots_raw = self.items(raw, "robots")
        if not robots_raw:
            self.fail("robots", "at least one robot is required")
        robots: list[RobotSpec] = []
        for i, r in enumerate(robots_raw):
            p = f"robots[{i}]"
            t = self.table(r, p, ("id", "start"), ("goal",))
            rid = self.robot_id(t["id"], f"{p}.id")
            claim(rid, f"{p}.id")
            start = self.vector(t["start"], f"{p}.start", 3, "[x, y, theta]")
            goal = self.ident(t["goal"], f"{p}.goal") if "goal" in t else None
            if not _inside(bounds, start[0], start[1], 0.0):
                self.fail(f"{p}.start", f"robot at ({start[0]}, {start[1]}) is not inside arena.bounds {list(bounds)}")
            if not _inside(bounds, start[0], start[1], BODY_RADIUS):
                self.fail(f"{p}.start", f"robot at ({start[0]}, {start[1]}) with body radius {BODY_RADIUS} m reaches "
                          f"outside arena.bounds {list(bounds)} (its centre must be at least {BODY_RADIUS} m inside)")
            robots.append(RobotSpec(rid, (start[0], start[1], start[2]), goal))
        return robots

    def target(self, tr: Any, p: str, bounds: tuple[float, ...], claim: Any) -> TargetSpec:
        """One ``[[targets]]``: a fixed or random-walk target at its ``position``, a circling
        or line target where its motion puts it at t = 0."""
        t = self.table(tr, p, ("id",), ("position", "motion"))
        tid = self.ident(t["id"], f"{p}.id", _max_length(TargetId))
        claim(tid, f"{p}.id")
        motion = self.motion(
            t.get("motion", {"type": "fixed"}), f"{p}.motion", ("fixed", "circle", "line", "random_walk"), bounds
        )
        if isinstance(motion, (Fixed, RandomWalk)):
            if "position" not in t:
                self.fail(f"{p}.position", f"missing (required for a {motion.kind} target)")
            pos = self.point(t["position"], f"{p}.position")
            if not _inside(bounds, pos[0], pos[1], 0.0):
                self.fail(f"{p}.position", f"{list(pos)} is not inside arena.bounds {list(bounds)}")
            if isinstance(motion, RandomWalk) and not _inside(motion.bounds, pos[0], pos[1], 0.0):
                self.fail(f"{p}.position", f"{list(pos)} is not inside motion.bounds {list(motion.bounds)}")
        else:
            if "position" in t:
                self.fail(f"{p}.position", f"must not be given for a {motion.kind} target (the motion sets it)")
            pos = motion.position(0.0)
        return TargetSpec(tid, pos, motion, p)

    def wall(self, w: Any, p: str, wall_t: float) -> WallSpec:
        """One ``[[walls]]``: a segment a-b of ``thickness`` (the arena's by default)."""
        t = self.table(w, p, ("a", "b"), ("thickness", "known"))
        a = self.point(t["a"], f"{p}.a")
        b = self.point(t["b"], f"{p}.b")
        if math.hypot(b[0] - a[0], b[1] - a[1]) < 1e-6:
            self.fail(f"{p}.b", "must differ from a (zero-length wall)")
        th = self.number(t.get("thickness", wall_t), f"{p}.thickness", gt=0.0, le=1.0)
        known = self.boolean(t.get("known", True), f"{p}.known")
        return WallSpec(a, b, th, known, p, tuple(geo.wall_outline(a, b, th)))

    def obstacle(self, o: Any, p: str, index: int, claim: Any, bounds: tuple[float, ...]) -> ObstacleSpec:
        shape, t = self.obstacle_table(o, p)
        moving = "motion" in t
        oid = self.ident(t["id"], f"{p}.id", _max_length(EntryId)) if "id" in t else f"o{index + 1}"
        claim(oid, f"{p}.id")
        known = self.boolean(t.get("known", False), f"{p}.known")
        motion: ScriptedMotion | None = None
        if moving:
            if shape in ("polygon", "concave"):
                self.fail(f"{p}.motion", f"a {shape} obstacle cannot move (moving obstacles are disc or box)")
            if "center" in t:
                self.fail(f"{p}.center", "must not be given for a moving obstacle (the motion sets it)")
            if known:
                self.fail(f"{p}.known", "a moving obstacle cannot be known (planners use static items only)")
            m = self.motion(t["motion"], f"{p}.motion", ("circle", "line"), bounds)
            assert isinstance(m, (CircleMotion, LineMotion))
            motion = m
        params: dict[str, Any] = {}
        radius: float | None = None
        center: Point | None = None
        outline: list[Point] | None = None
        parts: list[list[Point]] = []
        if shape == "disc":
            radius = self.number(t["radius"], f"{p}.radius", gt=0.0, le=10.0)
            params["radius"] = radius
            if not moving:
                center = self.point(t["center"], f"{p}.center")
        elif shape == "box":
            center, outline = self.box(t, p, moving, params)
            parts = [outline]
        elif shape == "polygon":
            outline, parts = self.polygon(t, p, params)
        else:  # concave
            center, outline, parts = self.concave(t, p, params)
        if center is not None:
            params["center"] = list(center)
        return ObstacleSpec(
            id=oid,
            shape=shape,
            known=known,
            source=p,
            params=params,
            radius=radius,
            center=center,
            outline=tuple(outline) if outline is not None else None,
            parts=tuple(tuple(q) for q in parts),
            motion=motion,
        )

    def obstacle_table(self, o: Any, p: str) -> tuple[str, dict[str, Any]]:
        """An obstacle's shape and its table, with the keys that shape takes (a static disc
        or box needs its ``center``; a moving one's motion sets it)."""
        if not isinstance(o, dict):
            self.fail(p, f"must be a table, got {_tname(o)}")
        if "shape" not in o:
            self.fail(f"{p}.shape", "missing (required; one of: disc, box, polygon, concave)")
        shape = self.enum(o["shape"], f"{p}.shape", ("disc", "box", "polygon", "concave"))
        common = ("shape", "id", "known", "motion")
        req, opt = {
            "disc": (("radius",), ("center",)),
            "box": (("size",), ("center", "angle")),
            "polygon": (("vertices",), ()),
            "concave": (("center", "width", "depth"), ("thickness", "facing")),
        }[shape]
        if "motion" not in o and shape in ("disc", "box"):
            req = req + ("center",)
            opt = tuple(k for k in opt if k != "center")
        return shape, self.table(o, p, req + ("shape",), opt + common)

    def box(self, t: dict[str, Any], p: str, moving: bool, params: dict[str, Any]) -> tuple[Point | None, list[Point]]:
        """A box's centre (None when it moves) and outline (local to its path when it moves)."""
        size = self.vector(t["size"], f"{p}.size", 2, "[width, height]")
        for k, s in enumerate(size):
            if not s > 0:
                self.fail(f"{p}.size[{k}]", f"out of range: {s} (must be > 0)")
        angle = self.number(t.get("angle", 0.0), f"{p}.angle")
        params.update(size=list(size), angle=angle)
        local = geo.box_local(size[0], size[1])
        if moving:
            return None, geo.transform(local, (0.0, 0.0), angle)
        center = self.point(t["center"], f"{p}.center")
        return center, geo.transform(local, center, angle)

    def polygon(self, t: dict[str, Any], p: str, params: dict[str, Any]) -> tuple[list[Point], list[list[Point]]]:
        """A simple polygon's outline (counter-clockwise) and its convex parts."""
        vs = t["vertices"]
        if not isinstance(vs, list):
            self.fail(f"{p}.vertices", f"must be an array of [x, y] points, got {_tname(vs)}")
        verts = [self.point(v, f"{p}.vertices[{k}]") for k, v in enumerate(vs)]
        problem = geo.simple_polygon_problem(verts)
        if problem:
            self.fail(f"{p}.vertices", f"not a valid polygon: {problem}")
        outline = geo.ccw(verts)
        params["vertices"] = [list(v) for v in verts]
        return outline, geo.convex_parts(outline)

    def concave(self, t: dict[str, Any], p: str,
                params: dict[str, Any]) -> tuple[Point, list[Point], list[list[Point]]]:
        """A U-shaped obstacle's centre, outline and convex parts."""
        center = self.point(t["center"], f"{p}.center")
        width = self.number(t["width"], f"{p}.width", gt=0.0, le=50.0)
        depth = self.number(t["depth"], f"{p}.depth", gt=0.0, le=50.0)
        th = self.number(t.get("thickness", DEFAULT_WALL_THICKNESS), f"{p}.thickness", gt=0.0, le=1.0)
        facing = self.number(t.get("facing", 0.0), f"{p}.facing")
        params.update(width=width, depth=depth, thickness=th, facing=facing)
        lo, lp = geo.concave_local(width, depth, th)
        return center, geo.transform(lo, center, facing), [geo.ccw(geo.transform(q, center, facing)) for q in lp]

    def motion(self, m: Any, p: str, kinds: tuple[str, ...], bounds: tuple[float, ...]) -> Motion:
        if not isinstance(m, dict):
            self.fail(p, f"must be a table, got {_tname(m)}")
        if "type" not in m:
            self.fail(f"{p}.type", f"missing (required; one of: {', '.join(kinds)})")
        kind = self.enum(m["type"], f"{p}.type", kinds)
        if kind == "fixed":
            self.table(m, p, ("type",), ())
            return Fixed()
        if kind == "circle":
            t = self.table(m, p, ("type", "center", "radius", "angular_speed"), ("phase", "direction"))
            return CircleMotion(
                center=self.point(t["center"], f"{p}.center"),
                radius=self.number(t["radius"], f"{p}.radius", gt=0.0, le=100.0),
                angular_speed=self.number(t["angular_speed"], f"{p}.angular_speed", ge=0.0, le=100.0),
                phase=self.number(t.get("phase", 0.0), f"{p}.phase"),
                direction=self.enum(t.get("direction", "ccw"), f"{p}.direction", ("ccw", "cw")),
            )
        if kind == "line":
            t = self.table(m, p, ("type", "a", "b", "speed"), ("phase",))
            a = self.point(t["a"], f"{p}.a")
            b = self.point(t["b"], f"{p}.b")
            if math.hypot(b[0] - a[0], b[1] - a[1]) < 1e-6:
                self.fail(f"{p}.b", "must differ from a")
            return LineMotion(
                a=a,
                b=b,
                speed=self.number(t["speed"], f"{p}.speed", gt=0.0, le=100.0),
                phase=self.number(t.get("phase", 0.0), f"{p}.phase", ge=0.0, lt=1.0),
            )
        t = self.table(m, p, ("type", "speed"), ("turn_noise", "heading", "bounds"))
        d = RANDOM_WALK_INSET
        default_bounds = [bounds[0] + d, bounds[1] + d, bounds[2] - d, bounds[3] - d]
        if "bounds" in t:
            wb = self.vector(t["bounds"], f"{p}.bounds", 4, "[xmin, ymin, xmax, ymax]")
            path_b = f"{p}.bounds"
        else:
            wb = tuple(default_bounds)
            path_b = "arena.bounds"
        if not (wb[0] < wb[2] and wb[1] < wb[3]):
            self.fail(path_b, f"random-walk bounds must satisfy xmin < xmax and ymin < ymax, got {list(wb)}")
        if not (bounds[0] <= wb[0] and bounds[1] <= wb[1] and wb[2] <= bounds[2] and wb[3] <= bounds[3]):
            self.fail(path_b, f"random-walk bounds {list(wb)} reach outside arena.bounds {list(bounds)}: the target "
                      "would walk out of the arena")
        return RandomWalk(
            speed=self.number(t["speed"], f"{p}.speed", ge=0.0, le=10.0),
            turn_noise=self.number(t.get("turn_noise", 0.0), f"{p}.turn_noise", ge=0.0, le=100.0),
            heading=self.number(t.get("heading", 0.0), f"{p}.heading"),
            bounds=(wb[0], wb[1], wb[2], wb[3]),
        )

    # -- geometric consistency -----------------------------------------------------------
    def check_outside(self, sc: Scenario) -> None:
        """A static wall or obstacle wholly outside the arena's bounds is a typo (it can meet
        nothing in the run): refused by its field."""
        x0, y0, x1, y1 = sc.bounds
        items = [(w.source, w.outline) for w in sc.walls if w.source.startswith("walls[")]
        for o in sc.obstacles:
            if o.motion is None:
                pts = o.outline or tuple(p for part in o.parts for p in part)
                if o.center is not None and o.radius is not None:
                    (cx, cy), rr = o.center, o.radius
                    pts = ((cx - rr, cy - rr), (cx + rr, cy + rr))
                items.append((o.source, pts))
        for where, pts in items:
            if pts and (max(p[0] for p in pts) < x0 or min(p[0] for p in pts) > x1
                        or max(p[1] for p in pts) < y0 or min(p[1] for p in pts) > y1):
                self.fail(where, f"lies wholly outside arena.bounds {list(sc.bounds)}: it can meet nothing")

    def check_overlaps(self, sc: Scenario) -> None:
        idx = StaticIndex(sc)
        r = BODY_RADIUS
        for i, rb in enumerate(sc.robots):
            x, y, _ = rb.start
            hit = idx.nearest(x, y)
            if hit is not None and hit[0] < r - 1e-9:  # touching is allowed
                self.fail(
                    f"robots[{i}].start",
                    f"robot body (radius {r} m) at ({x}, {y}) overlaps {hit[1]} "
                    + (f"(its centre is {-hit[0]:.4f} m inside it)" if hit[0] < 0 else
                       f"(its centre is {hit[0]:.4f} m from its surface, less than the radius)"),
                )
            for j in range(i):
                o = sc.robots[j]
                dist = math.hypot(o.start[0] - x, o.start[1] - y)
                if dist < 2 * r - 1e-9:
                    self.fail(f"robots[{i}].start", f"robot body overlaps robot {o.id!r} (centres {dist:.4f} m apart)")
        for tg in sc.targets:
            if isinstance(tg.motion, Fixed):
                hit = idx.nearest(*tg.position)
                if hit is not None and hit[0] < -1e-9:
                    self.fail(f"{tg.source}.position", f"target {list(tg.position)} is inside {hit[1]}")


def _boundary_walls(b: tuple[float, ...], t: float) -> list[WallSpec]:
    xmin, ymin, xmax, ymax = b
    h = 0.5 * t
    segs = [
        ((xmin - t, ymin - h), (xmax + t, ymin - h)),
        ((xmax + h, ymin - t), (xmax + h, ymax + t)),
        ((xmax + t, ymax + h), (xmin - t, ymax + h)),
        ((xmin - h, ymax + t), (xmin - h, ymin - t)),
    ]
    names = ("south", "east", "north", "west")
    return [
        WallSpec(a, bb, t, True, f"arena.boundary_walls ({n})", tuple(geo.wall_outline(a, bb, t)))
        for (a, bb), n in zip(segs, names, strict=True)
    ]


def _inside(b: tuple[float, ...], x: float, y: float, margin: float) -> bool:
    return b[0] + margin <= x <= b[2] - margin and b[1] + margin <= y <= b[3] - margin


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _tname(v: Any) -> str:
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, int):
        return "an integer"
    if isinstance(v, float):
        return "a float"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, list):
        return "an array"
    if isinstance(v, dict):
        return "a table"
    return type(v).__name__
