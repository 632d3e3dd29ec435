"""A ROS 2 robot as the controller graph's plant: pure functions (no I/O) that turn what a
ROS 2 robot publishes into the graph's sense messages, and the graph's wheel command into
the Twist the robot takes. The plant process (:mod:`.plant_server`) is a shell around them.

In (per robot, ROS namespace ``/<robot>``; REP 103 units, REP 105 frames):

- ``nav_msgs/msg/Odometry`` on ``/<robot>/odom``: the pose (x, y, yaw) in the odometry
  frame, the frame the goals are given in;
- ``sensor_msgs/msg/LaserScan`` on ``/<robot>/scan`` (origin at the robot's centre, x
  forward): the distance reading of sensor j is the beam nearest its direction, d = the
  beam's range (from the centre: the obstacle input u_j), None when the beam sees nothing
  within the sensor range beyond the body surface; or ``sensor_msgs/msg/Range`` on
  ``/<robot>/range_<j>`` (from the body surface, as the bridge publishes it: d = range +
  body radius);
- ``geometry_msgs/msg/PoseStamped`` on ``/<robot>/goal_pose`` (Nav2's goal): a new goal;
- ``geometry_msgs/msg/PoseArray`` on ``/targets`` (a tracking run): the scenario's targets.

The target reading is the goal in the robot's frame from the odometry: alpha =
atan2 in (-pi, pi], d rounded to 1 mm (the target sensor's resolution), alpha 0 when the
rounded d is 0 (the goal state), as the simulated world reads it.

Out: ``geometry_msgs/msg/Twist`` on ``/<robot>/cmd_vel``: v = (v_l + v_r) / 2,
omega = (v_r - v_l) / axle, each wheel clipped to +-v* first (as the world clips it).

Bad input is refused with a reason (:data:`REASONS`): bytes that are not the type's CDR,
numbers that are not finite, a scan whose ranges do not match its angles or that does
not cover a sensor's direction, a stamp older than :data:`STALE_S` or ahead of the clock,
a frame other than the declared one.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cekm_swarm.errors import CekmError
from cekm_swarm.robot import KHEPERA, RobotBody

from .interfaces import Interfaces

ODOMETRY = "nav_msgs/msg/Odometry"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
RANGE = "sensor_msgs/msg/Range"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
TWIST = "geometry_msgs/msg/Twist"
CLOCK = "rosgraph_msgs/msg/Clock"

STALE_S = 0.5
"""A robot message whose header stamp is older than this (s, on the plant's clock) is stale."""
AHEAD_S = 0.5
"""... or this much ahead of the plant's clock (two hosts' clocks apart): refused too."""
TARGET_RESOLUTION = KHEPERA.target_resolution
DEFAULT_BODY = RobotBody()
"""The body a robot description's missing keys come from by default (RobotBody's defaults: the Khepera)."""

MALFORMED, NOT_FINITE, WRONG_LENGTH, STALE, AHEAD, UNKNOWN_FRAME, NOT_COVERED = (
    "malformed CDR", "not finite", "scan of the wrong length", "stale stamp", "stamp ahead of the clock",
    "unknown frame", "scan does not cover a sensor")
REASONS = (MALFORMED, NOT_FINITE, WRONG_LENGTH, STALE, AHEAD, UNKNOWN_FRAME, NOT_COVERED)
"""Why a robot's message is dropped (the keys of the plant's drop counts)."""


class Refused(ValueError):
    """A robot message the plant does not believe; ``reason`` is one of :data:`REASONS`."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


class DescriptionError(CekmError):
    """A robot description file (or a body) that cannot be used; the message names the file and key."""


# ---------------------------------------------------------------------- the robot's description

SENSOR_SOURCES = ("scan", "range")


@dataclass(frozen=True)
class RobotDescription:
    """What the plant and the graph know of a ROS 2 robot: its body (axle, top wheel speed,
    body radius, sensor directions and range), where its distance readings come from
    (``scan``: one LaserScan; ``range``: one Range per sensor) and its frames (REP 105;
    a frame may also carry the robot's namespace, ``r1/odom``)."""

    body: RobotBody = field(default_factory=RobotBody)
    sensors: str = "scan"
    odom_frame: str = "odom"
    base_frame: str = "base_link"
    scan_frame: str = "base_scan"

    def frames(self, robot: str, frame: str) -> frozenset[str]:
        """The names ``frame`` may have on ``robot``'s messages: bare or under its namespace."""
        return frozenset({frame, f"{robot}/{frame}", f"/{robot}/{frame}"})

    def to_dict(self) -> dict[str, Any]:
        return {"body": self.body.to_dict(), "sensors": self.sensors, "odom_frame": self.odom_frame,
                "base_frame": self.base_frame, "scan_frame": self.scan_frame}

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> RobotDescription:
        return cls(RobotBody.from_dict(doc["body"]), doc["sensors"], doc["odom_frame"], doc["base_frame"],
                   doc["scan_frame"])


_NUMBERS = {"body_radius": (0.001, 5.0), "axle": (0.001, 5.0), "max_wheel_speed": (1e-4, 20.0),
            "sensor_range": (1e-3, 50.0)}
_KEYS = tuple(_NUMBERS) + ("sensor_angles_deg", "sensors", "odom_frame", "base_frame", "scan_frame", "target_range")


def load_description(path: str | Path, default: RobotBody = DEFAULT_BODY) -> RobotDescription:
    """A robot description file (TOML; docs/ros2.md "Driving a ROS 2 robot"): every key
    optional, a missing one taken from ``default`` (the scenario's body). Raises
    :class:`DescriptionError` naming the file and key."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except OSError as exc:
        raise DescriptionError(f"{path}: cannot read the robot description: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DescriptionError(f"{path}: not a TOML robot description: {exc}") from None
    return description_from(doc, str(path), default)


def description_from(doc: dict[str, Any], where: str, default: RobotBody = DEFAULT_BODY) -> RobotDescription:
    """A robot description from its TOML table ``doc`` (``where`` names it in errors)."""
    unknown = sorted(set(doc) - set(_KEYS))
    if unknown:
        raise DescriptionError(f"{where}: unknown key {unknown[0]!r} (keys: {', '.join(_KEYS)})")
    values: dict[str, float] = {}
    for key, (lo, hi) in _NUMBERS.items():
        if key in doc:
            v = doc[key]
            if type(v) not in (int, float) or not math.isfinite(v) or not lo <= v <= hi:
                raise DescriptionError(f"{where}: {key} = {v!r}: expected a number of metres (per second) "
                                       f"in [{lo:g}, {hi:g}]")
            values[key] = float(v)
    changes: dict[str, Any] = {("v_max" if k == "max_wheel_speed" else k): v for k, v in values.items()}
    body = replace(default, **changes)
    if "sensor_angles_deg" in doc:
        a = doc["sensor_angles_deg"]
        if (not isinstance(a, list) or not 1 <= len(a) <= 64
                or not all(type(x) in (int, float) and math.isfinite(x) and -180 <= x <= 180 for x in a)):
            raise DescriptionError(f"{where}: sensor_angles_deg: expected a list of 1 to 64 directions in "
                                   f"degrees, -180..180 (0 ahead, counter-clockwise)")
        body = replace(body, sensor_angles=tuple(math.atan2(math.sin(math.radians(x)), math.cos(math.radians(x)))
                                                 for x in a))
    if "target_range" in doc:
        tr = doc["target_range"]
        if type(tr) not in (int, float) or not tr > 0:
            raise DescriptionError(f"{where}: target_range = {tr!r}: expected a positive number of metres (inf: none)")
        body = replace(body, target_range=float(tr))
    strings = {}
    for key in ("sensors", "odom_frame", "base_frame", "scan_frame"):
        if key in doc:
            v = doc[key]
            if not isinstance(v, str) or not v or any(c.isspace() for c in v):
                raise DescriptionError(f"{where}: {key} = {v!r}: expected a frame or source name")
            strings[key] = v
    if strings.get("sensors", "scan") not in SENSOR_SOURCES:
        raise DescriptionError(f"{where}: sensors = {strings['sensors']!r}: "
                               f"expected one of {', '.join(SENSOR_SOURCES)}")
    return RobotDescription(body, **strings)


BODY_FIELDS = (("body_radius", "body radius", "m"), ("axle", "axle", "m"), ("v_max", "top wheel speed", "m/s"),
               ("sensor_range", "sensor range", "m"))


def body_differences(body: RobotBody, trained: RobotBody, rel: float = 1e-6) -> list[str]:
    """How ``body`` differs from ``trained`` (the body the model's maps were learned on),
    one phrase per field; [] when they are the same."""
    out = []
    for name, what, unit in BODY_FIELDS:
        a, b = getattr(body, name), getattr(trained, name)
        if not math.isclose(a, b, rel_tol=rel, abs_tol=1e-12):
            out.append(f"{what} {a:g} {unit} (the model's: {b:g} {unit})")
    if len(body.sensor_angles) != len(trained.sensor_angles):
        out.append(f"{len(body.sensor_angles)} distance sensors (the model's: {len(trained.sensor_angles)})")
    elif not all(math.isclose(a, b, abs_tol=1e-6)
                 for a, b in zip(body.sensor_angles, trained.sensor_angles, strict=True)):
        deg = ", ".join(f"{math.degrees(a):.4g}" for a in body.sensor_angles)
        out.append(f"sensor directions [{deg}] deg differ from the model's")
    return out


def check_body(body: RobotBody, trained: RobotBody, where: str) -> None:
    """Refuse (:class:`DescriptionError`) a body that differs from the model's: its maps
    (target, obstacle and motor) are in that body's units, so another body would be driven
    by maps that do not fit it. ``where`` names the description."""
    diff = body_differences(body, trained)
    if diff:
        raise DescriptionError(f"{where}: the robot's body differs from the one the model was trained for: "
                               f"{'; '.join(diff)}. Train a model for this body, or run a graph that reads "
                               f"no model")


# ---------------------------------------------------------------------- decoding

@dataclass(frozen=True)
class Odom:
    """One odometry reading: header stamp (s), pose in the odometry frame, body velocity."""

    stamp: float
    x: float
    y: float
    theta: float
    v: float
    omega: float


@dataclass(frozen=True)
class Scan:
    """One laser scan, as the plant samples it: stamp (s), first angle, increment, ranges."""

    stamp: float
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray


def _decode(ifc: Interfaces, payload: bytes, ros_type: str) -> Any:
    if len(payload) < 4 or payload[:2] not in (b"\x00\x01", b"\x00\x00"):
        raise Refused(MALFORMED, f"{len(payload)} bytes starting {payload[:4].hex() or 'with nothing'}: "
                                 f"no CDR encapsulation header")
    try:
        msg = ifc.from_cdr(payload, ros_type)
    except Exception as exc:  # rosbags raises its SerdeError (and struct, index, unicode errors) on bad bytes
        raise Refused(MALFORMED, f"not a {ros_type}: {type(exc).__name__}: {exc}") from None
    return msg


def _stamp(header: Any, now: float, what: str) -> float:
    t = header.stamp.sec + header.stamp.nanosec * 1e-9
    if t < now - STALE_S:
        raise Refused(STALE, f"{what} stamped {t:.3f} s, {now - t:.3f} s before the plant's clock ({now:.3f} s)")
    if t > now + AHEAD_S:
        raise Refused(AHEAD, f"{what} stamped {t:.3f} s, {t - now:.3f} s ahead of the plant's clock ({now:.3f} s)")
    return t


def _frame(frame: str, allowed: frozenset[str], what: str) -> None:
    if frame not in allowed:
        raise Refused(UNKNOWN_FRAME, f"{what} in frame {frame!r}, expected {' or '.join(sorted(allowed))}")


def yaw_of(q: Any) -> float:
    """The yaw (rad, about z) of a unit quaternion; :class:`Refused` when it is not one."""
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or abs(n - 1.0) > 1e-3:
        raise Refused(NOT_FINITE, f"orientation ({x}, {y}, {z}, {w}) is not a unit quaternion")
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def decode_odometry(ifc: Interfaces, payload: bytes, desc: RobotDescription, robot: str, now: float) -> Odom:
    """An Odometry's pose and velocity, checked (frames, finite numbers, stamp)."""
    m = _decode(ifc, payload, ODOMETRY)
    _frame(m.header.frame_id, desc.frames(robot, desc.odom_frame) | desc.frames(robot, "map"), "odometry")
    _frame(m.child_frame_id, desc.frames(robot, desc.base_frame), "odometry's child")
    p, tw = m.pose.pose.position, m.twist.twist
    values = (p.x, p.y, tw.linear.x, tw.angular.z)
    if not all(math.isfinite(v) for v in values):
        raise Refused(NOT_FINITE, f"odometry position ({p.x}, {p.y}), twist ({tw.linear.x}, {tw.angular.z})")
    theta = yaw_of(m.pose.pose.orientation)
    return Odom(_stamp(m.header, now, "odometry"), float(p.x), float(p.y), theta, float(tw.linear.x),
                float(tw.angular.z))


def decode_scan(ifc: Interfaces, payload: bytes, desc: RobotDescription, robot: str, now: float) -> Scan:
    """A LaserScan, checked: frame, finite angles and limits, as many ranges as its angles
    say (ROS: (angle_max - angle_min) / angle_increment + 1), every sensor's direction covered."""
    m = _decode(ifc, payload, LASER_SCAN)
    _frame(m.header.frame_id, desc.frames(robot, desc.scan_frame) | desc.frames(robot, desc.base_frame), "scan")
    a0, a1, inc = float(m.angle_min), float(m.angle_max), float(m.angle_increment)
    if not all(math.isfinite(v) for v in (a0, a1, inc, m.range_min, m.range_max)) or inc == 0.0:
        raise Refused(NOT_FINITE, f"scan angles {a0}..{a1} step {inc}, limits {m.range_min}..{m.range_max}")
    n = len(m.ranges)
    expected = round((a1 - a0) / inc) + 1
    if abs(n - expected) > 1 or n < 2:
        raise Refused(WRONG_LENGTH, f"{n} ranges for angles {a0:.4f}..{a1:.4f} rad in steps of {inc:.5f} "
                                    f"({expected} expected)")
    scan = Scan(_stamp(m.header, now, "scan"), a0, inc, float(m.range_min), float(m.range_max),
                np.asarray(m.ranges, dtype=np.float64))
    for j, a in enumerate(desc.body.sensor_angles):
        if beam_of(scan, a) is None:
            raise Refused(NOT_COVERED, f"sensor {j} looks at {math.degrees(a):.1f} deg, the scan covers "
                                       f"{math.degrees(a0):.1f}..{math.degrees(a1):.1f} deg")
    return scan


def beam_of(scan: Scan, angle: float) -> int | None:
    """The index of the beam nearest ``angle`` (rad, wrapped to the scan's turn), None when
    the scan does not reach within half a step of it."""
    n = len(scan.ranges)
    span = scan.angle_increment * (n - 1)
    for a in (angle, angle + 2 * math.pi, angle - 2 * math.pi):
        i = (a - scan.angle_min) / scan.angle_increment
        k = round(i)
        if -0.5 <= i <= n - 0.5 and 0 <= k < n:
            return k
    full_turn = abs(span) + abs(scan.angle_increment) >= 2 * math.pi - 1e-6
    return 0 if full_turn else None


def scan_readings(scan: Scan, body: RobotBody) -> list[float | None]:
    """Each sensor's reading d (m, from the robot's centre; None: nothing within the sensor
    range beyond the body surface) from the beam nearest its direction. A beam outside
    [range_min, range_max] or not finite (REP 117: nothing there, or no answer) sees nothing."""
    out: list[float | None] = []
    for a in body.sensor_angles:
        r = float(scan.ranges[beam_of(scan, a)])
        ok = math.isfinite(r) and scan.range_min <= r <= scan.range_max and r - body.body_radius <= body.sensor_range
        out.append(max(r, 0.0) if ok else None)
    return out


def decode_range(ifc: Interfaces, payload: bytes, desc: RobotDescription, robot: str, j: int,
                 now: float) -> tuple[float, float | None]:
    """A Range of sensor ``j`` (from the body surface) as (stamp, d from the centre or None)."""
    m = _decode(ifc, payload, RANGE)
    _frame(m.header.frame_id, desc.frames(robot, f"range_{j}"), f"range {j}")
    r = float(m.range)
    if math.isnan(r):
        raise Refused(NOT_FINITE, f"range {j} is NaN")
    t = _stamp(m.header, now, f"range {j}")
    limit = min(desc.body.sensor_range, float(m.max_range)) if math.isfinite(m.max_range) else desc.body.sensor_range
    if not math.isfinite(r) or r > limit or r < float(m.min_range):
        return t, None
    return t, max(0.0, r) + desc.body.body_radius


def decode_goal(ifc: Interfaces, payload: bytes, desc: RobotDescription, robot: str) -> tuple[float, float]:
    """A goal pose (Nav2's ``goal_pose``) as (x, y) in the odometry frame; its stamp is not
    checked (a goal stays until the next)."""
    m = _decode(ifc, payload, POSE_STAMPED)
    _frame(m.header.frame_id, desc.frames(robot, desc.odom_frame) | desc.frames(robot, "map"), "goal")
    p = m.pose.position
    if not (math.isfinite(p.x) and math.isfinite(p.y)):
        raise Refused(NOT_FINITE, f"goal position ({p.x}, {p.y})")
    return float(p.x), float(p.y)


def decode_targets(ifc: Interfaces, payload: bytes, desc: RobotDescription, ids: list[str],
                   now: float) -> dict[str, tuple[float, float]]:
    """A tracking run's targets (``/targets``, a PoseArray in the odometry frame or ``map``):
    the i-th pose is the scenario's i-th target, {id: (x, y)}; as many poses as targets."""
    m = _decode(ifc, payload, POSE_ARRAY)
    _frame(m.header.frame_id, frozenset({desc.odom_frame, "map"}), "targets")
    if len(m.poses) != len(ids):
        raise Refused(WRONG_LENGTH, f"{len(m.poses)} target poses, the scenario has {len(ids)} targets")
    xy = [(float(p.position.x), float(p.position.y)) for p in m.poses]
    if not all(math.isfinite(v) for p in xy for v in p):
        raise Refused(NOT_FINITE, f"target positions {xy}")
    _stamp(m.header, now, "targets")
    return dict(zip(ids, xy, strict=True))


def targets_seen(odom: Odom, targets: dict[str, tuple[float, float]],
                 target_range: float) -> dict[str, tuple[float, float]]:
    """The targets within ``target_range`` of the robot, each as (alpha, d) in its frame (the
    target reading of :func:`target_reading`)."""
    out = {}
    for tid, xy in targets.items():
        alpha, d, visible = target_reading(odom, xy, target_range)
        if visible:
            out[tid] = (alpha, d)
    return out


def decode_clock(ifc: Interfaces, payload: bytes) -> float:
    """A ``/clock`` message's time in s."""
    m = _decode(ifc, payload, CLOCK)
    return m.clock.sec + m.clock.nanosec * 1e-9


# ---------------------------------------------------------------------- sense and command

def target_reading(odom: Odom, goal: tuple[float, float], target_range: float = math.inf,
                   resolution: float = TARGET_RESOLUTION) -> tuple[float, float, bool]:
    """(alpha, d, visible) of ``goal`` seen from the odometry's pose: alpha = atan2 in
    (-pi, pi] in the robot's frame, d rounded to ``resolution`` (alpha 0 when that is 0)."""
    dx, dy = goal[0] - odom.x, goal[1] - odom.y
    c, s = math.cos(odom.theta), math.sin(odom.theta)
    fx, fy = c * dx + s * dy, -s * dx + c * dy
    true_d = math.hypot(fx, fy)
    d = round(true_d / resolution) * resolution if resolution > 0 else true_d
    if d == 0.0:
        return 0.0, 0.0, true_d <= target_range
    alpha = math.atan2(fy, fx)
    if alpha == -math.pi:
        alpha = math.pi
    return alpha, round(d, 9), true_d <= target_range


def twist_of(v_l: float, v_r: float, body: RobotBody) -> tuple[float, float]:
    """(v, omega) of the differential drive for wheel speeds (v_l, v_r), each clipped to +-v*."""
    v_l = min(max(v_l, -body.v_max), body.v_max)
    v_r = min(max(v_r, -body.v_max), body.v_max)
    return (v_l + v_r) / 2.0, (v_r - v_l) / body.axle


def twist_cdr(ifc: Interfaces, v: float, omega: float) -> bytes:
    """The CDR bytes of a Twist of forward speed ``v`` and turn rate ``omega``."""
    vec = "geometry_msgs/msg/Vector3"
    return ifc.cdr(ifc.make(TWIST, linear=ifc.make(vec, x=float(v), y=0.0, z=0.0),
                            angular=ifc.make(vec, x=0.0, y=0.0, z=float(omega))), TWIST)
