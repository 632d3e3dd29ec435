"""The messages carried on the key space, each declared once: its fields, their types and
constraints (:mod:`.schema`), and its rules between fields (``check``).

Wire format (schema version 1): one msgpack map per message with

- ``v``: the schema version (int, :data:`SCHEMA_VERSION`),
- ``kind``: the message kind, the :class:`KeyKind` value of the key it travels on,
- ``stamp``: sim time in seconds (float, finite, >= 0),
- ``sender``: who sent it (non-empty string, e.g. ``world`` or ``r1/obstacle-3``),
- the kind's own fields, in the order declared here. A :data:`~.schema.Vector` travels as
  a map ``{"dtype": "<f8", "shape": [n], "data": <n * 8 raw little-endian bytes>}``; a
  tuple as a list; an entry of the world state as a map of its fields.

A message is checked and normalized when it is built (by its declared types, then its
``check``), so an invalid message can neither be sent nor come out of :func:`decode`,
and a decoded message equals the one that was sent. Decoding (:mod:`.codec`) also checks
the wire layout (version, kind against the key, missing and unexpected fields) and that
a sensor index in the payload is the key's. Every failure is a :class:`MessageError`
subclass naming the key, the field and the problem.
"""

from __future__ import annotations

from typing import Annotated, ClassVar

import msgspec
from msgspec import Meta

from .checks import MAX_ARRAY_LEN
from .errors import MessageFieldError
from .keys import KeyKind
from .schema import (
    MAX_INDEX,
    MAX_SENDER_LEN,
    MAX_TARGETS,
    MESSAGE_TYPES,
    MSGPACK_ENCODING,
    SCHEMA_VERSION,
    Angle,
    Count,
    Distance,
    Entry,
    EntryId,
    Finite,
    Message,
    Neuron,
    Plain,
    Point,
    Pose,
    RobotId,
    SensorIndex,
    Stamp,
    TargetId,
    Vector,
    Weight,
)

__all__ = ["MAX_ARRAY_LEN", "MAX_INDEX", "MAX_SENDER_LEN", "MAX_TARGETS", "MESSAGE_TYPES", "MSGPACK_ENCODING",
           "SCHEMA_VERSION", "Message", "SenseTarget", "SenseRange", "TargetField", "ObstacleField", "WheelCommand",
           "Share", "SensePose", "SenseTargets", "Unchanged", "TrackingField", "RobotState", "TargetState",
           "ObstacleState", "WorldState", "Clock", "Data", "SenseOdometry", "MapVersion", "with_stamp", "decode",
           "encode", "peek", "summary", "to_plain", "to_wire"]


def _fail(field: str, problem: str) -> MessageFieldError:
    return MessageFieldError(problem, field=field)


class SenseTarget(Message):
    """World -> target module: the target's direction ``alpha`` (rad) and distance ``d`` (m).

    ``visible`` is False when the target is out of sensing range; alpha and d are then
    meaningless (the world sends 0, 0)."""

    alpha: Angle
    d: Distance
    visible: bool
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_TARGET


class SenseRange(Message):
    """World -> obstacle module ``index``: the sensor's direction ``alpha`` and range ``d``
    (m, from the robot's centre: the obstacle input u_j), None when the sensor sees nothing."""

    index: SensorIndex
    alpha: Angle
    d: Distance | None
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_RANGE


