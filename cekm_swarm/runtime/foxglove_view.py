"""Foxglove view channels in the project's MCAP logs (Foxglove cannot decode msgpack).

Messages are built with the ``foxglove-sdk`` package's types
(``foxglove.messages.SceneUpdate(...).encode()`` gives protobuf bytes and
``SceneUpdate.get_schema()`` the official ``foxglove.SceneUpdate`` protobuf schema),
then written through :class:`~cekm_swarm.runtime.mcap_log.McapRecorder`, so one file
holds both the raw msgpack channels and these views.

Channels: ``/view/scene`` (SceneUpdate: walls, static and moving obstacles, targets,
robots with a heading arrow, a label and the trail of their path since its last path
message), ``/view/tf`` (FrameTransforms ``world`` -> each robot), ``/view/path/<robot>``
(PosesInFrame: the robot's path so far, at most every :data:`PATH_EVERY_S` s of sim time)
and, in a tracking run, ``/view/tracking`` (SceneUpdate: each robot's target sensing circle
and a line from it to every target it observes).

A path message holds the whole path (a view that seeks shows it at once), so sending it
at every tick cost bytes in proportion to the path: at 1,000 ticks it was the bulk of the
log and of the world server's CPU for the views (docs/performance.md, "Lockstep
tracking"). The scene's trail draws the rest of the path up to the robot's pose, so the
path in view is the same at every tick. What does not change between messages (colours,
sizes, the sensing circle's points about its centre) is built once.

Input is plain data in the shapes ``world.World.static_geometry()`` and
``world.World.state()`` return (this module does not import the world package).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from .mcap_log import SchemaSpec

try:  # optional dependency: foxglove-sdk
    import foxglove.messages as fm
except ImportError:  # pragma: no cover - exercised only where foxglove-sdk is missing
    fm = None  # type: ignore[assignment]  # foxglove-sdk missing: available() says so

SCENE_TOPIC = "/view/scene"
TF_TOPIC = "/view/tf"
PATH_TOPIC = "/view/path/{robot}"
TRACKING_TOPIC = "/view/tracking"
CIRCLE_POINTS = 48
_SENSING = (0.1, 0.55, 0.95, 0.5)
_OBSERVES = (0.95, 0.6, 0.1, 0.9)
WORLD_FRAME = "world"
PATH_STEP = 0.005
PATH_MAX = 2000
PATH_EVERY_S = 1.0
"""Sim seconds between two path messages of a robot (a full log); the scene's trail draws
the path since the last one."""

_WALL = (0.45, 0.45, 0.5, 1.0)
_KNOWN_OBSTACLE = (0.35, 0.35, 0.75, 0.9)
_UNKNOWN_OBSTACLE = (0.75, 0.35, 0.35, 0.9)
_ROBOT = (0.1, 0.55, 0.95, 1.0)
_TARGET = (0.95, 0.6, 0.1, 1.0)
_HEIGHT = 0.05


def available() -> bool:
    """True when the foxglove-sdk package is installed."""
    return fm is not None


def _need() -> Any:
    if fm is None:
        raise ImportError("Foxglove view channels need the foxglove-sdk package (pip install foxglove-sdk)")
    return fm


def _stamp(t: float) -> Any:
    ns = max(0, int(round(t * 1e9)))
    return fm.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def _color(c: Sequence[float]) -> Any:
    return fm.Color(r=c[0], g=c[1], b=c[2], a=c[3])


def _yaw(yaw: float) -> Any:
    return fm.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _pose(x: float, y: float, z: float = 0.0, yaw: float = 0.0) -> Any:
    return fm.Pose(position=fm.Vector3(x=x, y=y, z=z), orientation=_yaw(yaw))


def _schema(cls: Any) -> SchemaSpec:
    s = cls.get_schema()
    return SchemaSpec(s.name, s.encoding, bytes(s.data))


def _loop(points: Sequence[Sequence[float]], z: float, color: Sequence[float], thickness: float = 0.004) -> Any:
    pts = [fm.Point3(x=float(p[0]), y=float(p[1]), z=z) for p in points]
    return fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineLoop, pose=_pose(0, 0), thickness=thickness,
                            scale_invariant=False, points=pts, color=_color(color))


def _fill(parts: Sequence[Sequence[Sequence[float]]], z: float, color: Sequence[float]) -> Any:
    """Convex parts as one triangle list (fan triangulation of each part)."""
    pts = []
    for part in parts:
        for i in range(1, len(part) - 1):
            for p in (part[0], part[i], part[i + 1]):
                pts.append(fm.Point3(x=float(p[0]), y=float(p[1]), z=z))
    return fm.TriangleListPrimitive(pose=_pose(0, 0), points=pts, color=_color(color))


class ViewSink(Protocol):
    """Where the views go: a log (:class:`McapRecorder`, a log set's recorder) or a live
    Foxglove server's channels (``cekm view --foxglove``)."""

    def write_encoded(self, topic: str, message_encoding: str, schema: SchemaSpec, data: bytes,
                      sim_time: float, sticky: bool = False) -> None: ...


class FoxgloveViews:
    """Writes the view channels of one run into ``recorder``."""

    def __init__(self, recorder: ViewSink, *, robot_radius: float = 0.03,
                 path_every: float = PATH_EVERY_S) -> None:
        _need()
        self.path_every = path_every  # s of sim time between two path messages of a robot (0: whenever it moved)
        self._path_sent: dict[str, float] = {}
        self.recorder = recorder
        self.robot_radius = robot_radius
        self._scene = _schema(fm.SceneUpdate)
        self._tf = _schema(fm.FrameTransforms)
        self._poses = _schema(fm.PosesInFrame)
        self._moving: dict[str, Mapping[str, Any]] = {}
        # robot -> its path, each pose encoded once: a PosesInFrame is its header's bytes and
        # its poses' bytes one after another, so a path message is a join, not 2,000 objects
        # kept and encoded again per message; the same bytes
        self._paths: dict[str, list[bytes]] = {}
        # robot -> the last pose of its path (x, y, theta), all a step needs: keeping every
        # pose as floats too cost 144 bytes a pose, 2.3 MB at PATH_MAX for 8 robots, and
        # grew the world server for its first 10 minutes (docs/performance.md, "Long runs")
        self._path_last: dict[str, tuple[float, float, float]] = {}
        # robot -> the trail: its path's points since (and with) the last pose its last path
        # message holds, which the robot's scene entity draws up to where it is now
        self._trail: dict[str, list[Any]] = {}
        self._fixed: _Fixed | None = None
        self._circles: dict[float, list[Any]] = {}  # sensing radius -> the circle's points about its centre

    def _constants(self) -> _Fixed:
        if self._fixed is None or self._fixed.robot_radius != self.robot_radius:
            self._fixed = _Fixed(self.robot_radius)
        return self._fixed

    def _put(self, topic: str, schema: SchemaSpec, msg: Any, t: float, sticky: bool = False) -> None:
        """``sticky``: the static scene, which a log set writes again at the start of every file."""
        self.recorder.write_encoded(topic, "protobuf", schema, msg.encode(), t, sticky=sticky)

    def write_geometry(self, t: float, geometry: Mapping[str, Any]) -> None:
        """The static scene (walls, polygons, discs) once, as entities without lifetime."""
        ts = _stamp(t)
        entities = []
        for i, w in enumerate(geometry.get("walls", ())):
            (ax, ay), (bx, by) = w["a"], w["b"]
            th = float(w.get("thickness", 0.01))
            length = math.hypot(bx - ax, by - ay) + th
            cube = fm.CubePrimitive(pose=_pose((ax + bx) / 2, (ay + by) / 2, _HEIGHT / 2, math.atan2(by - ay, bx - ax)),
                                    size=fm.Vector3(x=length, y=th, z=_HEIGHT), color=_color(_WALL))
            entities.append(fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"wall/{i}", cubes=[cube]))
        for p in geometry.get("polygons", ()):
            color = _KNOWN_OBSTACLE if p.get("known", True) else _UNKNOWN_OBSTACLE
            parts = p.get("parts") or [p["vertices"]]
            entities.append(fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"obstacle/{p['id']}",
                                           triangles=[_fill(parts, 0.001, color)],
                                           lines=[_loop(p["vertices"], 0.002, color)]))
        for d in geometry.get("discs", ()):
            color = _KNOWN_OBSTACLE if d.get("known", True) else _UNKNOWN_OBSTACLE
            r = float(d["radius"])
            cyl = fm.CylinderPrimitive(pose=_pose(d["center"][0], d["center"][1], _HEIGHT / 2),
                                       size=fm.Vector3(x=2 * r, y=2 * r, z=_HEIGHT), bottom_scale=1.0, top_scale=1.0,
                                       color=_color(color))
            entities.append(fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"obstacle/{d['id']}",
                                           cylinders=[cyl]))
        for m in geometry.get("moving_obstacles", ()):
            self._moving[str(m["id"])] = m
        self.robot_radius = float(geometry.get("body_radius", self.robot_radius))
        self._put(SCENE_TOPIC, self._scene, fm.SceneUpdate(entities=entities), t, sticky=True)

    def _path_step(self, rid: str, x: float, y: float, th: float) -> bool:
        """Extend the robot's path if it moved (>= PATH_STEP m or 0.2 rad); True if extended."""
        poses = self._paths.setdefault(rid, [])
        last = self._path_last.get(rid)
        if last is not None:
            lx, ly, lth = last
            if math.hypot(x - lx, y - ly) < PATH_STEP and abs(math.remainder(th - lth, math.tau)) < 0.2:
                return False
        self._path_last[rid] = (x, y, th)
        poses.append(fm.PosesInFrame(poses=[_pose(x, y, 0.0, th)]).encode())
        if len(poses) > PATH_MAX:  # thin the older half so messages stay bounded on long runs
            half = len(poses) // 2
            poses[:half] = poses[:half:2]
        return True

    def _path_due(self, rid: str, t: float) -> bool:
        if self.path_every <= 0:
            return True
        last = self._path_sent.get(rid)
        if last is not None and t - last < self.path_every - 1e-9:
            return False
        self._path_sent[rid] = t
        return True

    def _robot(self, c: _Fixed, ts: Any, t: float, rid: str, x: float, y: float, th: float) -> tuple[Any, Any]:
        """The robot's scene entity (body, heading, label, trail) and its transform; its path
        message when one is due."""
        r = self.robot_radius
        here = fm.Vector3(x=x, y=y, z=0.0)
        body = fm.CylinderPrimitive(pose=fm.Pose(position=fm.Vector3(x=x, y=y, z=_HEIGHT / 2), orientation=c.level),
                                    size=c.body, bottom_scale=1.0, top_scale=1.0, color=c.robot)
        heading = _yaw(th)
        arrow = fm.ArrowPrimitive(pose=fm.Pose(position=fm.Vector3(x=x, y=y, z=_HEIGHT + 0.005), orientation=heading),
                                  shaft_length=1.2 * r, shaft_diameter=0.2 * r, head_length=0.6 * r,
                                  head_diameter=0.5 * r, color=c.white)
        label = fm.TextPrimitive(pose=fm.Pose(position=fm.Vector3(x=x, y=y, z=_HEIGHT + 0.03), orientation=c.level),
                                 billboard=True, font_size=14.0, scale_invariant=True, color=c.white, text=rid)
        trail = self._trail.setdefault(rid, [])
        point = fm.Point3(x=x, y=y, z=0.0)
        if self._path_step(rid, x, y, th):
            if self._path_due(rid, t):
                head = fm.PosesInFrame(timestamp=ts, frame_id=WORLD_FRAME, poses=[]).encode()
                self.recorder.write_encoded(PATH_TOPIC.format(robot=rid), "protobuf", self._poses,
                                            head + b"".join(self._paths[rid]), t)
                trail[:] = [point]
            else:
                trail.append(point)
        lines = []
        if trail:  # the path since its last message, up to the robot
            lines.append(fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineStrip, pose=c.origin, thickness=0.004,
                                          scale_invariant=False, points=[*trail, point],
                                          color=c.robot))
        entity = fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"robot/{rid}", cylinders=[body],
                                arrows=[arrow], texts=[label], lines=lines)
        transform = fm.FrameTransform(timestamp=ts, parent_frame_id=WORLD_FRAME, child_frame_id=rid,
                                      translation=here, rotation=heading)
        return entity, transform

    def write_state(self, t: float, state: Mapping[str, Any]) -> None:
        """Robots, targets and moving obstacles at sim time ``t`` (a ``World.state()``-shaped
        map), the ``world`` -> robot transforms, and each robot's path so far."""
        ts = _stamp(t)
        c = self._constants()
        entities, transforms = [], []
        for rid, rs in state.get("robots", {}).items():
            entity, transform = self._robot(c, ts, t, str(rid), float(rs["x"]), float(rs["y"]), float(rs["theta"]))
            entities.append(entity)
            transforms.append(transform)
        for tid, tg in state.get("targets", {}).items():
            sphere = fm.SpherePrimitive(pose=fm.Pose(position=fm.Vector3(x=float(tg["x"]), y=float(tg["y"]), z=0.01),
                                                     orientation=c.level), size=c.target_size, color=c.target)
            entities.append(fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"target/{tid}", spheres=[sphere]))
        for oid, os_ in state.get("obstacles", {}).items():
            shape = self._moving.get(str(oid), {})
            x, y, th = float(os_["x"]), float(os_["y"]), float(os_.get("theta", 0.0))
            if shape.get("radius"):
                rr = float(shape["radius"])
                prim: dict[str, Any] = {"cylinders": [fm.CylinderPrimitive(pose=_pose(x, y, _HEIGHT / 2),
                                                           size=fm.Vector3(x=2 * rr, y=2 * rr, z=_HEIGHT),
                                                           bottom_scale=1.0, top_scale=1.0, color=c.unknown)]}
            elif shape.get("vertices"):
                cs, sn = math.cos(th), math.sin(th)
                pts = [(x + cs * px - sn * py, y + sn * px + cs * py) for px, py in shape["vertices"]]
                prim = {"lines": [_loop(pts, 0.002, _UNKNOWN_OBSTACLE)]}
            else:
                prim = {"spheres": [fm.SpherePrimitive(pose=_pose(x, y, 0.01), size=c.mover_size, color=c.unknown)]}
            entities.append(fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"obstacle/{oid}", **prim))
        self._put(SCENE_TOPIC, self._scene, fm.SceneUpdate(entities=entities), t, sticky=True)
        if transforms:
            self._put(TF_TOPIC, self._tf, fm.FrameTransforms(transforms=transforms), t)

    def _circle(self, radius: float) -> list[Any]:
        """The sensing circle's points about its centre (the entity's pose puts it at the robot)."""
        pts = self._circles.get(radius)
        if pts is None:
            step = 2 * math.pi / CIRCLE_POINTS
            pts = self._circles[radius] = [fm.Point3(x=radius * math.cos(k * step), y=radius * math.sin(k * step),
                                                     z=0.003) for k in range(CIRCLE_POINTS)]
        return pts

    def write_tracking(self, t: float, state: Mapping[str, Any], target_range: float,
                       observed_by: Mapping[str, Sequence[str]]) -> None:
        """Tracking (docs/tracking.md): each robot's target sensing circle (radius
        ``target_range``) and a line to every target it observes (``observed_by``:
        {target id: [robot ids]}, what :class:`world.tracking.ObservationMeter` returns)."""
        ts = _stamp(t)
        c = self._constants()
        robots = state.get("robots", {})
        targets = state.get("targets", {})
        seen: dict[str, list[str]] = {}
        for tid, who in observed_by.items():
            for rid in who:
                seen.setdefault(str(rid), []).append(str(tid))
        circle = self._circle(float(target_range))
        entities = []
        for rid, rs in robots.items():
            x, y = float(rs["x"]), float(rs["y"])
            centre = fm.Pose(position=fm.Vector3(x=x, y=y, z=0.0), orientation=c.level)
            lines = [fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineLoop, pose=centre, thickness=0.003,
                                      scale_invariant=False, points=circle, color=c.sensing)]
            pts = []
            for tid in seen.get(str(rid), ()):
                tg = targets.get(tid)
                if tg is not None:
                    pts += [fm.Point3(x=x, y=y, z=0.004), fm.Point3(x=float(tg["x"]), y=float(tg["y"]), z=0.004)]
            if pts:
                lines.append(fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineList, pose=c.origin,
                                              thickness=0.004, scale_invariant=False, points=pts, color=c.observes))
            entities.append(fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id=f"sensing/{rid}", lines=lines))
        self._put(TRACKING_TOPIC, self._scene, fm.SceneUpdate(entities=entities), t)


class _Fixed:
    """The parts every view message shares, built once: foxglove-sdk's messages are
    immutable values, so one object serves every message that holds it."""

    def __init__(self, robot_radius: float) -> None:
        r = self.robot_radius = robot_radius
        self.level = fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        self.origin = _pose(0, 0)
        self.body = fm.Vector3(x=2 * r, y=2 * r, z=_HEIGHT)
        self.target_size = fm.Vector3(x=0.02, y=0.02, z=0.02)
        self.mover_size = fm.Vector3(x=0.03, y=0.03, z=0.03)
        self.robot, self.white, self.target = _color(_ROBOT), _color((1, 1, 1, 1)), _color(_TARGET)
        self.unknown, self.sensing, self.observes = _color(_UNKNOWN_OBSTACLE), _color(_SENSING), _color(_OBSERVES)
