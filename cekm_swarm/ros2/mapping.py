"""The mapping of the project's keys to standard ROS 2 messages (docs/ros2.md has the table).

:class:`RosMapper` takes the protocol's decoded messages in the order they come (from a
log or live) and returns the ROS 2 messages they map to, each with its topic, type,
sim-time stamp and QoS. It is pure (no I/O): the bag export (:mod:`.bag`) and the live
bridge (:mod:`.bridge`) are both shells around it.

Conventions (REP 103, 105, 117): SI units, x forward and z up, yaw counter-clockwise;
frames ``map`` (the world frame), ``<robot>/base_link`` and ``<robot>/range_<j>``; topics
``/<robot>/...`` with the robot id (a ``-`` becomes ``_``, which a ROS name cannot
hold); every ``header.stamp`` is the message's sim time. The world state is ground truth,
so odometry is in ``map`` with zero covariance (covariance is not estimated).

EKM activities travel as ``std_msgs/msg/Float64MultiArray`` over the motor map's lattice:
neuron i = row * N + col (rows span distance, columns direction), layout dims
``[row (N, stride N*N), col (N, stride N)]``; a field the module did not compute (no
target, or a sensor that sees nothing) has no data and no dims. The motor activity is
e = a - sum_j b_j (Eq. 9; in tracking, a - b_teammates - sum_j b_j) over the latest fields
when the robot's wheel command comes, and ``winners`` holds s (the target field's winner),
k = argmax e (Eq. 10) and each obstacle field's winner, -1 where there is none.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from cekm_swarm.protocol import (
    DEFAULT_KEYS,
    Clock,
    DropCounter,
    KeyKind,
    KeySpace,
    KeySpaceError,
    Message,
    ObstacleField,
    SenseRange,
    TargetField,
    TrackingField,
    Unchanged,
    WheelCommand,
    WorldState,
    with_stamp,
)
from cekm_swarm.robot import KHEPERA, Khepera

from .interfaces import Interfaces
from .wire import Qos

MAP_FRAME = "map"
ODOMETRY = "nav_msgs/msg/Odometry"
TWIST = "geometry_msgs/msg/Twist"
RANGE = "sensor_msgs/msg/Range"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
FLOAT_ARRAY = "std_msgs/msg/Float64MultiArray"
INT_ARRAY = "std_msgs/msg/Int32MultiArray"
CLOCK = "rosgraph_msgs/msg/Clock"

DEFAULT_QOS = Qos()
"""Reliable, volatile, keep the last 10: ROS 2's default profile."""
LATCHED_QOS = Qos(transient_local=True, depth=1)
"""``/tf_static``'s profile: a late subscriber gets the last message."""

RANGE_TYPE_INFRARED = 1  # sensor_msgs/msg/Range.INFRARED: the Khepera's proximity sensors
SCENE_EVERY_S = 1.0
"""Sim seconds between two copies of the static scene on ``/world/markers`` (a viewer
that joins late, or a bag played from the middle, shows it within this time)."""
MARKER_HEIGHT = 0.05
LINE_WIDTH = 0.005
CIRCLE_POINTS = 48


@dataclass(frozen=True)
class Topic:
    """One row of the mapping: ROS topic (``{robot}``, ``{j}`` filled in), type, where it
    comes from and what it holds."""

    name: str
    ros_type: str
    source: str
    what: str
    qos: Qos = DEFAULT_QOS


