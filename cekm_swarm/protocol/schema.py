"""What a message declaration is made of: the field types, and the checks they give.

Every message of the protocol (:mod:`.messages`) and every entry of the world state is a
:class:`msgspec.Struct` whose fields are typed with the aliases below: a Python type with
its constraints (``Annotated[float, Meta(ge=..., le=...)]``). That one declaration gives

* the **wire decoder**: msgspec decodes the msgpack bytes against the declared types and
  constraints (:mod:`.codec`), in C: a field of the wrong type, out of range, missing or
  unexpected never becomes a message;
* the **construction check**: building a message (``SenseRange(t, "world", 3, 0.5,
  None)``) checks and normalizes every field against the same declared types and
  constraints (compiled into one function per class, with an inline
  test per field for the well-formed case: numpy scalars become floats and ints, tuples
  and lists the declared tuples, arrays read-only float64 vectors), then runs the
  class's own rules between fields (:meth:`Record.check`), so an invalid message can
  neither be sent nor come out of the decoder, and a decoded message equals the one
  that was built (what makes ``cekm run`` equal a lockstep launch bit for bit);
  :mod:`.checks` compiles it from the declared types;
* the **error text**: every failure is a :class:`~.errors.MessageFieldError` naming the
  field (``targets.t1[1]``, ``robots.r1.x``) and the problem.

Field types (what a newcomer meets in :mod:`.messages`): :data:`Stamp`, :data:`Sender`,
:data:`Finite`, :data:`Angle`, :data:`Distance`, :data:`Weight`, :data:`SensorIndex`,
:data:`Neuron`, :data:`Count`, :data:`Vector`, :data:`Point`, :data:`Pose`,
:data:`TargetId`, :data:`EntryId`, :data:`RobotId` and :data:`Plain`.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator
from typing import Annotated, Any, ClassVar

import numpy as np
from msgspec import Meta

from .checks import MAX_ARRAY_LEN, Record
from .keys import KeyKind

SCHEMA_VERSION = 1
"""The version of the wire format this code writes and accepts."""

MSGPACK_ENCODING = "application/msgpack"
"""The Zenoh encoding label of every payload."""

MAX_SENDER_LEN = 128
MAX_INDEX = 1024  # sanity bound for indices in payloads; the key space bounds sensor indices exactly
MAX_TARGETS = 4096
"""Sanity bound on the number of targets in one message."""
ANGLE_LIMIT = math.pi + 1e-9
_BIG = sys.float_info.max  # ge=-_BIG, le=_BIG: finite (NaN and infinities fail both)

# --------------------------------------------------------------------------- field types

Finite = Annotated[float, Meta(ge=-_BIG, le=_BIG)]
"""A finite number (an int is taken as its float)."""
Stamp = Annotated[float, Meta(ge=0.0, le=_BIG)]
"""Sim time in seconds: finite, >= 0 (which stamps a receiver believes: :mod:`.stamps`)."""
Angle = Annotated[float, Meta(ge=-ANGLE_LIMIT, le=ANGLE_LIMIT, description="an angle in [-pi, pi]")]
"""An angle in radians, in [-pi, pi]."""
Distance = Annotated[float, Meta(ge=0.0, le=_BIG)]
"""A finite distance >= 0, in metres."""
Weight = Annotated[float, Meta(ge=0.0, le=_BIG)]
"""A finite weight >= 0."""
Sender = Annotated[str, Meta(min_length=1, max_length=MAX_SENDER_LEN)]
"""Who sent a message (``world``, ``r1/obstacle-3``)."""
SensorIndex = Annotated[int, Meta(ge=0, lt=MAX_INDEX)]
"""A distance sensor's index j (the decoder also holds it to the key's and the key space's)."""
Neuron = Annotated[int, Meta(ge=0, lt=MAX_ARRAY_LEN)]
"""A neuron's index in its map (a winner; the message holds it to its field's length)."""
Count = Annotated[int, Meta(ge=0, le=(1 << 63) - 1)]
"""A tick number or sequence number."""
Vector = np.ndarray
"""A finite float64 vector of 1..2^20 values, held read-only; on the wire the map
``{"dtype": "<f8", "shape": [n], "data": <n * 8 raw little-endian bytes>}`` (:class:`~.checks.WireVector`)."""
Point = tuple[Finite, Finite]
"""(x, y) in metres, in the world frame."""
Pose = tuple[Finite, Finite, Angle]
"""(x, y, theta) in the world frame."""
TargetId = Annotated[str, Meta(min_length=1, max_length=64)]
"""A target's id (1..64 characters)."""
EntryId = Annotated[str, Meta(min_length=1, max_length=256)]
"""The id of a target or a moving obstacle in the world state (a scenario's id)."""
RobotId = Annotated[str, Meta(pattern=r"^(?!world\Z)[A-Za-z][A-Za-z0-9_-]{0,63}\Z",
                              description="a robot id (a letter, then letters, digits, '_' or '-', at most 64; "
                                          "'world' is reserved)")]
"""A robot id, as the key space takes it (:func:`~.keys.validate_robot_id`)."""
Plain = Any
"""Plain data: None, bool, int (64 bits), finite float, str, and lists and string-keyed
maps of them, at most :data:`~.checks.MAX_DEPTH` levels deep (tuples become lists)."""


# --------------------------------------------------------------------------- records


class Entry(Record):
    """An entry of the world state. It reads like the map ``World.state()`` gives (``r["x"]``,
    ``r.get("goal")``), so drawing code takes either."""

    def __getitem__(self, name: str) -> Any:
        if name in self.__struct_fields__:
            return getattr(self, name)
        raise KeyError(name)

    def get(self, name: str, default: Any = None) -> Any:
        return getattr(self, name) if name in self.__struct_fields__ else default

    def keys(self) -> tuple[str, ...]:
        return self.__struct_fields__

    def items(self) -> Iterator[tuple[str, Any]]:
        return ((n, getattr(self, n)) for n in self.__struct_fields__)

    def __iter__(self) -> Iterator[str]:
        return iter(self.__struct_fields__)

    def __len__(self) -> int:
        return len(self.__struct_fields__)

    def __contains__(self, name: object) -> bool:
        return name in self.__struct_fields__


MESSAGE_TYPES: dict[KeyKind, type[Message]] = {}
"""The message class of each key kind (liveliness keys carry no message), in declaration order."""


class Message(Record):
    """A message of the protocol: the envelope (``stamp``, ``sender``), then its own fields.
    ``KIND`` is the kind of key it travels on."""

    stamp: Stamp
    sender: Sender
    KIND: ClassVar[KeyKind]

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        kind = cls.__dict__.get("KIND")
        if kind is not None:
            MESSAGE_TYPES[kind] = cls

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        for name in self.__struct_fields__:
            a, b = getattr(self, name), getattr(other, name)
            if type(a) is np.ndarray or type(b) is np.ndarray:
                if a is None or b is None or not np.array_equal(a, b):
                    return False
            elif a != b:
                return False
        return True

    __hash__ = None  # type: ignore[assignment]
