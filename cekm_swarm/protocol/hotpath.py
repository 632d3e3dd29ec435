"""The hot path of module processes: accepting a well-formed message in a few checks, and
re-stamping pre-encoded bytes, both equal to the general :func:`~.messages.decode` and
:func:`~.messages.encode`.

A module process is woken once per tick and does a few microseconds of work, so on a
busy machine it runs with cold caches, where every extra Python function call costs
several microseconds (``benchmarks/bench_runtime.py``). The general decoder builds and
validates a message object; the functions here read the unpacked map directly.

* ``*_values(m, ...)`` take the unpacked msgpack map and return the message's values
  when the map is exactly what this code itself sends (every field present, exact
  Python types, in range), else None. None does not mean invalid: the caller then runs
  the general :func:`~.messages.decode`, which accepts or refuses with the precise error.
  So a message accepted here is one the general decoder accepts with the same values
  (``tests/protocol/test_hotpath.py`` checks that over generated maps).
* :class:`Splice` holds the bytes of one message and gives them for any stamp (and other
  float fields), equal to ``encode`` of the message with those values: a field is one of a
  lattice's worth of fixed rows (Eqs. 6, 8), so its bytes are packed once per winner.
"""

from __future__ import annotations

import math
from typing import Any

import msgpack
import numpy as np

from .keys import KeyKind
from .messages import _ANGLE_LIMIT, MAX_ARRAY_LEN, MAX_SENDER_LEN, SCHEMA_VERSION, Message, encode, to_wire

_packb = msgpack.packb
_unpackb = msgpack.unpackb
_INF = math.inf
_SENSE_RANGE = KeyKind.SENSE_RANGE.value
_SENSE_TARGET = KeyKind.SENSE_TARGET.value
_FIELD_OBSTACLE = KeyKind.FIELD_OBSTACLE.value
_FIELD_TARGET = KeyKind.FIELD_TARGET.value
_RANGE_KEYS = frozenset(("v", "kind", "stamp", "sender", "index", "alpha", "d"))
_TARGET_KEYS = frozenset(("v", "kind", "stamp", "sender", "alpha", "d", "visible"))
_OBSTACLE_FIELD_KEYS = frozenset(("v", "kind", "stamp", "sender", "index", "winner", "b"))
_TARGET_FIELD_KEYS = frozenset(("v", "kind", "stamp", "sender", "winner", "a", "alpha", "d", "at_goal"))
_ARRAY_KEYS = frozenset(("dtype", "shape", "data"))
_F8 = np.dtype("<f8")


def unpack(data: bytes) -> Any:
    """The msgpack value of ``data`` as the general decoder reads it, or None when it does
    not read (the general decoder then says why)."""
    try:
        return _unpackb(data, raw=False, strict_map_key=True)
    except Exception:  # noqa: BLE001 - any failure goes to the general decoder
        return None


def _envelope_ok(m: dict, kind: str) -> bool:
    v, stamp, sender = m["v"], m["stamp"], m["sender"]
    return (type(v) is int and v == SCHEMA_VERSION and m["kind"] == kind
            and type(stamp) is float and 0.0 <= stamp < _INF
            and type(sender) is str and 0 < len(sender) <= MAX_SENDER_LEN)


def sense_range_values(m: Any, index: int) -> tuple[float, float, float | None] | None:
    """``(stamp, alpha, d)`` of a well-formed SenseRange map for sensor ``index``, else None."""
    if type(m) is not dict or m.keys() != _RANGE_KEYS or not _envelope_ok(m, _SENSE_RANGE):
        return None
    i, alpha, d = m["index"], m["alpha"], m["d"]
    if type(i) is not int or i != index or type(alpha) is not float or not -_ANGLE_LIMIT <= alpha <= _ANGLE_LIMIT:
        return None
    if d is not None and (type(d) is not float or not 0.0 <= d < _INF):
        return None
    return m["stamp"], alpha, d


def sense_target_values(m: Any) -> tuple[float, float, float, bool] | None:
    """``(stamp, alpha, d, visible)`` of a well-formed SenseTarget map, else None."""
    if type(m) is not dict or m.keys() != _TARGET_KEYS or not _envelope_ok(m, _SENSE_TARGET):
        return None
    alpha, d, visible = m["alpha"], m["d"], m["visible"]
    if (type(alpha) is not float or not -_ANGLE_LIMIT <= alpha <= _ANGLE_LIMIT
            or type(d) is not float or not 0.0 <= d < _INF or type(visible) is not bool):
        return None
    return m["stamp"], alpha, d, visible


