"""A declared record (:class:`Record`, the base of every message and world-state entry of
:mod:`.schema`) and its construction check, compiled from its declared field types: one
function per class that tests each field's well-formed case inline (an exact type and
its range, a few comparisons) and otherwise calls the field type's check, which
normalizes the value (numpy scalars to Python numbers, sequences to the declared tuples,
arrays to read-only float64 vectors) or raises a
:class:`~.errors.MessageFieldError` naming the field (``targets.t1[1]``) and the problem.
The field types are read from msgspec's own view of the declaration
(:func:`msgspec.inspect.type_info`), the same the wire decoder is built from. The wire
form of a vector (:class:`WireVector`) and the limits these checks hold values to live here
too, below :mod:`.schema`, which builds its field types from them.
"""

from __future__ import annotations

import math
import operator
import re
import sys
import warnings
from collections.abc import Callable
from typing import Annotated, Any, Literal

import msgspec
import msgspec.inspect as mi
import numpy as np
from msgspec import Meta

from .errors import MessageArrayError, MessageFieldError

_F8 = np.dtype("<f8")

MAX_ARRAY_LEN = 1 << 20
"""The longest vector a message may hold."""
MAX_DEPTH = 16
"""How deeply plain data (:data:`~.schema.Plain`) may nest."""


