"""What a message declaration is made of: the field types, and the checks they give.

Every message of the protocol (:mod:`.messages`) and every entry of the world state is a
:class:`msgspec.Struct` whose fields are typed with the aliases below: a Python type with
its constraints (``Annotated[float, Meta(ge=..., le=...)]``). That one declaration gives

* the **wire decoder**: msgspec decodes the msgpack bytes against the declared types and
  constraints (:mod:`.codec`), in C: a field of the wrong type, out of range, missing or
  unexpected never becomes a message;
* the **construction check**: building a message (``SenseRange(t, "world", 3, 0.5,
  None)``) checks and normalizes every field against the same declared types and
  constraints (:func:`_compile` turns them into one function per class, with an inline
  test per field for the well-formed case: numpy scalars become floats and ints, tuples
  and lists the declared tuples, arrays read-only float64 vectors), then runs the
  class's own rules between fields (:meth:`Record.check`), so an invalid message can
  neither be sent nor come out of the decoder, and a decoded message equals the one
  that was built (what makes ``cekm run`` equal a lockstep launch bit for bit);
* the **error text**: every failure is a :class:`~.errors.MessageFieldError` naming the
  field (``targets.t1[1]``, ``robots.r1.x``) and the problem.

Field types (what a newcomer meets in :mod:`.messages`): :data:`Stamp`, :data:`Sender`,
:data:`Finite`, :data:`Angle`, :data:`Distance`, :data:`Weight`, :data:`SensorIndex`,
:data:`Neuron`, :data:`Count`, :data:`Vector`, :data:`Point`, :data:`Pose`,
:data:`TargetId`, :data:`EntryId`, :data:`RobotId` and :data:`Plain`.
"""

from __future__ import annotations

import math
import operator
import re
import sys
import warnings
from collections.abc import Callable, Iterator
from typing import Annotated, Any, ClassVar, Literal

import msgspec
import msgspec.inspect as mi
import numpy as np
from msgspec import Meta

from .errors import MessageArrayError, MessageFieldError
from .keys import KeyKind

SCHEMA_VERSION = 1
"""The version of the wire format this code writes and accepts."""

MSGPACK_ENCODING = "application/msgpack"
"""The Zenoh encoding label of every payload."""

MAX_SENDER_LEN = 128
MAX_INDEX = 1024  # sanity bound for indices in payloads; the key space bounds sensor indices exactly
MAX_ARRAY_LEN = 1 << 20
MAX_TARGETS = 4096
"""Sanity bound on the number of targets in one message."""
MAX_DEPTH = 16
"""How deeply plain data (:data:`Plain`) may nest."""
ANGLE_LIMIT = math.pi + 1e-9
_BIG = sys.float_info.max  # ge=-_BIG, le=_BIG: finite (NaN and infinities fail both)
_F8 = np.dtype("<f8")

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
``{"dtype": "<f8", "shape": [n], "data": <n * 8 raw little-endian bytes>}`` (:class:`WireVector`)."""
Point = tuple[Finite, Finite]
"""(x, y) in metres, in the world frame."""
Pose = tuple[Finite, Finite, Angle]
"""(x, y, theta) in the world frame."""
TargetId = Annotated[str, Meta(min_length=1, max_length=64)]
"""A target's id (1..64 characters)."""
EntryId = Annotated[str, Meta(min_length=1, max_length=256)]
"""The id of a target or a moving obstacle in the world state (a scenario's id)."""
RobotId = Annotated[str, Meta(pattern=r"^(?!world$)[A-Za-z][A-Za-z0-9_-]{0,63}$",
                              description="a robot id (a letter, then letters, digits, '_' or '-', at most 64; "
                                          "'world' is reserved)")]
"""A robot id, as the key space takes it (:func:`~.keys.validate_robot_id`)."""
Plain = Any
"""Plain data: None, bool, int (64 bits), finite float, str, and lists and string-keyed
maps of them, at most :data:`MAX_DEPTH` levels deep (tuples become lists)."""