class VectorCache:
    """Field vectors already checked, by their wire bytes: a field is one of a fixed
    table's rows (Eqs. 6, 8), so a receiver meets the same few hundred vectors again and
    again. Holds at most ``limit`` vectors and ``max_bytes`` bytes of them (then starts
    again), and only vectors of ``length`` floats when that is given: a peer sending
    distinct vectors of up to 2^20 floats cannot make it hold more. Values are read-only."""

    def __init__(self, limit: int = 4096, max_bytes: int = 8 << 20, length: int | None = None) -> None:
        self.limit = limit
        self.max_bytes = max_bytes
        self.length = length
        self.bytes = 0
        self._arrays: dict[bytes, np.ndarray] = {}

    def vector(self, m: Any) -> np.ndarray | None:
        """The float64 vector of a well-formed wire array map with finite values, else None."""
        if type(m) is not dict or m.keys() != _ARRAY_KEYS:
            return None
        data, shape = m["data"], m["shape"]
        if (type(data) is not bytes or m["dtype"] != "<f8" or type(shape) is not list or len(shape) != 1
                or type(shape[0]) is not int or not 0 < shape[0] <= MAX_ARRAY_LEN or len(data) != 8 * shape[0]
                or (self.length is not None and shape[0] != self.length)):
            return None
        x = self._arrays.get(data)
        if x is not None:
            return x
        x = np.frombuffer(data, dtype=_F8)
        if not np.isfinite(x).all():
            return None
        if len(data) > self.max_bytes:
            return x
        if len(self._arrays) >= self.limit or self.bytes + len(data) > self.max_bytes:
            self._arrays.clear()
            self.bytes = 0
        self._arrays[data] = x
        self.bytes += len(data)
        return x


def obstacle_field_values(m: Any, index: int, vectors: VectorCache
                          ) -> tuple[float, str, int | None, np.ndarray | None] | None:
    """``(stamp, sender, winner, b)`` of a well-formed ObstacleField map for sensor
    ``index``, else None."""
    if type(m) is not dict or m.keys() != _OBSTACLE_FIELD_KEYS or not _envelope_ok(m, _FIELD_OBSTACLE):
        return None
    i, s, b = m["index"], m["winner"], m["b"]
    if type(i) is not int or i != index:
        return None
    if s is None and b is None:
        return m["stamp"], m["sender"], None, None
    b = vectors.vector(b)
    if b is None or type(s) is not int or not 0 <= s < b.shape[0]:
        return None
    return m["stamp"], m["sender"], s, b


def target_field_values(m: Any, vectors: VectorCache) -> tuple[float, str, int, np.ndarray, float, float] | None:
    """``(stamp, sender, winner, a, alpha, d)`` of a well-formed TargetField map with a
    field (a target sensed, short of the goal), else None."""
    if type(m) is not dict or m.keys() != _TARGET_FIELD_KEYS or not _envelope_ok(m, _FIELD_TARGET):
        return None
    s, alpha, d = m["winner"], m["alpha"], m["d"]
    if (m["at_goal"] is not False or type(alpha) is not float or not -_ANGLE_LIMIT <= alpha <= _ANGLE_LIMIT
            or type(d) is not float or not 0.0 <= d < _INF):
        return None
    a = vectors.vector(m["a"])
    if a is None or type(s) is not int or not 0 <= s < a.shape[0]:
        return None
    return m["stamp"], m["sender"], s, a, alpha, d


class Splice:
    """The wire bytes of messages equal to ``template`` but for the float fields ``fields``:
    ``Splice(msg, ("stamp",))(t) == encode(msg with stamp t)``.

    The bytes between the changing values are packed once; a call packs only the given
    values, which must be valid for their fields (finite floats, as a decoded message's
    are). A msgpack map is its header followed by each key and value, so the pieces are
    exact; the constructor checks that they join to ``encode(template)``."""

    __slots__ = ("fields", "_static")

    def __init__(self, template: Message, fields: tuple[str, ...] = ("stamp",)) -> None:
        wire = to_wire(template)
        missing = [f for f in fields if f not in wire]
        if missing:
            raise ValueError(f"{type(template).__name__} has no field {missing[0]!r}")
        n = len(wire)
        head = bytes([0x80 | n]) if n < 16 else b"\xde" + n.to_bytes(2, "big")
        pieces, current = [], [head]
        for k, v in wire.items():
            current.append(_packb(k, use_bin_type=True))
            if k in fields:
                pieces.append(b"".join(current))
                current = []
            else:
                current.append(_packb(v, use_bin_type=True))
        pieces.append(b"".join(current))
        self.fields = tuple(k for k in wire if k in fields)  # in wire order
        self._static = tuple(pieces)
        if self(*(wire[k] for k in self.fields)) != encode(template):  # pragma: no cover - encode changed
            raise AssertionError("Splice's pieces do not join to encode(template)")

    def __call__(self, *values: float) -> bytes:
        """The bytes with ``values`` for ``self.fields``, in that order."""
        static = self._static
        out = [static[0]]
        for i, v in enumerate(values, 1):
            out.append(_packb(v))
            out.append(static[i])
        return b"".join(out)