class TargetField(Message):
    """Target module -> motor module: the winning neuron ``winner`` and the target
    field's activities ``a`` (float64[n], one per neuron of the motor map), and the
    sensed target input u = (``alpha``, ``d``) that Eq. 11 maps through M_k when k = s.

    No target sensed: alpha, d, winner and a are all None. The goal state (d = 0):
    ``at_goal`` is True, alpha and d are given, winner and a are None (the robot stops).
    """

    winner: Neuron | None
    a: Vector | None
    alpha: Angle | None = None
    d: Distance | None = None
    at_goal: bool = False
    KIND: ClassVar[KeyKind] = KeyKind.FIELD_TARGET

    def check(self) -> None:
        if (self.alpha is None) != (self.d is None):
            raise _fail("alpha" if self.alpha is None else "d",
                        "alpha and d must both be None (no target) or both be given")
        if (self.winner is None) != (self.a is None):
            raise _fail("winner" if self.winner is None else "a", "winner and a must both be None or both be given")
        if self.a is not None:
            if self.winner >= self.a.shape[0]:
                raise _fail("winner", f"{self.winner} out of range 0..{self.a.shape[0] - 1}")
            if self.at_goal:
                raise _fail("at_goal", "at the goal state the target module sends no field")
        elif self.at_goal and self.alpha is None:
            raise _fail("at_goal", "the goal state needs the sensed alpha and d")


class ObstacleField(Message):
    """Obstacle module ``index`` -> motor module: the winning neuron and the obstacle
    field ``b`` (float64[n]); both None when the sensor sees nothing."""

    index: SensorIndex
    winner: Neuron | None
    b: Vector | None
    KIND: ClassVar[KeyKind] = KeyKind.FIELD_OBSTACLE

    def check(self) -> None:
        if (self.winner is None) != (self.b is None):
            raise _fail("winner" if self.winner is None else "b",
                        "winner and b must both be None (nothing seen) or both be given")
        if self.b is not None and self.winner >= self.b.shape[0]:
            raise _fail("winner", f"{self.winner} out of range 0..{self.b.shape[0] - 1}")


class WheelCommand(Message):
    """Motor module -> world: the left and right wheels' linear speeds ``v_l``, ``v_r`` (m/s,
    positive forward; the world clamps each to +-``v_max`` of the robot's body without a
    word, and executes it with its wheel noise) and ``seq``, a sequence number of the
    sender's own (the shipped motors send the tick number, which the runner also fills in
    when a step leaves it out)."""

    v_l: Finite
    v_r: Finite
    seq: Count
    KIND: ClassVar[KeyKind] = KeyKind.CMD_WHEELS


class Share(Message):
    """Robot -> teammates: own ``pose`` (x, y, theta) and the targets it sees,
    ``targets`` = {target id: (x, y)} in the world frame."""

    pose: Pose
    targets: Annotated[dict[TargetId, Point], Meta(max_length=MAX_TARGETS)]
    KIND: ClassVar[KeyKind] = KeyKind.SHARE


class SensePose(Message):
    """World -> a tracking robot's modules: the robot's own ``pose`` (x, y, theta) in the
    world frame, as an external localization system (an overhead camera) would give it;
    the simulator sends the true pose."""

    pose: Pose
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_POSE


class SenseTargets(Message):
    """World -> a tracking robot's modules: every target within the robot's target sensing
    range, ``targets`` = {target id: (alpha, d)} in the robot's frame (the target sensor's
    noise model, the same as :class:`SenseTarget`); an empty map when it sees none."""

    targets: Annotated[dict[TargetId, tuple[Angle, Distance]], Meta(max_length=MAX_TARGETS)]
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_TARGETS


ReadingKey = Annotated[str, Meta(pattern=r"^sense/[a-z]+(/(0|[1-9][0-9]*))?$", max_length=32)]