TOPICS: tuple[Topic, ...] = (
    Topic("/{robot}/odom", ODOMETRY, "cekm/world/state",
          "pose in map (ground truth) and the executed wheel speeds as v, omega in base_link"),
    Topic("/tf", TF_MESSAGE, "cekm/world/state", "map -> <robot>/base_link for every robot"),
    Topic("/tf_static", TF_MESSAGE, "cekm/<robot>/sense/range/<j>",
          "<robot>/base_link -> <robot>/range_<j>: sensor j on the body surface, facing its direction",
          LATCHED_QOS),
    Topic("/{robot}/range_{j}", RANGE, "cekm/<robot>/sense/range/<j>",
          "distance from the body surface (d - body radius), +inf when nothing is in range"),
    Topic("/{robot}/cmd_vel_out", TWIST, "cekm/<robot>/cmd/wheels",
          "the wheel command as v = (v_l + v_r)/2, omega = (v_r - v_l)/axle"),
    Topic("/{robot}/wheel_speeds", FLOAT_ARRAY, "cekm/<robot>/cmd/wheels", "[v_l, v_r] in m/s, dim 'wheel'"),
    Topic("/{robot}/ekm/target_field", FLOAT_ARRAY, "cekm/<robot>/field/target", "the target field a (Eq. 5)"),
    Topic("/{robot}/ekm/tracking_field", FLOAT_ARRAY, "cekm/<robot>/field/tracking",
          "tracking: the weighted target fields a and teammate fields b, dims [field (2), row, col]"),
    Topic("/{robot}/ekm/obstacle_field_{j}", FLOAT_ARRAY, "cekm/<robot>/field/obstacle/<j>",
          "obstacle field b_j of sensor j (Eqs. 6-8)"),
    Topic("/{robot}/ekm/motor_activity", FLOAT_ARRAY, "fields + cekm/<robot>/cmd/wheels",
          "e = a - sum_j b_j (Eq. 9) at the wheel command"),
    Topic("/{robot}/ekm/winners", INT_ARRAY, "fields + cekm/<robot>/cmd/wheels",
          "[s, k = argmax e (Eq. 10), winner of obstacle field 0..11], -1 for none"),
    Topic("/world/markers", MARKER_ARRAY, "cekm/world/state + the run's geometry",
          "walls, fixed and moving obstacles, targets, robots with headings, target sensing circles"),
    Topic("/clock", CLOCK, "cekm/world/clock", "sim time (live bridge only: `ros2 bag play --clock` makes its own)"),
)


@dataclass(frozen=True)
class RosOut:
    """One ROS 2 message to publish or write: topic, type, the message, stamp (ns of sim time), QoS."""

    topic: str
    ros_type: str
    msg: Any
    stamp_ns: int
    qos: Qos = DEFAULT_QOS


def ros_name(robot: str) -> str:
    """A robot id as a ROS name token (robot ids may hold ``-``, ROS names may not)."""
    return robot.replace("-", "_")


def base_frame(robot: str) -> str:
    return f"{ros_name(robot)}/base_link"


def range_frame(robot: str, j: int) -> str:
    return f"{ros_name(robot)}/range_{j}"


def stamp_ns(t: float) -> int:
    """Sim time in s -> integer ns (stamps are finite and >= 0: the protocol checked them)."""
    return int(round(t * 1e9))