class WireVector(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    """A :data:`Vector` as it travels: float64, one dimension, the raw little-endian bytes."""

    dtype: Literal["<f8"]
    shape: tuple[Annotated[int, Meta(ge=1, le=MAX_ARRAY_LEN)]]
    data: bytes


class Record(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    """A declared record (a message, or an entry of the world state): checked and
    normalized when built, by its declared field types and then its own :meth:`check`.

    Records are mutable for speed; treat them as immutable once built."""

    def __post_init__(self) -> None:
        _CHECKS[type(self)](self)

    def check(self) -> None:
        """The record's own rules between fields (after every field passed its type)."""


class _Checks(dict[type[Record], Callable[[Record], None]]):
    """Each record class's compiled check, compiled when the class's first record is built."""

    def __missing__(self, cls: type[Record]) -> Callable[[Record], None]:
        check = self[cls] = compile_check(cls)
        return check


_CHECKS = _Checks()




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
        v: float = x
        if not math.isfinite(v):
            raise _fail(where, f"not finite ({x})")
        if not lo <= x <= hi:
            raise _fail(where, f"{x} is not {what}" if what else f"{x} is below {lo:g}" if x < lo
                        else f"{x} is above {hi:g}")
        return v

    return check


def _int_bounds(t: mi.IntType) -> tuple[int, int]:
    """[lo, hi) of an integer field (64 bits when the declaration does not bound it)."""
    lo = t.ge if t.ge is not None else t.gt + 1 if t.gt is not None else -(1 << 63)
    hi = t.lt if t.lt is not None else t.le + 1 if t.le is not None else 1 << 64
    return lo, hi


def _int_check(t: mi.IntType) -> Check:
    lo, hi = _int_bounds(t)

    def check(x: Any, where: str) -> int:
        if type(x) is not int:
            if isinstance(x, (bool, np.bool_)):
                raise _fail(where, "expected an integer, got bool")
            try:
                x = operator.index(x)
            except TypeError:
                raise _fail(where, f"expected an integer, got {type(x).__name__}") from None
        v: int = x
        if not lo <= v < hi:
            raise _fail(where, f"{v} out of range {lo}..{hi - 1}")
        return v

    return check


PASSED_MAX = 4096
"""Strings a patterned string check remembers as passed (then forgets them all and starts
again): the keys and names a node receives are the same few, tick after tick."""


def _str_check(t: mi.StrType, what: str | None) -> Check:
    lo, hi = t.min_length or 0, t.max_length
    pattern = None if t.pattern is None else re.compile(t.pattern)
    passed: set[str] = set()  # a string is a value: one that passed passes again

    def check(x: Any, where: str) -> str:
        if type(x) is not str:
            raise _fail(where, f"expected a string, got {type(x).__name__}")
        if x in passed:
            return x
        if len(x) < lo or (hi is not None and len(x) > hi):
            raise _fail(where, f"must be {lo}..{hi} characters, got {len(x)}")
        if pattern is not None:
            if not pattern.search(x):
                raise _fail(where, f"{x!r} is not {what or 'matching ' + pattern.pattern}")
            if len(passed) >= PASSED_MAX:
                passed.clear()
            passed.add(x)
        return x

    return check


def _bool_check(x: Any, where: str) -> bool:
    if type(x) is bool:
        return x
    if isinstance(x, np.bool_):
        return bool(x)
    raise _fail(where, f"expected a bool, got {type(x).__name__}")


# A sequence's or a map's entries are checked first under the container's own name, and
# only when one fails once more naming each (``where[i]``, ``where.key``): an entry's name
# is a string built per entry, which cost more than the check of a well-formed one (an
# ``Unchanged`` of ten readings took 27 us to decode, most of it naming them).


def _tuple_check(items: tuple[Check, ...]) -> Check:
    n = len(items)

    def check(x: Any, where: str) -> tuple[Any, ...]:
        if not isinstance(x, (list, tuple, np.ndarray)) or len(x) != n:
            raise _fail(where, f"expected {n} values, got {x!r}"[:200])
        try:
            return tuple([c(v, where) for c, v in zip(items, x, strict=True)])
        except MessageFieldError:
            pass  # said again below, naming the entry
        return tuple(c(v, f"{where}[{i}]") for i, (c, v) in enumerate(zip(items, x, strict=True)))

    return check


def _var_tuple_check(item: Check, max_length: int | None, well_formed: Callable[[Any], bool] | None = None
                     ) -> Check:
    """``well_formed``: the item type's inline guard (:func:`_guard`) as a function, for a
    scalar item type: entries that all pass it are taken as they are."""
    def check(x: Any, where: str) -> tuple[Any, ...]:
        if not isinstance(x, (list, tuple)):
            raise _fail(where, f"expected a list, got {type(x).__name__}")
        if max_length is not None and len(x) > max_length:
            raise _fail(where, f"{len(x)} entries, at most {max_length}")
        if well_formed is not None:
            if all(map(well_formed, x)):
                return x if type(x) is tuple else tuple(x)
        else:
            try:
                return tuple([item(v, where) for v in x])
            except MessageFieldError:
                pass  # said again below, naming the entry
        return tuple(item(v, f"{where}[{i}]") for i, v in enumerate(x))

    return check


def _at(where: str, key: str) -> str:
    """The name of a map's entry in an error: ``where.key``, the key quoted (and cut) when
    it would not print on one line as it is."""
    return f"{where}.{key}" if key.isprintable() and 0 < len(key) <= 64 else f"{where}[{key[:64]!r}]"


def _dict_check(key: Check, value: Check, max_length: int | None) -> Check:
    def check(x: Any, where: str) -> dict[Any, Any]:
        if not isinstance(x, dict):
            raise _fail(where, f"expected a map, got {type(x).__name__}")
        if max_length is not None and len(x) > max_length:
            raise _fail(where, f"{len(x)} entries, at most {max_length}")
        try:
            if all(type(k) is str for k in x):
                return {key(k, where): value(v, where) for k, v in x.items()}
        except MessageFieldError:
            pass  # said again below, naming the entry
        out = {}
        for k, v in x.items():
            if type(k) is not str:
                raise _fail(where, f"map key {k!r} is not a string")
            at = _at(where, k)
            out[key(k, at)] = value(v, at)
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
            out[k] = plain(v, _at(where, k), depth + 1)
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
    # One cheap reduction (0.6 us for 225 values, np.errstate alone costs twice that): any
    # NaN or infinity makes the sum of squares non-finite; only then, or when finite
    # values beyond 1e154 overflow it, look element by element. numpy warns of that
    # overflow, which is a peer's huge values and not this process's floating-point
    # error: the warning is filtered for this module (below), and if warnings are errors
    # the overflow is taken as what it is.
    try:
        energy = x.dot(x)
    except RuntimeWarning:
        energy = math.inf
    if not math.isfinite(energy):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise MessageFieldError(f"not finite at index {int(bad[0])} ({x[bad[0]]})", field=where)


warnings.filterwarnings("ignore", message="overflow encountered in dot", category=RuntimeWarning,
                        module=re.escape(__name__))


def vector(x: Any, where: str) -> np.ndarray:
    """A :data:`Vector`: finite float64, one dimension, 1..2^20 values, read-only (a
    writeable array is held through a read-only view; its owner may still change it)."""
    if type(x) is WireVector:  # as decoded: read-only, one dimension, its length checked
        decoded = wire_vector(x, where)
        _finite(decoded, where)
        return decoded
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
    held: np.ndarray = x
    return held


def checker(t: mi.Type) -> Check:
    """The check of one declared field type (msgspec's view of its annotation)."""
    t, what = _meta(t)
    if isinstance(t, mi.FloatType):
        if t.gt is not None or t.lt is not None or t.multiple_of is not None:
            raise TypeError(f"a float field is bounded with ge and le only, got {t}")
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
        return _var_tuple_check(checker(t.item_type), t.max_length, _well_formed(t.item_type))
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
        ns[f"lo{i}"], ns[f"hi{i}"] = _int_bounds(t)
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


def _well_formed(t: mi.Type) -> Callable[[Any], bool] | None:
    """The inline guard of a scalar type as a function of ``x``, or None (no guard)."""
    ns: dict[str, Any] = {}
    guard = _guard(t, 0, ns)
    if guard is None:
        return None
    exec(f"def well_formed(x):\n    return {guard}", ns)  # noqa: S102 - from the declared type, as below
    well_formed: Callable[[Any], bool] = ns["well_formed"]
    return well_formed


def compile_check(cls: type[Record]) -> Callable[[Record], None]:
    """The construction check of ``cls``: per field, the inline guard of the well-formed
    case, else the field type's check (which normalizes the value or raises); then the
    class's own :meth:`~Record.check`."""
    info = mi.type_info(cls)
    if not isinstance(info, mi.StructType):
        raise TypeError(f"{cls.__name__} is not a record declaration")
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
            lines.append("    if y is not x:")
            lines.append(f"        self.{f.name} = y")
    if cls.check is not Record.check:
        lines.append("    self.check()")
    if len(lines) == 1:
        lines.append("    pass")
    exec("\n".join(lines), ns)  # noqa: S102 - source built above from the declared field types
    check: Callable[[Record], None] = ns["check"]
    return check


# ------------------------------------------------------------------- the model's lattice

LATTICE_KINDS = frozenset({"field/target", "field/obstacle", "field/tracking"})
"""The kinds of message whose vectors hold one value per neuron of the run's motor map
(and whose winners are neurons of it): the fields. Well-formed alone, such a message is
usable only when it fits the lattice of the run's model (:func:`lattice_misfit`)."""


def on_lattice(cls: type) -> bool:
    """Whether messages of type ``cls`` are over the run's lattice (:data:`LATTICE_KINDS`)."""
    kind = getattr(cls, "KIND", None)
    return getattr(kind, "value", None) in LATTICE_KINDS


def lattice_misfit(msg: Any, n: int) -> str | None:
    """Why a field does not fit a lattice of ``n`` neurons (None: it does): what a field's
    reader refuses (drops and counts, :meth:`cekm_swarm.node.Node.check_input`) and what
    its producer's step is refused for (:mod:`cekm_swarm.node.checks`)."""
    for name in ("a", "b"):
        v = getattr(msg, name, None)
        if v is not None and v.shape[0] != n:
            return f"field {name} has {v.shape[0]} values, the model's lattice {n} neurons"
    w = getattr(msg, "winner", None)
    if w is not None and not 0 <= w < n:
        return f"winner {w} outside the lattice's 0..{n - 1}"
    for i, row in enumerate(getattr(msg, "inputs", ()) or ()):
        if not 0 <= row[0] < n:
            return f"inputs[{i}].winner {row[0]} outside the lattice's 0..{n - 1}"
    return None