class WireVector(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    """A :data:`Vector` as it travels: float64, one dimension, the raw little-endian bytes."""

    dtype: Literal["<f8"]
    shape: tuple[Annotated[int, Meta(ge=1, le=MAX_ARRAY_LEN)]]
    data: bytes


# --------------------------------------------------------------------------- records


class Record(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    """A declared record (a message, or an entry of the world state): checked and
    normalized when built, by its declared field types and then its own :meth:`check`.

    Records are mutable for speed; treat them as immutable once built."""

    def __post_init__(self) -> None:
        _CHECKS[type(self)](self)

    def check(self) -> None:
        """The record's own rules between fields (after every field passed its type)."""


class _Checks(dict):
    """Each record class's compiled check, compiled when the class's first record is built."""

    def __missing__(self, cls: type[Record]) -> Callable[[Record], None]:
        check = self[cls] = _compile(cls)
        return check


_CHECKS = _Checks()


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


# --------------------------------------------------------------------------- the construction check


def _fail(where: str, problem: str) -> MessageFieldError:
    return MessageFieldError(problem, field=where)


Check = Callable[[Any, str], Any]
"""A field type's check: the normalized value, or MessageFieldError naming ``where``."""


def _meta(t: mi.Type) -> tuple[mi.Type, str | None]:
    if isinstance(t, mi.Metadata):
        return t.type, (t.extra_json_schema or {}).get("description")
    return t, None


def _float_check(t: mi.FloatType, what: str | None) -> Check:
    lo = -math.inf if t.ge is None else t.ge
    hi = math.inf if t.le is None else t.le

    def check(x: Any, where: str) -> float:
        if type(x) is not float:
            if type(x) is bool or not isinstance(x, (int, float, np.floating, np.integer)):
                raise _fail(where, f"expected a number, got {type(x).__name__}")
            x = float(x)
        if not math.isfinite(x):
            raise _fail(where, f"not finite ({x})")
        if not lo <= x <= hi:
            raise _fail(where, f"{x} is not {what}" if what else f"{x} is below {lo:g}" if x < lo
                        else f"{x} is above {hi:g}")
        return x

    return check


def _int_check(t: mi.IntType) -> Check:
    lo = 0 if t.ge is None else t.ge
    hi = t.lt if t.lt is not None else None if t.le is None else t.le + 1  # exclusive

    def check(x: Any, where: str) -> int:
        if type(x) is not int:
            if isinstance(x, (bool, np.bool_)):
                raise _fail(where, "expected an integer, got bool")
            try:
                x = operator.index(x)
            except TypeError:
                raise _fail(where, f"expected an integer, got {type(x).__name__}") from None
        if x < lo or (hi is not None and x >= hi):
            raise _fail(where, f"{x} out of range {lo}..{'' if hi is None else hi - 1}")
        return x

    return check


def _str_check(t: mi.StrType, what: str | None) -> Check:
    lo, hi = t.min_length or 0, t.max_length
    pattern = None if t.pattern is None else re.compile(t.pattern)

    def check(x: Any, where: str) -> str:
        if type(x) is not str:
            raise _fail(where, f"expected a string, got {type(x).__name__}")
        if len(x) < lo or (hi is not None and len(x) > hi):
            raise _fail(where, f"must be {lo}..{hi} characters, got {len(x)}")
        if pattern is not None and not pattern.search(x):
            raise _fail(where, f"{x!r} is not {what or 'matching ' + pattern.pattern}")
        return x

    return check


def _bool_check(x: Any, where: str) -> bool:
    if type(x) is bool:
        return x
    if isinstance(x, np.bool_):
        return bool(x)
    raise _fail(where, f"expected a bool, got {type(x).__name__}")


def _tuple_check(items: tuple[Check, ...]) -> Check:
    n = len(items)

    def check(x: Any, where: str) -> tuple:
        if not isinstance(x, (list, tuple, np.ndarray)) or len(x) != n:
            raise _fail(where, f"expected {n} values, got {x!r}"[:200])
        return tuple(c(v, f"{where}[{i}]") for i, (c, v) in enumerate(zip(items, x)))

    return check


def _var_tuple_check(item: Check, max_length: int | None) -> Check:
    def check(x: Any, where: str) -> tuple:
        if not isinstance(x, (list, tuple)):
            raise _fail(where, f"expected a list, got {type(x).__name__}")
        if max_length is not None and len(x) > max_length:
            raise _fail(where, f"{len(x)} entries, at most {max_length}")
        return tuple(item(v, f"{where}[{i}]") for i, v in enumerate(x))

    return check


def _dict_check(key: Check, value: Check, max_length: int | None) -> Check:
    def check(x: Any, where: str) -> dict:
        if not isinstance(x, dict):
            raise _fail(where, f"expected a map, got {type(x).__name__}")
        if max_length is not None and len(x) > max_length:
            raise _fail(where, f"{len(x)} entries, at most {max_length}")
        out = {}
        for k, v in x.items():
            if type(k) is not str:
                raise _fail(where, f"map key {k!r} is not a string")
            out[key(k, f"{where}.{k}")] = value(v, f"{where}.{k}")
        return out

    return check


def _optional_check(inner: Check) -> Check:
    def check(x: Any, where: str) -> Any:
        return None if x is None else inner(x, where)

    return check


def _entry_check(cls: type[Record]) -> Check:
    names = cls.__struct_fields__
    required = {f.name for f in msgspec.structs.fields(cls) if f.required}

    def check(x: Any, where: str) -> Record:
        if type(x) is cls:
            return x  # checked when it was built
        if not isinstance(x, dict):
            raise _fail(where, f"expected a map, got {type(x).__name__}")
        for k in x:
            if k not in names:
                raise _fail(f"{where}.{k}", "unexpected field")
        for k in names:
            if k in required and k not in x:
                raise _fail(f"{where}.{k}", "missing")
        try:
            return cls(**x)
        except MessageFieldError as exc:
            raise _fail(f"{where}.{exc.field}", exc.problem) from None

    return check


def plain(x: Any, where: str, depth: int = 0) -> Any:
    """:data:`Plain` data, normalized (numpy scalars to Python, tuples to lists)."""
    if depth > MAX_DEPTH:
        raise _fail(where, f"nested deeper than {MAX_DEPTH} levels")
    if x is None or type(x) in (bool, str):
        return x
    if type(x) is float:
        if not math.isfinite(x):
            raise _fail(where, f"not finite ({x})")
        return x
    if type(x) is int:
        if not -(1 << 63) <= x < (1 << 64):
            raise _fail(where, f"integer {x} does not fit 64 bits")
        return x
    if isinstance(x, dict):
        out = {}
        for k, v in x.items():
            if type(k) is not str:
                raise _fail(where, f"map key {k!r} is not a string")
            out[k] = plain(v, f"{where}.{k}", depth + 1)
        return out
    if isinstance(x, (list, tuple)):
        return [plain(v, f"{where}[{i}]", depth + 1) for i, v in enumerate(x)]
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.integer):
        return plain(int(x), where, depth)
    if isinstance(x, np.floating):
        return plain(float(x), where, depth)
    raise _fail(where, f"{type(x).__name__} is not plain data (use dict, list, str, int, float, bool, None)")


def wire_vector(m: Any, where: str) -> np.ndarray:
    """The read-only float64 vector of a wire array (a :class:`WireVector`, or its map as
    msgpack gives it); MessageArrayError naming the field for any other layout."""
    if type(m) is WireVector:
        n, data = m.shape[0], m.data
    else:
        if type(m) is not dict:
            raise MessageArrayError(f"expected an array map {{dtype, shape, data}}, got {type(m).__name__}",
                                    field=where)
        if len(m) != 3 or "dtype" not in m or "shape" not in m or "data" not in m:
            raise MessageArrayError(f"array map must have exactly dtype, shape, data; got {sorted(map(str, m))}",
                                    field=where)
        dtype, shape, data = m["dtype"], m["shape"], m["data"]
        if dtype != "<f8":
            raise MessageArrayError(f"dtype {dtype!r}, expected '<f8' (little-endian float64)", field=where)
        if (type(shape) is not list or len(shape) != 1 or type(shape[0]) is not int
                or not 1 <= shape[0] <= MAX_ARRAY_LEN):
            raise MessageArrayError(f"shape {shape!r}, expected [n] with 1 <= n <= {MAX_ARRAY_LEN}", field=where)
        if type(data) is not bytes:
            raise MessageArrayError(f"data must be bytes, got {type(data).__name__}", field=where)
        n = shape[0]
    if len(data) != 8 * n:
        raise MessageArrayError(f"data holds {len(data)} bytes, shape [{n}] needs {8 * n}", field=where)
    return np.frombuffer(data, dtype=_F8)


def _finite(x: np.ndarray, where: str) -> None:
    # One cheap reduction (0.6 us for 225 values): any NaN or infinity makes the sum of
    # squares non-finite; only then, or when finite values beyond 1e154 overflow it, look
    # element by element. (numpy warns of that overflow: a peer's huge values are not
    # this process's floating-point error, so the warning is filtered, for this module.)
    if not math.isfinite(x.dot(x)):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise MessageFieldError(f"not finite at index {int(bad[0])} ({x[bad[0]]})", field=where)


warnings.filterwarnings("ignore", message="overflow encountered in dot", category=RuntimeWarning,
                        module=re.escape(__name__))


def vector(x: Any, where: str) -> np.ndarray:
    """A :data:`Vector`: finite float64, one dimension, 1..2^20 values, read-only (a
    writeable array is held through a read-only view; its owner may still change it)."""
    if type(x) is WireVector:  # as decoded: read-only, one dimension, its length checked
        x = wire_vector(x, where)
        _finite(x, where)
        return x
    if type(x) is not np.ndarray or x.dtype is not _F8:
        if isinstance(x, dict):
            x = wire_vector(x, where)
        else:
            try:
                x = np.asarray(x, dtype=_F8)
            except (TypeError, ValueError) as exc:
                raise MessageArrayError(f"not convertible to float64: {exc}", field=where) from None
    if x.ndim != 1:
        raise MessageArrayError(f"expected a 1-D array, got shape {x.shape}", field=where)
    n = x.shape[0]
    if n == 0 or n > MAX_ARRAY_LEN:
        raise MessageArrayError(f"length {n} outside 1..{MAX_ARRAY_LEN}", field=where)
    _finite(x, where)
    if x.flags.writeable:
        x = x.view()
        x.flags.writeable = False
    return x


def checker(t: mi.Type) -> Check:
    """The check of one declared field type (msgspec's view of its annotation)."""
    t, what = _meta(t)
    if isinstance(t, mi.FloatType):
        return _float_check(t, what)
    if isinstance(t, mi.IntType):
        return _int_check(t)
    if isinstance(t, mi.StrType):
        return _str_check(t, what)
    if isinstance(t, mi.BoolType):
        return _bool_check
    if isinstance(t, mi.UnionType):
        others = [u for u in t.types if not isinstance(u, mi.NoneType)]
        if len(others) != 1 or len(t.types) != 2:
            raise TypeError(f"a field's type may be X or X | None, got {t}")
        return _optional_check(checker(others[0]))
    if isinstance(t, mi.TupleType):
        return _tuple_check(tuple(checker(u) for u in t.item_types))
    if isinstance(t, mi.VarTupleType):
        return _var_tuple_check(checker(t.item_type), t.max_length)
    if isinstance(t, mi.DictType):
        return _dict_check(checker(t.key_type), checker(t.value_type), t.max_length)
    if isinstance(t, mi.AnyType):
        return plain
    if isinstance(t, mi.CustomType) and t.cls is np.ndarray:
        return vector
    if isinstance(t, mi.StructType) and issubclass(t.cls, Record):
        return _entry_check(t.cls)
    raise TypeError(f"no check for field type {t}")


def _guard(t: mi.Type, i: int, ns: dict[str, Any]) -> str | None:
    """A Python expression true for ``x`` already of the declared type and in range (the
    well-formed case, tested inline), or None when the type has none."""
    t, _ = _meta(t)
    if isinstance(t, mi.FloatType):
        ns[f"lo{i}"] = -math.inf if t.ge is None else t.ge
        ns[f"hi{i}"] = math.inf if t.le is None else t.le
        return f"type(x) is float and lo{i} <= x <= hi{i}"
    if isinstance(t, mi.IntType):
        ns[f"lo{i}"] = 0 if t.ge is None else t.ge
        ns[f"hi{i}"] = t.lt if t.lt is not None else (1 << 64) if t.le is None else t.le + 1
        return f"type(x) is int and lo{i} <= x < hi{i}"
    if isinstance(t, mi.StrType) and t.pattern is None:
        ns[f"lo{i}"], ns[f"hi{i}"] = t.min_length or 0, t.max_length or sys.maxsize
        return f"type(x) is str and lo{i} <= len(x) <= hi{i}"
    if isinstance(t, mi.BoolType):
        return "type(x) is bool"
    if isinstance(t, mi.UnionType) and len(t.types) == 2 and isinstance(t.types[1], mi.NoneType):
        inner = _guard(t.types[0], i, ns)
        return None if inner is None else f"x is None or ({inner})"
    return None


def _compile(cls: type[Record]) -> Callable[[Record], None]:
    """The construction check of ``cls``: per field, the inline guard of the well-formed
    case, else the field type's check (which normalizes the value or raises); then the
    class's own :meth:`~Record.check`."""
    info = mi.type_info(cls)
    ns: dict[str, Any] = {}
    lines = ["def check(self):"]
    for i, f in enumerate(info.fields):
        ns[f"c{i}"] = checker(f.type)
        guard = _guard(f.type, i, ns)
        lines.append(f"    x = self.{f.name}")
        if guard is not None:
            lines.append(f"    if not ({guard}):")
            lines.append(f"        self.{f.name} = c{i}(x, {f.name!r})")
        else:
            lines.append(f"    y = c{i}(x, {f.name!r})")
            lines.append(f"    if y is not x:")
            lines.append(f"        self.{f.name} = y")
    if cls.check is not Record.check:
        lines.append("    self.check()")
    if len(lines) == 1:
        lines.append("    pass")
    exec("\n".join(lines), ns)  # noqa: S102 - source built above from the declared field types
    return ns["check"]