class Unchanged(Message):
    """World -> the readers of a robot's held readings: the readings ``keys`` (relative to
    the robot, ``sense/range/3``) this tick are equal to the last ones the world sent, at
    sim times ``since``, so the world left them out (the paper, section 3: the localization
    EKMs "remain activated until they are updated"). A reader's pure producer of such a
    reading did not run: its outputs of ``since`` stand for this tick
    (:meth:`cekm_swarm.graph.plan.RunPlan.held_readings`)."""

    keys: Annotated[tuple[ReadingKey, ...], Meta(min_length=1, max_length=MAX_INDEX + 8)]
    since: Annotated[tuple[Stamp, ...], Meta(min_length=1, max_length=MAX_INDEX + 8)]
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_UNCHANGED

    def check(self) -> None:
        if len(self.since) != len(self.keys):
            raise _fail("since", f"{len(self.since)} values for {len(self.keys)} keys")
        if len(set(self.keys)) != len(self.keys):
            raise _fail("keys", "a key is named twice")
        for i, t in enumerate(self.since):
            if t >= self.stamp:
                raise _fail(f"since[{i}]", f"{t} is not before the message's stamp {self.stamp}")


class TrackingField(Message):
    """Tracking target module -> motor module (tracking scenarios): ``a``, the sum of the
    weighted target fields (and the search goal's), ``b``, the sum of the weighted
    teammate fields (float64[n] each), and per localized point (each sensed target, then
    the search goal when searching) ``inputs`` = (winner, alpha, d, weight): the input u
    Eq. 11 maps through M_k when k is that winner. ``weights`` = {target id: w_t}."""

    a: Vector
    b: Vector
    inputs: Annotated[tuple[tuple[Neuron, Angle, Distance, Weight], ...], Meta(max_length=MAX_TARGETS + 1)]
    weights: Annotated[dict[TargetId, Weight], Meta(max_length=MAX_TARGETS)]
    searching: bool
    KIND: ClassVar[KeyKind] = KeyKind.FIELD_TRACKING

    def check(self) -> None:
        n = self.a.shape[0]
        if self.b.shape[0] != n:
            raise _fail("b", f"length {self.b.shape[0]}, a has {n}")
        for i, row in enumerate(self.inputs):
            if row[0] >= n:
                raise _fail(f"inputs[{i}][0]", f"winner {row[0]} out of range 0..{n - 1}")


class RobotState(Entry):
    """One robot in the world state (ground truth): its pose ``x``, ``y`` (m) and
    ``theta`` (rad); the wheel speeds commanded (clipped) ``v_l``, ``v_r`` and executed
    with noise in the last sub-step ``v_l_exec``, ``v_r_exec`` (m/s); ``in_contact``;
    its navigation ``goal`` (x, y), None when it has none. The world sends every field; a
    field with a default may be left out by other senders."""

    x: Finite
    y: Finite
    theta: Angle
    v_l: Finite = 0.0
    v_r: Finite = 0.0
    v_l_exec: Finite = 0.0
    v_r_exec: Finite = 0.0
    in_contact: bool = False
    goal: Point | None = None


class TargetState(Entry):
    """One target in the world state: its position ``x``, ``y`` (m)."""

    x: Finite
    y: Finite


class ObstacleState(Entry):
    """One moving obstacle in the world state: its position ``x``, ``y`` (m) and its body's
    angle ``theta`` (rad, not wrapped: it turns as it turns)."""

    x: Finite
    y: Finite
    theta: Finite = 0.0


class WorldState(Message):
    """World -> monitors: ground truth, typed: ``robots`` {robot id: :class:`RobotState`},
    ``targets`` {id: :class:`TargetState`}, ``obstacles`` {id: :class:`ObstacleState`}
    (the moving obstacles). Built from ``world.World.state()``'s maps as they are."""

    robots: dict[RobotId, RobotState]
    targets: dict[EntryId, TargetState]
    obstacles: dict[EntryId, ObstacleState]
    KIND: ClassVar[KeyKind] = KeyKind.WORLD_STATE


class Clock(Message):
    """World -> all (lockstep): the tick number; ``stamp`` is the tick's sim time."""

    tick: Count
    KIND: ClassVar[KeyKind] = KeyKind.WORLD_CLOCK


