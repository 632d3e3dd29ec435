"""The messages carried on the key space: dataclasses, msgpack encoding, strict decoding.

Wire format (schema version 1): one msgpack map per message with

- ``v``: the schema version (int, :data:`SCHEMA_VERSION`),
- ``kind``: the message kind, the :class:`KeyKind` value of the key it travels on,
- ``stamp``: sim time in seconds (float, finite, >= 0),
- ``sender``: who sent it (non-empty string, e.g. ``world`` or ``r1/obstacle-3``),
- the kind's own fields. A numpy array travels as a map
  ``{"dtype": "<f8", "shape": [n], "data": <n * 8 raw little-endian bytes>}``.

Every message object is validated when it is built (``__post_init__``), so an invalid
message can neither be sent nor come out of :func:`decode`. :func:`decode` also checks
the wire layout (version, kind against the key, missing and unexpected fields, array
dtype/shape/byte length) and, when given a key, that a sensor index in the payload is
the one in the key. Every failure is a :class:`MessageError` subclass naming the key,
the field and the problem. Decoded arrays are read-only views of the received bytes.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass, fields
from typing import Any, ClassVar, Union

import msgpack
import numpy as np

from .errors import (KeySpaceError, MessageArrayError, MessageError, MessageFieldError, MessageFormatError,
                     MessageKindError, MessageVersionError)
from .keys import DEFAULT_KEYS, KeyKind, KeySpace, validate_robot_id

SCHEMA_VERSION = 1
"""The version of the wire format this code writes and accepts."""

MSGPACK_ENCODING = "application/msgpack"
"""The Zenoh encoding label of every payload."""

MAX_SENDER_LEN = 128
MAX_INDEX = 1024  # sanity bound for indices in payloads; the key space bounds sensor indices exactly
MAX_ARRAY_LEN = 1 << 20
_MAX_DEPTH = 16
_ANGLE_LIMIT = math.pi + 1e-9
_F8 = np.dtype("<f8")
_ENVELOPE = ("v", "kind", "stamp", "sender")


# --------------------------------------------------------------------------- field checks


def _fail(field: str, problem: str) -> MessageFieldError:
    return MessageFieldError(problem, field=field)


def _float(field: str, x: Any, *, lo: float | None = None, angle: bool = False) -> float:
    t = type(x)
    if t is not float:
        if t is bool or not isinstance(x, (int, float, np.floating, np.integer)):
            raise _fail(field, f"expected a number, got {t.__name__}")
        x = float(x)
    if not math.isfinite(x):
        raise _fail(field, f"not finite ({x})")
    if lo is not None and x < lo:
        raise _fail(field, f"{x} is below {lo}")
    if angle and not -_ANGLE_LIMIT <= x <= _ANGLE_LIMIT:
        raise _fail(field, f"angle {x} outside [-pi, pi]")
    return x


def _int(field: str, x: Any, *, lo: int = 0, hi: int | None = None) -> int:
    if type(x) is not int:
        if isinstance(x, bool):
            raise _fail(field, "expected an integer, got bool")
        try:
            x = operator.index(x)
        except TypeError:
            raise _fail(field, f"expected an integer, got {type(x).__name__}") from None
    if x < lo or (hi is not None and x >= hi):
        raise _fail(field, f"{x} out of range {lo}..{'' if hi is None else hi - 1}")
    return x


def _bool(field: str, x: Any) -> bool:
    if type(x) is bool:
        return x
    if isinstance(x, np.bool_):
        return bool(x)
    raise _fail(field, f"expected a bool, got {type(x).__name__}")


def _text(field: str, x: Any, *, max_len: int = MAX_SENDER_LEN) -> str:
    if type(x) is not str:
        raise _fail(field, f"expected a string, got {type(x).__name__}")
    if not x or len(x) > max_len:
        raise _fail(field, f"must be 1..{max_len} characters, got {len(x)}")
    return x


def _vector(field: str, x: Any) -> np.ndarray:
    """A finite 1-D float64 array with at least one element."""
    if type(x) is not np.ndarray or x.dtype is not _F8:
        try:
            x = np.asarray(x, dtype=_F8)
        except (TypeError, ValueError) as exc:
            raise MessageArrayError(f"not convertible to float64: {exc}", field=field) from None
    if x.ndim != 1:
        raise MessageArrayError(f"expected a 1-D array, got shape {x.shape}", field=field)
    n = x.shape[0]
    if n == 0 or n > MAX_ARRAY_LEN:
        raise MessageArrayError(f"length {n} outside 1..{MAX_ARRAY_LEN}", field=field)
    # One cheap reduction (0.5 us for 225 values): any NaN or infinity makes the sum of
    # squares non-finite, and NaN/inf inputs raise no FP warning; only then, or when
    # finite values beyond 1e154 overflow it (silently: a peer's huge values are not this
    # process's floating-point error), look element by element.
    with np.errstate(over="ignore"):
        energy = x.dot(x)
    if not math.isfinite(energy):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise MessageFieldError(f"not finite at index {int(bad[0])} ({x[bad[0]]})", field=field)
    return x


def _plain(field: str, x: Any, depth: int = 0) -> Any:
    """Plain nested data (None, bool, int, finite float, str, list, str-keyed dict), normalized."""
    if depth > _MAX_DEPTH:
        raise _fail(field, f"nested deeper than {_MAX_DEPTH} levels")
    if x is None or type(x) in (bool, str):
        return x
    if type(x) is float:
        if not math.isfinite(x):
            raise _fail(field, f"not finite ({x})")
        return x
    if type(x) is int:
        if not -(1 << 63) <= x < (1 << 64):
            raise _fail(field, f"integer {x} does not fit 64 bits")
        return x
    if isinstance(x, dict):
        out = {}
        for k, v in x.items():
            if type(k) is not str:
                raise _fail(field, f"map key {k!r} is not a string")
            out[k] = _plain(f"{field}.{k}", v, depth + 1)
        return out
    if isinstance(x, (list, tuple)):
        return [_plain(f"{field}[{i}]", v, depth + 1) for i, v in enumerate(x)]
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, np.integer):
        return _plain(field, int(x), depth)
    if isinstance(x, np.floating):
        return _plain(field, float(x), depth)
    raise _fail(field, f"{type(x).__name__} is not plain data (use dict, list, str, int, float, bool, None)")


def _xy(field: str, x: Any, n: int) -> tuple[float, ...]:
    if not isinstance(x, (list, tuple, np.ndarray)) or len(x) != n:
        raise _fail(field, f"expected {n} numbers, got {x!r}")
    return tuple(_float(f"{field}[{i}]", v, angle=(n == 3 and i == 2)) for i, v in enumerate(x))


# --------------------------------------------------------------------------- wire arrays


def _array_to_wire(a: np.ndarray) -> dict[str, Any]:
    if a.dtype is not _F8 or not a.flags.c_contiguous:
        a = np.ascontiguousarray(a, dtype=_F8)
    return {"dtype": "<f8", "shape": list(a.shape), "data": a.tobytes()}


def _array_from_wire(field: str, m: Any) -> np.ndarray:
    if type(m) is not dict:
        raise MessageArrayError(f"expected an array map {{dtype, shape, data}}, got {type(m).__name__}", field=field)
    if len(m) != 3 or "dtype" not in m or "shape" not in m or "data" not in m:
        raise MessageArrayError(f"array map must have exactly dtype, shape, data; got {sorted(map(str, m))}",
                                field=field)
    dtype, shape, data = m["dtype"], m["shape"], m["data"]
    if dtype != "<f8":
        raise MessageArrayError(f"dtype {dtype!r}, expected '<f8' (little-endian float64)", field=field)
    if type(shape) is not list or len(shape) != 1 or type(shape[0]) is not int or shape[0] < 1:
        raise MessageArrayError(f"shape {shape!r}, expected [n] with n >= 1", field=field)
    if type(data) is not bytes:
        raise MessageArrayError(f"data must be bytes, got {type(data).__name__}", field=field)
    if len(data) != 8 * shape[0]:
        raise MessageArrayError(f"data holds {len(data)} bytes, shape {shape} needs {8 * shape[0]}", field=field)
    return np.frombuffer(data, dtype=_F8)


# --------------------------------------------------------------------------- messages


class _Message:
    """Shared behaviour: envelope checks, array-aware equality, wire conversion.

    Messages are plain (non-frozen, for speed) slotted records validated once when
    built; treat them as immutable."""

    __slots__ = ()
    KIND: ClassVar[KeyKind]
    _ARRAYS: ClassVar[tuple[str, ...]] = ()
    _BODY: ClassVar[tuple[str, ...]] = ()  # field names after stamp and sender, set below

    def _envelope(self) -> None:
        stamp = self.stamp  # type: ignore[attr-defined]
        if type(stamp) is not float or not (0.0 <= stamp < math.inf):
            self.stamp = _float("stamp", stamp, lo=0.0)  # type: ignore[attr-defined]
        sender = self.sender  # type: ignore[attr-defined]
        if type(sender) is not str or not 0 < len(sender) <= MAX_SENDER_LEN:
            _text("sender", sender)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        for name in ("stamp", "sender") + self._BODY:
            a, b = getattr(self, name), getattr(other, name)
            if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
                if a is None or b is None or not np.array_equal(a, b):
                    return False
            elif a != b:
                return False
        return True

    __hash__ = None  # type: ignore[assignment]

    def _body(self) -> dict[str, Any]:
        out = {name: getattr(self, name) for name in self._BODY}
        for name in self._ARRAYS:
            if out[name] is not None:
                out[name] = _array_to_wire(out[name])
        return out

    @classmethod
    def _from_body(cls, body: dict[str, Any]) -> "_Message":
        for name in cls._ARRAYS:
            v = body.get(name)
            if v is not None:
                body[name] = _array_from_wire(name, v)
        return cls(**body)


@dataclass(eq=False, slots=True)
class SenseTarget(_Message):
    """World -> target module: the target's direction ``alpha`` (rad) and distance ``d`` (m).

    ``visible`` is False when the target is out of sensing range; alpha and d are then
    meaningless (the world sends 0, 0)."""

    stamp: float
    sender: str
    alpha: float
    d: float
    visible: bool
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_TARGET

    def __post_init__(self) -> None:
        self._envelope()
        self.alpha = _float("alpha", self.alpha, angle=True)
        self.d = _float("d", self.d, lo=0.0)
        self.visible = _bool("visible", self.visible)


@dataclass(eq=False, slots=True)
class SenseRange(_Message):
    """World -> obstacle module ``index``: the sensor's direction ``alpha`` and range ``d``
    (m), None when the sensor sees nothing."""

    stamp: float
    sender: str
    index: int
    alpha: float
    d: float | None
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_RANGE

    def __post_init__(self) -> None:
        self._envelope()
        self.index = _int("index", self.index, hi=MAX_INDEX)
        self.alpha = _float("alpha", self.alpha, angle=True)
        if self.d is not None:
            self.d = _float("d", self.d, lo=0.0)


@dataclass(eq=False, slots=True)
class TargetField(_Message):
    """Target module -> motor module: the winning neuron ``winner`` and the target
    field's activities ``a`` (float64[n], one per neuron of the motor map), and the
    sensed target input u = (``alpha``, ``d``) that Eq. 11 maps through M_k when k = s.

    No target sensed: alpha, d, winner and a are all None. The goal state (d = 0):
    ``at_goal`` is True, alpha and d are given, winner and a are None (the robot stops).
    """

    stamp: float
    sender: str
    winner: int | None
    a: np.ndarray | None
    alpha: float | None = None
    d: float | None = None
    at_goal: bool = False
    KIND: ClassVar[KeyKind] = KeyKind.FIELD_TARGET
    _ARRAYS: ClassVar[tuple[str, ...]] = ("a",)

    def __post_init__(self) -> None:
        self._envelope()
        self.at_goal = _bool("at_goal", self.at_goal)
        if (self.alpha is None) != (self.d is None):
            raise _fail("alpha" if self.alpha is None else "d", "alpha and d must both be None (no target) or both be given")
        if self.alpha is not None:
            self.alpha = _float("alpha", self.alpha, angle=True)
            self.d = _float("d", self.d, lo=0.0)
        if (self.winner is None) != (self.a is None):
            raise _fail("winner" if self.winner is None else "a", "winner and a must both be None or both be given")
        if self.a is not None:
            a = _vector("a", self.a)
            self.a = a
            self.winner = _int("winner", self.winner, hi=a.shape[0])
            if self.at_goal:
                raise _fail("at_goal", "at the goal state the target module sends no field")
        elif self.at_goal and self.alpha is None:
            raise _fail("at_goal", "the goal state needs the sensed alpha and d")


@dataclass(eq=False, slots=True)
class ObstacleField(_Message):
    """Obstacle module ``index`` -> motor module: the winning neuron and the obstacle
    field ``b`` (float64[n]); both None when the sensor sees nothing."""

    stamp: float
    sender: str
    index: int
    winner: int | None
    b: np.ndarray | None
    KIND: ClassVar[KeyKind] = KeyKind.FIELD_OBSTACLE
    _ARRAYS: ClassVar[tuple[str, ...]] = ("b",)

    def __post_init__(self) -> None:
        self._envelope()
        self.index = _int("index", self.index, hi=MAX_INDEX)
        if (self.winner is None) != (self.b is None):
            raise _fail("winner" if self.winner is None else "b",
                        "winner and b must both be None (nothing seen) or both be given")
        if self.b is not None:
            b = _vector("b", self.b)
            self.b = b
            self.winner = _int("winner", self.winner, hi=b.shape[0])


@dataclass(eq=False, slots=True)
class WheelCommand(_Message):
    """Motor module -> world: wheel linear speeds (m/s) and a per-sender sequence number."""

    stamp: float
    sender: str
    v_l: float
    v_r: float
    seq: int
    KIND: ClassVar[KeyKind] = KeyKind.CMD_WHEELS

    def __post_init__(self) -> None:
        self._envelope()
        self.v_l = _float("v_l", self.v_l)
        self.v_r = _float("v_r", self.v_r)
        self.seq = _int("seq", self.seq, hi=1 << 63)


@dataclass(eq=False, slots=True)
class Share(_Message):
    """Robot -> teammates: own ``pose`` (x, y, theta) and the targets it sees,
    ``targets`` = {target id: (x, y)} in the world frame."""

    stamp: float
    sender: str
    pose: tuple[float, float, float]
    targets: dict[str, tuple[float, float]]
    KIND: ClassVar[KeyKind] = KeyKind.SHARE

    def __post_init__(self) -> None:
        self._envelope()
        self.pose = _xy("pose", self.pose, 3)
        self.targets = _targets_map("targets", self.targets, 2)

    def _body(self) -> dict[str, Any]:
        return {"pose": list(self.pose), "targets": {k: list(v) for k, v in self.targets.items()}}


MAX_TARGETS = 4096
"""Sanity bound on the number of targets in one message."""


def _targets_map(field: str, x: Any, n: int, *, polar: bool = False) -> dict[str, tuple[float, ...]]:
    """{target id: n numbers}; ``polar``: (alpha, d) with alpha an angle and d >= 0."""
    if not isinstance(x, dict):
        raise _fail(field, f"expected a map {{target id: [{n} numbers]}}, got {type(x).__name__}")
    if len(x) > MAX_TARGETS:
        raise _fail(field, f"{len(x)} targets, at most {MAX_TARGETS}")
    out = {}
    for tid, v in x.items():
        _text(field, tid, max_len=64)
        xy = _xy(f"{field}.{tid}", v, n)
        if polar:
            _float(f"{field}.{tid}[0]", xy[0], angle=True)
            _float(f"{field}.{tid}[1]", xy[1], lo=0.0)
        out[tid] = xy
    return out


@dataclass(eq=False, slots=True)
class SensePose(_Message):
    """World -> a tracking robot's modules: the robot's own ``pose`` (x, y, theta) in the
    world frame, as an external localization system (an overhead camera) would give it;
    the simulator sends the true pose."""

    stamp: float
    sender: str
    pose: tuple[float, float, float]
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_POSE

    def __post_init__(self) -> None:
        self._envelope()
        self.pose = _xy("pose", self.pose, 3)

    def _body(self) -> dict[str, Any]:
        return {"pose": list(self.pose)}


@dataclass(eq=False, slots=True)
class SenseTargets(_Message):
    """World -> a tracking robot's modules: every target within the robot's target sensing
    range, ``targets`` = {target id: (alpha, d)} in the robot's frame (the target sensor's
    noise model, the same as :class:`SenseTarget`); an empty map when it sees none."""

    stamp: float
    sender: str
    targets: dict[str, tuple[float, float]]
    KIND: ClassVar[KeyKind] = KeyKind.SENSE_TARGETS

    def __post_init__(self) -> None:
        self._envelope()
        self.targets = _targets_map("targets", self.targets, 2, polar=True)

    def _body(self) -> dict[str, Any]:
        return {"targets": {k: list(v) for k, v in self.targets.items()}}


@dataclass(eq=False, slots=True)
class TrackingField(_Message):
    """Tracking target module -> motor module (tracking scenarios): ``a``, the sum of the
    weighted target fields (and the search goal's), ``b``, the sum of the weighted
    teammate fields (float64[n] each), and per localized point (each sensed target, then
    the search goal when searching) ``inputs`` = (winner, alpha, d, weight): the input u
    Eq. 11 maps through M_k when k is that winner. ``weights`` = {target id: w_t}."""

    stamp: float
    sender: str
    a: np.ndarray
    b: np.ndarray
    inputs: tuple[tuple[int, float, float, float], ...]
    weights: dict[str, float]
    searching: bool
    KIND: ClassVar[KeyKind] = KeyKind.FIELD_TRACKING
    _ARRAYS: ClassVar[tuple[str, ...]] = ("a", "b")

    def __post_init__(self) -> None:
        self._envelope()
        self.a = _vector("a", self.a)
        self.b = _vector("b", self.b)
        n = self.a.shape[0]
        if self.b.shape[0] != n:
            raise _fail("b", f"length {self.b.shape[0]}, a has {n}")
        if not isinstance(self.inputs, (list, tuple)) or len(self.inputs) > MAX_TARGETS + 1:
            raise _fail("inputs", f"expected at most {MAX_TARGETS + 1} [winner, alpha, d, weight] entries")
        rows = []
        for i, row in enumerate(self.inputs):
            if not isinstance(row, (list, tuple)) or len(row) != 4:
                raise _fail(f"inputs[{i}]", f"expected [winner, alpha, d, weight], got {row!r}")
            rows.append((_int(f"inputs[{i}].winner", row[0], hi=n), _float(f"inputs[{i}].alpha", row[1], angle=True),
                         _float(f"inputs[{i}].d", row[2], lo=0.0), _float(f"inputs[{i}].weight", row[3], lo=0.0)))
        self.inputs = tuple(rows)
        if not isinstance(self.weights, dict) or len(self.weights) > MAX_TARGETS:
            raise _fail("weights", f"expected a map {{target id: weight}} of at most {MAX_TARGETS} entries")
        self.weights = {_text("weights", k, max_len=64): _float(f"weights.{k}", v, lo=0.0)
                        for k, v in self.weights.items()}
        self.searching = _bool("searching", self.searching)

    def _body(self) -> dict[str, Any]:
        return {"a": _array_to_wire(self.a), "b": _array_to_wire(self.b), "inputs": [list(r) for r in self.inputs],
                "weights": dict(self.weights), "searching": self.searching}


@dataclass(eq=False, slots=True)
class WorldState(_Message):
    """World -> monitors: ground truth as plain nested data, as ``world.World.state()``
    gives it: ``robots`` {robot id: {x, y, theta, ...}}, ``targets`` {id: {...}},
    ``obstacles`` {id: {...}} (moving obstacles). Tuples become lists."""

    stamp: float
    sender: str
    robots: dict[str, dict[str, Any]]
    targets: dict[str, Any]
    obstacles: dict[str, Any]
    KIND: ClassVar[KeyKind] = KeyKind.WORLD_STATE

    def __post_init__(self) -> None:
        self._envelope()
        for name in ("robots", "targets", "obstacles"):
            value = getattr(self, name)
            if not isinstance(value, dict):
                raise _fail(name, f"expected a map, got {type(value).__name__}")
            setattr(self, name, _plain(name, value))
        for rid, r in self.robots.items():
            try:
                validate_robot_id(rid)
            except KeySpaceError as exc:
                raise _fail(f"robots.{rid}", exc.problem) from None
            if not isinstance(r, dict):
                raise _fail(f"robots.{rid}", f"expected a map, got {type(r).__name__}")


@dataclass(eq=False, slots=True)
class Clock(_Message):
    """World -> all (lockstep): the tick number; ``stamp`` is the tick's sim time."""

    stamp: float
    sender: str
    tick: int
    KIND: ClassVar[KeyKind] = KeyKind.WORLD_CLOCK

    def __post_init__(self) -> None:
        self._envelope()
        self.tick = _int("tick", self.tick, hi=1 << 63)


@dataclass(eq=False, slots=True)
class Data(_Message):
    """A node's own named values (on a key its graph declares): ``values`` = {name: plain
    data}, where plain data is None, bool, int, finite float, str, and lists and
    string-keyed maps of them. What a controller's intermediate results (command fusion's
    two proposals, A-CMOMMT's force) and a user's own node send."""

    stamp: float
    sender: str
    values: dict[str, Any]
    KIND: ClassVar[KeyKind] = KeyKind.DATA

    def __post_init__(self) -> None:
        self._envelope()
        if not isinstance(self.values, dict):
            raise _fail("values", f"expected a map, got {type(self.values).__name__}")
        self.values = _plain("values", self.values)


Message = Union[SenseTarget, SenseRange, TargetField, ObstacleField, WheelCommand, Share, WorldState, Clock,
                SensePose, SenseTargets, TrackingField, Data]
"""Any message of the protocol."""

MESSAGE_TYPES: dict[KeyKind, type] = {cls.KIND: cls for cls in
                                      (SenseTarget, SenseRange, TargetField, ObstacleField, WheelCommand, Share,
                                       WorldState, Clock, SensePose, SenseTargets, TrackingField, Data)}
"""The message class of each key kind (liveliness keys carry no message)."""

for _cls in MESSAGE_TYPES.values():
    _cls._BODY = tuple(f.name for f in fields(_cls) if f.name not in ("stamp", "sender"))

_FIELDS: dict[KeyKind, frozenset[str]] = {
    kind: frozenset(f.name for f in fields(cls)) for kind, cls in MESSAGE_TYPES.items()}


# --------------------------------------------------------------------------- encode / decode

_KIND_VALUE: dict[type, str] = {cls: kind.value for kind, cls in MESSAGE_TYPES.items()}
_packb = msgpack.packb
_unpackb = msgpack.unpackb


def to_wire(msg: Message) -> dict[str, Any]:
    """The map that :func:`encode` packs: the envelope, then the kind's fields in order."""
    kind = _KIND_VALUE.get(type(msg))
    if kind is None:
        raise MessageKindError(f"{type(msg).__name__} is not a protocol message")
    wire = {"v": SCHEMA_VERSION, "kind": kind, "stamp": msg.stamp, "sender": msg.sender}
    wire.update(msg._body())
    return wire


def encode(msg: Message) -> bytes:
    """The msgpack bytes of ``msg`` (already validated when it was built)."""
    return _packb(to_wire(msg), use_bin_type=True)


_PARSED: dict[int, tuple[KeySpace, dict[str, tuple[KeyKind, int | None]]]] = {}
_PARSED_MAX = 4096


def _parse_cached(keys: KeySpace, key: str) -> tuple[KeyKind, int | None]:
    """keys.parse(key) memoized per KeySpace object (receivers see the same few keys)."""
    entry = _PARSED.get(id(keys))
    if entry is None or entry[0] is not keys:
        entry = _PARSED[id(keys)] = (keys, {})
    cache = entry[1]
    hit = cache.get(key)
    if hit is None:
        p = keys.parse(key)
        if len(cache) >= _PARSED_MAX:
            cache.clear()
        hit = cache[key] = (p.kind, p.index)
    return hit


def decode(key: str | KeyKind, data: bytes | bytearray | memoryview, *, keys: KeySpace = DEFAULT_KEYS,
           expect: KeyKind | None = None) -> Message:
    """Decode and validate the payload received on ``key`` (a key string, or a KeyKind).

    A key a graph declares for a node (``KeyKind.NODE``) carries the kind its node
    declares: ``expect`` (from the graph), or, when not given, whatever kind of the
    protocol the payload says.

    Raises a MessageError subclass naming the key and field for anything wrong: bytes
    that are not one msgpack map, a wrong or missing version, a kind that does not match
    the key, missing or unexpected fields, wrong types, non-finite numbers, arrays of the
    wrong dtype/shape/length, indices out of range or different from the key's.
    """
    if isinstance(key, KeyKind):
        kind, key_index, where = key, None, key.value
    else:
        where = str(key)
        try:
            kind, key_index = _parse_cached(keys, where)
        except KeySpaceError as exc:
            raise MessageKindError(exc.problem, key=where) from None
        if kind is KeyKind.NODE:
            kind = expect if expect is not None else _payload_kind(data, where)
    cls = MESSAGE_TYPES.get(kind)
    if cls is None:
        raise MessageKindError(f"keys of kind '{kind.value}' carry no message", key=where)
    try:
        m = _unpackb(data, raw=False, strict_map_key=True)
    except msgpack.ExtraData:
        raise MessageFormatError("trailing bytes after the msgpack map", key=where) from None
    except Exception as exc:  # msgpack raises ValueError, FormatError, StackError, TypeError ...
        raise MessageFormatError(f"not valid msgpack ({type(exc).__name__}: {exc})", key=where) from None
    if type(m) is not dict:
        raise MessageFormatError(f"expected a msgpack map, got {type(m).__name__}", key=where)
    try:
        v = m.pop("v")
    except KeyError:
        raise MessageVersionError("missing schema version field 'v'", key=where, field="v") from None
    if type(v) is not int or v != SCHEMA_VERSION:
        raise MessageVersionError(f"schema version {v!r}, this code speaks {SCHEMA_VERSION}", key=where, field="v")
    mkind = m.pop("kind", None)
    if mkind != kind.value:
        raise MessageKindError(f"message kind {mkind!r} does not match the key's kind '{kind.value}'",
                               key=where, field="kind")
    expected = _FIELDS[kind]
    if m.keys() != expected:
        missing = sorted(expected - m.keys())
        if missing:
            raise MessageFieldError("missing", key=where, field=missing[0])
        extra = sorted(map(str, m.keys() - expected))
        raise MessageFieldError("unexpected field", key=where, field=extra[0])
    try:
        msg = cls._from_body(m)
    except MessageError as exc:
        raise exc.at_key(where) from None
    if key_index is not None and msg.index != key_index:
        raise MessageFieldError(f"index {msg.index} differs from the key's sensor index {key_index}",
                                key=where, field="index")
    if "index" in expected and not key_index_ok(keys, msg.index):
        raise MessageFieldError(f"{msg.index} out of range 0..{keys.range_sensors - 1}", key=where, field="index")
    return msg


def _payload_kind(data: bytes | bytearray | memoryview, where: str) -> KeyKind:
    """The kind a payload on a graph's own key says it is (checked again by the decode)."""
    got, _ = peek(bytes(data))
    try:
        kind = KeyKind(got)
    except ValueError:
        raise MessageKindError(f"message kind {got!r} is not a kind of the protocol", key=where, field="kind") from None
    if kind not in MESSAGE_TYPES:
        raise MessageKindError(f"message kind {got!r} is not a kind of the protocol", key=where, field="kind")
    return kind


def key_index_ok(keys: KeySpace, index: int) -> bool:
    """True when ``index`` is a sensor index of ``keys``."""
    return 0 <= index < keys.range_sensors


def peek(data: bytes) -> tuple[str | None, float | None]:
    """(kind, stamp) of a payload without validating it, (None, None) when unreadable.

    For recorders that must file even malformed messages at a sim time."""
    try:
        m = msgpack.unpackb(data, raw=False)
    except Exception:
        return None, None
    if type(m) is not dict:
        return None, None
    kind, stamp = m.get("kind"), m.get("stamp")
    kind = kind if type(kind) is str else None
    stamp = float(stamp) if type(stamp) in (int, float) and math.isfinite(stamp) else None
    return kind, stamp


def to_plain(msg: Message) -> dict[str, Any]:
    """``msg`` as plain data (arrays as lists), for printing and JSON."""
    out: dict[str, Any] = {"kind": msg.KIND.value}
    for f in fields(msg):  # type: ignore[arg-type]
        v = getattr(msg, f.name)
        if isinstance(v, np.ndarray):
            v = v.tolist()
        elif isinstance(v, tuple):
            v = list(v)
        out[f.name] = v
    return out


def summary(msg: Message, max_items: int = 6) -> str:
    """A one-line description of ``msg`` (long arrays shortened), for ``topic echo``."""
    parts = [f"{msg.KIND.value} t={msg.stamp:.3f} from={msg.sender}"]
    for f in fields(msg):  # type: ignore[arg-type]
        if f.name in ("stamp", "sender"):
            continue
        v = getattr(msg, f.name)
        if isinstance(v, np.ndarray):
            head = ", ".join(f"{x:.3g}" for x in v[:max_items])
            more = f", ... ({v.shape[0]} values, max {v.max():.3g} at {int(v.argmax())})" if v.shape[0] > max_items else ""
            v = f"[{head}{more}]"
        elif isinstance(v, float):
            v = f"{v:.4g}"
        parts.append(f"{f.name}={v}")
    return " ".join(parts)