class RosMapper:
    """Maps the protocol's messages to ROS 2 messages (see the module's docstring).

    ``geometry`` is the run's static scene (``world.World.static_geometry()``: body and
    sensor range, walls, obstacles); None uses the Khepera's constants and draws no scene.
    ``robots`` limits the output to those robots (None: every robot). ``clock``: map
    ``cekm/world/clock`` to ``/clock`` (live; a bag player makes its own). What cannot be
    mapped is dropped and counted in ``drops``, per source key."""

    def __init__(self, ifc: Interfaces, *, geometry: Mapping[str, Any] | None = None,
                 robots: Collection[str] | None = None, clock: bool = False, keys: KeySpace = DEFAULT_KEYS,
                 robot: Khepera = KHEPERA, drops: DropCounter | None = None) -> None:
        self.ifc = ifc
        self.robot = robot
        self.axle = robot.axle
        self.set_geometry(geometry)
        self.robots = None if robots is None else frozenset(robots)
        self.clock = clock
        self.keys = keys
        self.drops = drops if drops is not None else DropCounter("ros2 mapping", keys=keys)
        self._sensors: dict[str, dict[int, float]] = {}  # robot -> sensor index -> direction (rad)
        self._target: dict[str, TargetField | TrackingField] = {}
        self._obstacles: dict[str, dict[int, ObstacleField]] = {}
        self._lattice: dict[str, int] = {}  # robot -> neurons of its motor map, once a field showed it
        self._ranges: dict[str, dict[int, SenseRange]] = {}  # robot -> sensor -> its latest reading

    def set_geometry(self, geometry: Mapping[str, Any] | None) -> None:
        """Take the run's static scene (when it comes later than the first messages)."""
        self.geometry = dict(geometry) if isinstance(geometry, Mapping) and geometry else None
        g = self.geometry or {}

        def number(name: str, default: float) -> float:
            v = g.get(name, default)
            return float(v) if type(v) in (int, float) and v > 0 else default

        self.radius = number("body_radius", self.robot.body_radius)
        self.sensor_range = number("sensor_range", self.robot.sensor_range)
        self.target_range = number("target_range", math.inf)
        moving = g.get("moving_obstacles", [])
        self._moving = {o["id"]: o for o in (moving if isinstance(moving, list) else [])
                        if isinstance(o, Mapping) and "id" in o}
        self._scene_at = -math.inf

    # ------------------------------------------------------------------ entry

    def feed(self, key: str, msg: Message) -> list[RosOut]:
        """The ROS 2 messages ``msg``, received on ``key``, maps to (often none)."""
        try:
            parsed = self.keys.parse(key)
        except KeySpaceError:
            return []
        robot = parsed.robot
        if robot is not None and self.robots is not None and robot not in self.robots:
            return []
        if isinstance(msg, WorldState):
            return self._world_state(msg)
        if isinstance(msg, SenseRange) and robot is not None:
            self._ranges.setdefault(robot, {})[msg.index] = msg
            return self._range(robot, msg)
        if isinstance(msg, Unchanged) and robot is not None:
            return self._unchanged(robot, msg)
        if isinstance(msg, WheelCommand) and robot is not None:
            return self._wheels(robot, msg)
        if isinstance(msg, (TargetField, TrackingField)) and robot is not None:
            self._target[robot] = msg
            return [self._target_field(robot, msg)]
        if isinstance(msg, ObstacleField) and robot is not None and parsed.kind is KeyKind.FIELD_OBSTACLE:
            self._obstacles.setdefault(robot, {})[msg.index] = msg
            t = f"/{ros_name(robot)}/ekm/obstacle_field_{msg.index}"
            return [RosOut(t, FLOAT_ARRAY, self._lattice_array(msg.b), stamp_ns(msg.stamp))]
        if isinstance(msg, Clock) and self.clock:
            return [RosOut("/clock", CLOCK, self.ifc.make(CLOCK, clock=self._time(msg.stamp)), stamp_ns(msg.stamp))]
        return []

    # ------------------------------------------------------------------ builders

    def _time(self, t: float) -> Any:
        ns = stamp_ns(t)
        return self.ifc.make("builtin_interfaces/msg/Time", sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def _header(self, t: float, frame: str) -> Any:
        return self.ifc.make("std_msgs/msg/Header", stamp=self._time(t), frame_id=frame)

    def _vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0, kind: str = "Vector3") -> Any:
        return self.ifc.make(f"geometry_msgs/msg/{kind}", x=x, y=y, z=z)

    def _yaw(self, yaw: float) -> Any:
        return self.ifc.make("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def _pose(self, x: float, y: float, z: float = 0.0, yaw: float = 0.0) -> Any:
        return self.ifc.make("geometry_msgs/msg/Pose", position=self._vector(x, y, z, "Point"),
                             orientation=self._yaw(yaw))

    def _twist(self, v: float, omega: float) -> Any:
        return self.ifc.make(TWIST, linear=self._vector(v), angular=self._vector(0.0, 0.0, omega))

    def _transform(self, t: float, parent: str, child: str, x: float, y: float, yaw: float) -> Any:
        tr = self.ifc.make("geometry_msgs/msg/Transform", translation=self._vector(x, y), rotation=self._yaw(yaw))
        return self.ifc.make("geometry_msgs/msg/TransformStamped", header=self._header(t, parent),
                             child_frame_id=child, transform=tr)

    def _array(self, values: Any, dims: list[tuple[str, int, int]], ros_type: str = FLOAT_ARRAY) -> Any:
        dtype = np.float64 if ros_type == FLOAT_ARRAY else np.int32
        layout = self.ifc.make("std_msgs/msg/MultiArrayLayout", data_offset=0, dim=[
            self.ifc.make("std_msgs/msg/MultiArrayDimension", label=label, size=size, stride=stride)
            for label, size, stride in dims])
        return self.ifc.make(ros_type, layout=layout, data=np.ascontiguousarray(values, dtype=dtype))

    def _lattice_array(self, *fields: np.ndarray | None) -> Any:
        """One or more fields over the lattice as one array (empty when the first is None)."""
        if fields[0] is None:
            return self._array(np.zeros(0), [])
        n = fields[0].shape[0]
        side = math.isqrt(n)
        dims = [("row", side, side * side), ("col", side, side)] if side * side == n else [("neuron", n, n)]
        if len(fields) > 1:
            dims = [("field", len(fields), len(fields) * n)] + dims
        return self._array(np.concatenate(cast("tuple[np.ndarray, ...]", fields)), dims)  # all given when the first is

    # ------------------------------------------------------------------ per key

    def _world_state(self, msg: WorldState) -> list[RosOut]:
        t = msg.stamp
        ns = stamp_ns(t)
        out, transforms, poses = [], [], {}
        for rid, r in msg.robots.items():
            if self.robots is not None and rid not in self.robots:
                continue
            x, y, th, v_l, v_r = r.x, r.y, r.theta, r.v_l_exec, r.v_r_exec  # typed and finite (protocol.messages)
            poses[rid] = (x, y, th)
            cov = np.zeros(36)
            odom = self.ifc.make(
                ODOMETRY, header=self._header(t, MAP_FRAME), child_frame_id=base_frame(rid),
                pose=self.ifc.make("geometry_msgs/msg/PoseWithCovariance", pose=self._pose(x, y, 0.0, th),
                                   covariance=cov),
                twist=self.ifc.make("geometry_msgs/msg/TwistWithCovariance",
                                    twist=self._twist((v_l + v_r) / 2, (v_r - v_l) / self.axle), covariance=cov))
            out.append(RosOut(f"/{ros_name(rid)}/odom", ODOMETRY, odom, ns))
            transforms.append(self._transform(t, MAP_FRAME, base_frame(rid), x, y, th))
        if transforms:
            out.append(RosOut("/tf", TF_MESSAGE, self.ifc.make(TF_MESSAGE, transforms=transforms), ns))
        if self.geometry is not None and t - self._scene_at >= SCENE_EVERY_S - 1e-9:
            self._scene_at = t
            try:
                scene = self._scene_markers(t)
                out.append(RosOut("/world/markers", MARKER_ARRAY, self.ifc.make(MARKER_ARRAY, markers=scene), ns))
            except (KeyError, TypeError, ValueError, IndexError) as exc:  # a geometry it cannot draw
                self.geometry = None
                self.drops.drop(self.keys.world_geometry(),
                                f"the run's geometry cannot be drawn ({exc!r}); no scene markers")
        try:
            markers = self._dynamic_markers(t, poses, msg)
        except (KeyError, TypeError, ValueError, IndexError) as exc:  # a moving obstacle's shape it cannot draw
            self.drops.drop(self.keys.world_state(), exc)
            markers = []
        if markers:
            out.append(RosOut("/world/markers", MARKER_ARRAY, self.ifc.make(MARKER_ARRAY, markers=markers), ns))
        return out

    def _unchanged(self, robot: str, msg: Unchanged) -> list[RosOut]:
        """Readings the world held this tick (docs/runtime.md, held readings): each range
        sensor's reading again at this tick, as the sensor measured it, and its obstacle
        field again, and for a held target reading the target field again (each the pure
        function of its reading in the cekm graphs), so a ROS 2 reader sees one Range per
        sensor per tick either way."""
        out: list[RosOut] = []
        head = "sense/range/"
        for key in msg.keys:
            if key == "sense/target" and robot in self._target:  # the target field again
                field = cast("TargetField | TrackingField", with_stamp(self._target[robot], msg.stamp))
                out.append(self._target_field(robot, field))
            if not key.startswith(head):
                continue
            j = int(key[len(head):])
            last = self._ranges.get(robot, {}).get(j)
            if last is not None:
                out += self._range(robot, cast(SenseRange, with_stamp(last, msg.stamp)))
            held = self._obstacles.get(robot, {}).get(j)
            if held is not None:
                t = f"/{ros_name(robot)}/ekm/obstacle_field_{j}"
                out.append(RosOut(t, FLOAT_ARRAY, self._lattice_array(held.b), stamp_ns(msg.stamp)))
        return out

    def _range(self, robot: str, msg: SenseRange) -> list[RosOut]:
        out = []
        sensors = self._sensors.setdefault(robot, {})
        if sensors.get(msg.index) != msg.alpha:  # a new sensor (or one that turned): the static frames again
            sensors[msg.index] = msg.alpha
            transforms = [self._transform(msg.stamp, base_frame(r), range_frame(r, j), self.radius * math.cos(a),
                                          self.radius * math.sin(a), a)
                          for r in sorted(self._sensors) for j, a in sorted(self._sensors[r].items())]
            out.append(RosOut("/tf_static", TF_MESSAGE, self.ifc.make(TF_MESSAGE, transforms=transforms),
                              stamp_ns(msg.stamp), LATCHED_QOS))
        surface = math.inf if msg.d is None else max(0.0, msg.d - self.radius)
        rng = self.ifc.make(RANGE, header=self._header(msg.stamp, range_frame(robot, msg.index)),
                            radiation_type=RANGE_TYPE_INFRARED, field_of_view=0.0, min_range=0.0,
                            max_range=self.sensor_range, range=surface, variance=0.0)
        out.append(RosOut(f"/{ros_name(robot)}/range_{msg.index}", RANGE, rng, stamp_ns(msg.stamp)))
        return out

    def _target_field(self, robot: str, msg: TargetField | TrackingField) -> RosOut:
        ns = stamp_ns(msg.stamp)
        if isinstance(msg, TrackingField):
            return RosOut(f"/{ros_name(robot)}/ekm/tracking_field", FLOAT_ARRAY, self._lattice_array(msg.a, msg.b), ns)
        return RosOut(f"/{ros_name(robot)}/ekm/target_field", FLOAT_ARRAY, self._lattice_array(msg.a), ns)

    def _wheels(self, robot: str, msg: WheelCommand) -> list[RosOut]:
        ns = stamp_ns(msg.stamp)
        name = ros_name(robot)
        twist = self._twist((msg.v_l + msg.v_r) / 2, (msg.v_r - msg.v_l) / self.axle)
        out = [RosOut(f"/{name}/cmd_vel_out", TWIST, twist, ns),
               RosOut(f"/{name}/wheel_speeds", FLOAT_ARRAY, self._array([msg.v_l, msg.v_r], [("wheel", 2, 2)]), ns)]
        activity = self.motor_activity(robot, msg.stamp)
        if activity is not None:
            e, winners = activity
            out.append(RosOut(f"/{name}/ekm/motor_activity", FLOAT_ARRAY, self._lattice_array(e), ns))
            out.append(RosOut(f"/{name}/ekm/winners", INT_ARRAY,
                              self._array(winners, [("winner", len(winners), len(winners))], INT_ARRAY), ns))
        return out

    def motor_activity(self, robot: str, t: float) -> tuple[np.ndarray, list[int]] | None:
        """(e, winners) for ``robot`` at sim time ``t`` from its latest fields stamped at or
        before ``t``: the target (or tracking) field and the obstacle fields of the newest
        range tick (e is zero where no field holds values); None before any field showed
        the lattice's size."""
        tf = self._target.get(robot)
        tf = tf if tf is not None and tf.stamp <= t else None
        obstacles = [f for f in self._obstacles.get(robot, {}).values() if f.stamp <= t]
        newest = max((f.stamp for f in obstacles), default=None)
        obstacles = [f for f in obstacles if f.stamp == newest]
        sizes = {a.shape[0] for a in ([tf.a] if tf is not None and tf.a is not None else [])
                 + [f.b for f in obstacles if f.b is not None]}
        if not sizes and robot in self._lattice:  # no field holds values now: e is zero everywhere
            sizes = {self._lattice[robot]}
        if len(sizes) != 1:  # no field of known size yet, or fields of different lattices
            return None
        (n,) = sizes
        self._lattice[robot] = n
        e = np.zeros(n)
        if tf is not None and tf.a is not None:
            e += tf.a
            if isinstance(tf, TrackingField):
                e -= tf.b
        for f in obstacles:
            if f.b is not None:
                e -= f.b  # Eq. 9
        s = tf.winner if isinstance(tf, TargetField) and tf.winner is not None else -1
        k = int(np.argmax(e)) if tf is not None and tf.a is not None else -1  # Eq. 10
        by_index = {f.index: f.winner for f in obstacles}
        sensors = max([len(self._sensors.get(robot, {})), self.keys.range_sensors])
        winners = [s, k] + [(-1 if (w := by_index.get(j)) is None else int(w)) for j in range(sensors)]
        return e, winners

    # ------------------------------------------------------------------ markers

    def _marker(self, t: float, ns: str, mid: int, kind: int, pose: Any, scale: tuple[float, float, float],
                color: tuple[float, float, float, float], points: Sequence[tuple[float, float]] = ()) -> Any:
        return self.ifc.make(
            "visualization_msgs/msg/Marker", header=self._header(t, MAP_FRAME), ns=ns, id=mid, type=kind, action=0,
            pose=pose, scale=self._vector(*scale),
            color=self.ifc.make("std_msgs/msg/ColorRGBA", r=color[0], g=color[1], b=color[2], a=color[3]),
            points=[self._vector(x, y, 0.0, "Point") for x, y in points])

    def _outline(self, t: float, ns: str, mid: int, vertices: list[Any],
                 color: tuple[float, float, float, float]) -> Any:
        pts = [(float(v[0]), float(v[1])) for v in vertices]
        return self._marker(t, ns, mid, 4, self._pose(0.0, 0.0), (LINE_WIDTH, 0.0, 0.0), color, pts + pts[:1])

    def _circle(self, t: float, ns: str, mid: int, cx: float, cy: float, r: float,
                color: tuple[float, float, float, float]) -> Any:
        pts = [(cx + r * math.cos(2 * math.pi * i / CIRCLE_POINTS), cy + r * math.sin(2 * math.pi * i / CIRCLE_POINTS))
               for i in range(CIRCLE_POINTS)]
        return self._marker(t, ns, mid, 4, self._pose(0.0, 0.0), (LINE_WIDTH, 0.0, 0.0), color, pts + pts[:1])

    def _scene_markers(self, t: float) -> list[Any]:
        """Walls, static polygons and discs from the run's geometry (LINE_STRIP outlines, cylinders)."""
        g = self.geometry or {}
        out = []
        for i, w in enumerate(g.get("walls", [])):
            out.append(self._outline(t, "walls", i, w["vertices"], (0.45, 0.45, 0.5, 1.0)))
        for i, p in enumerate(g.get("polygons", [])):
            color = (0.35, 0.35, 0.75, 0.9) if p.get("known") else (0.75, 0.35, 0.35, 0.9)
            out.append(self._outline(t, "obstacles", i, p["vertices"], color))
        for i, d in enumerate(g.get("discs", [])):
            color = (0.35, 0.35, 0.75, 0.9) if d.get("known") else (0.75, 0.35, 0.35, 0.9)
            r = float(d["radius"])
            centre = self._pose(float(d["center"][0]), float(d["center"][1]), MARKER_HEIGHT / 2)
            out.append(self._marker(t, "discs", i, 3, centre, (2 * r, 2 * r, MARKER_HEIGHT), color))
        return out

    def _dynamic_markers(self, t: float, poses: dict[str, tuple[float, float, float]], msg: WorldState) -> list[Any]:
        """Robots (cylinder and heading arrow), targets, moving obstacles, sensing circles."""
        out = []
        r = self.radius
        for i, (_rid, (x, y, th)) in enumerate(sorted(poses.items())):
            out.append(self._marker(t, "robots", i, 3, self._pose(x, y, MARKER_HEIGHT / 2),
                                    (2 * r, 2 * r, MARKER_HEIGHT), (0.1, 0.55, 0.95, 1.0)))
            out.append(self._marker(t, "headings", i, 0, self._pose(x, y, MARKER_HEIGHT, th), (2 * r, 0.008, 0.008),
                                    (1.0, 1.0, 1.0, 1.0)))
            if math.isfinite(self.target_range):
                out.append(self._circle(t, "sensing", i, x, y, self.target_range, (0.1, 0.55, 0.95, 0.5)))
        for i, (_tid, tg) in enumerate(sorted(msg.targets.items())):
            x, y = tg.x, tg.y
            out.append(self._marker(t, "targets", i, 2, self._pose(x, y, 0.015), (0.03, 0.03, 0.03),
                                    (0.95, 0.6, 0.1, 1.0)))
        for i, (oid, ob) in enumerate(sorted(msg.obstacles.items())):
            x, y, th = ob.x, ob.y, ob.theta
            shape = self._moving.get(oid, {})
            color = (0.75, 0.35, 0.35, 0.9)
            if shape.get("vertices"):
                c, s = math.cos(th), math.sin(th)
                pts = [(x + c * float(vx) - s * float(vy), y + s * float(vx) + c * float(vy))
                       for vx, vy in shape["vertices"]]
                out.append(self._outline(t, "moving_obstacles", i, pts, color))
            else:
                rad = float(shape.get("radius") or r)
                out.append(self._marker(t, "moving_obstacles", i, 3, self._pose(x, y, MARKER_HEIGHT / 2),
                                        (2 * rad, 2 * rad, MARKER_HEIGHT), color))
        return out