class Data(Message):
    """A node's own named values (on a key its graph declares): ``values`` = {name: plain
    data}, where plain data is None, bool, int, finite float, str, and lists and
    string-keyed maps of them. What a controller's intermediate results (command fusion's
    two proposals, A-CMOMMT's force) and a user's own node send."""

    values: dict[str, Plain]
    KIND: ClassVar[KeyKind] = KeyKind.DATA


ODOMETRY_ROWS = 16
"""Ticks a :class:`SenseOdometry` reading covers (the last ones): a learner running every
8 ticks loses no tick when one reading is lost."""
_Rows = Annotated[tuple[Finite, ...], Meta(max_length=ODOMETRY_ROWS)]


class SenseOdometry(Message):
    """World -> the learner: the robot's motor controller's record of its last ticks
    (docs/learning.md), one row per tick ``ticks[i]`` (the interval that ends at it): the
    wheel speeds it held, ``set_l``, ``set_r`` (m/s, the robot's command clipped to c*),
    what the wheel encoders measured, ``left``, ``right`` (m, signed; the executed speeds
    with the plant's slip noise, over each sub-step), and ``blocked``, whether the body
    touched a wall, an obstacle or a robot meanwhile (the motors' stall signal). ``dt``: a
    tick's length (s). Never the pose."""

    ticks: Annotated[tuple[Count, ...], Meta(max_length=ODOMETRY_ROWS)]
    set_l: _Rows
    set_r: _Rows
    left: _Rows
    right: _Rows
    blocked: Annotated[tuple[bool, ...], Meta(max_length=ODOMETRY_ROWS)]
    dt: Annotated[float, Meta(ge=1e-6, le=60.0)]
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_ODOMETRY

    def check(self) -> None:
        n = len(self.ticks)
        for name in ("set_l", "set_r", "left", "right", "blocked"):
            if len(getattr(self, name)) != n:
                raise _fail(name, f"{len(getattr(self, name))} rows, ticks has {n}")
        if any(b <= a for a, b in zip(self.ticks, self.ticks[1:], strict=False)):
            raise _fail("ticks", "not increasing")


Digest = Annotated[str, Meta(pattern=r"^[0-9a-f]{16}$")]
"""A map's digest: the first 16 hex digits of the SHA-256 of its w and M (docs/learning.md)."""


class MapVersion(Message):
    """Learner -> every EKM node of its robot: version ``version`` of the robot's map (section
    3.5: all of a robot's EKMs share one set of input weights), whole: the input weights
    ``w`` (2n: alpha_i, d_i per neuron) and the control parameters ``M`` (4n, row-major 2x2
    per neuron, internal units; R^-1 stays with the learner), after ``steps`` learning
    steps (``applied`` learned from, own and teammates', ``skipped`` stopped or blocked),
    and ``digest`` of the two arrays. A reader uses version k from the tick after its
    stamp (docs/learning.md)."""

    version: Count
    steps: Count
    applied: Count
    skipped: Count
    digest: Digest
    w: Vector
    M: Vector
    error: Weight = 0.0  # m/s: the mean |c - M_s v| of its own last run's steps before it learned them (Eq. 13)
    KIND: ClassVar[KeyKind] = KeyKind.MAP_VERSION

    def check(self) -> None:
        n2 = self.w.shape[0]
        if n2 % 2:
            raise _fail("w", f"length {n2} is not two values per neuron")
        if self.M.shape[0] != 2 * n2:
            raise _fail("M", f"length {self.M.shape[0]}, w has {n2 // 2} neurons (4 values each)")
        if self.applied + self.skipped != self.steps:
            raise _fail("steps", f"{self.steps} steps, but {self.applied} applied and {self.skipped} skipped")


def with_stamp(msg: Message, t: float) -> Message:
    """``msg`` as sent at sim time ``t`` (checked as any record): what a pure node would
    have sent at ``t`` for the same inputs."""
    return msgspec.structs.replace(msg, stamp=t)


from .codec import decode, encode, peek, summary, to_plain, to_wire  # noqa: E402 - the messages' old home re-exports them
