"""Encoding and decoding the declared messages (:mod:`.messages`), both from the one
declaration of each message.

* :func:`encode`: msgspec packs the message's fields in declaration order after the
  envelope's ``v`` and ``kind``: the bytes are those of ``msgpack.packb`` of the wire map
  (tested against it), so logs written before read the same.
* :func:`decode`: msgspec decodes the bytes against a wire type generated from the
  message's declaration (the envelope's ``v`` and ``kind`` as literals, then every field
  with its declared type and constraints, all required, nothing else allowed; vectors as
  :class:`~.checks.WireVector`), and the message is built from it (its construction
  check: vectors to read-only float64 arrays, the message's rules). Bytes it refuses are
  read again with msgpack to say precisely why (:func:`_explain`): the key, the field and
  the problem. Only refusals pay for that.
"""

from __future__ import annotations

import math
import re
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints

import msgpack
import msgspec
import numpy as np

from .checks import _CHECKS, Record, WireVector, wire_vector
from .errors import (
    KeySpaceError,
    MessageError,
    MessageFieldError,
    MessageFormatError,
    MessageKindError,
    MessageVersionError,
)
from .keys import DEFAULT_KEYS, KeyKind, KeySpace
from .schema import MESSAGE_TYPES, SCHEMA_VERSION, Message
from .user import NOTHING_HEAD, USER_TYPES, Nothing, UntypedData, UserMessage, is_message_type

_F8 = np.dtype("<f8")


# --------------------------------------------------------------------------- encode


def _enc_hook(x: Any) -> Any:
    if type(x) is np.ndarray:
        if x.dtype is not _F8 or not x.flags.c_contiguous:
            x = np.ascontiguousarray(x, dtype=_F8)
        return {"dtype": "<f8", "shape": [x.shape[0]], "data": x.tobytes()}
    raise TypeError(f"{type(x).__name__} is not a field type of the protocol")


_encoder = msgspec.msgpack.Encoder(enc_hook=_enc_hook)
_HEADS: dict[type, bytes] = {}


def _head(cls: type[Message]) -> bytes:
    """The wire map's header and its envelope entries ``v`` and ``kind`` (and a user type's
    ``type``): what comes before the message's own fields (msgspec packs those as a map of
    their own, whose one-byte header this replaces)."""
    user = issubclass(cls, UserMessage)
    n = len(cls.__struct_fields__) + 2 + user
    if n > 15:  # a declaration past 12 (a user's: 11) fields of its own
        raise TypeError(f"{cls.__name__}: more fields than one msgpack fixmap holds (at most {15 - 2 - user})")
    head: bytes = bytes([0x80 | n]) + msgpack.packb("v") + msgpack.packb(SCHEMA_VERSION) + \
        msgpack.packb("kind") + msgpack.packb(cls.KIND.value)
    if issubclass(cls, UserMessage):
        head += msgpack.packb("type") + msgpack.packb(cls.TYPE)
    _HEADS[cls] = head
    return head


def encode(msg: Message) -> bytes:
    """The msgpack bytes of ``msg`` (already checked when it was built)."""
    head = _HEADS.get(type(msg))
    if head is None:
        if type(msg) is Nothing:
            return NOTHING_HEAD + _encoder.encode({"stamp": msg.stamp, "sender": msg.sender})[1:]
        if type(msg) is UntypedData:
            return _encoder.encode({"v": SCHEMA_VERSION, "kind": KeyKind.DATA.value, "type": msg.type,
                                    "stamp": msg.stamp, "sender": msg.sender, **msg.values})
        if not is_message_type(type(msg)):
            raise MessageKindError(f"{type(msg).__name__} is not a protocol message")
        head = _head(type(msg))
    return head + _encoder.encode(msg)[1:]


def to_wire(msg: Message) -> dict[str, Any]:
    """The map that :func:`encode` packs: the envelope, then the kind's fields in order."""
    doc: dict[str, Any] = msgpack.unpackb(encode(msg), raw=False)
    return doc


# --------------------------------------------------------------------------- decode


def _wire_type(t: Any) -> Any:
    """The declared annotation ``t`` as the wire carries it: a vector as its WireVector."""
    if t is np.ndarray:
        return WireVector
    if get_origin(t) in (Union, type(int | None)) and np.ndarray in get_args(t):
        return Union[tuple(_wire_type(a) for a in get_args(t))]  # noqa: UP007 -- built at run time
    return t


class _Codec:
    """Decoding one message class: its generated wire type and decoder."""

    __slots__ = ("cls", "fields", "vectors", "indexed", "decoder", "head", "type")

    def __init__(self, cls: type[Message]) -> None:
        hints = get_type_hints(cls, include_extras=True)
        self.cls = cls
        self.fields = frozenset(cls.__struct_fields__)
        self.vectors = frozenset(n for n in cls.__struct_fields__ if _wire_type(hints[n]) is not hints[n])
        self.indexed = "index" in self.fields  # a sensor's index: held to the key's and the key space's
        self.type = cls.TYPE if issubclass(cls, UserMessage) else None  # a user's type: its name on the wire
        envelope = [("v", Literal[SCHEMA_VERSION]), ("kind", Literal[cls.KIND.value])]
        if self.type is not None:
            envelope.append(("type", Literal[self.type]))
        self.head = len(envelope)
        wire = msgspec.defstruct(
            f"{cls.__name__}Wire", envelope + [(name, _wire_type(hints[name])) for name in cls.__struct_fields__],
            forbid_unknown_fields=True, gc=False)
        self.decoder = msgspec.msgpack.Decoder(wire)


_CODECS: dict[Any, _Codec] = {}


def _codec(kind: Any) -> _Codec | None:
    """The codec of a KeyKind's message class, or of a user's message class."""
    c = _CODECS.get(kind)
    if c is None:
        cls = kind if isinstance(kind, type) else MESSAGE_TYPES.get(kind)
        if cls is None:
            return None
        c = _CODECS[kind] = _Codec(cls)
    return c


def warm() -> int:
    """Make now what the first message of each kind would make: every kind's decoder and
    envelope head, and every record class's compiled check. A fork server calls it once, so
    the node processes it forks share them instead of each paying 2-6 ms on its first
    messages (in a 30 s lockstep ``tracking-crowd`` run, 84 nodes made them 84 times).
    Returns how many record classes were made ready."""
    for kind, cls in MESSAGE_TYPES.items():
        _codec(kind)
        if cls not in _HEADS:
            _head(cls)
    n, stack = 0, list(Record.__subclasses__())
    while stack:
        sub = stack.pop()
        stack += sub.__subclasses__()
        _CHECKS[sub]  # noqa: B018 - compiled on its first lookup (_Checks.__missing__)
        n += 1
    return n


_PARSED: dict[int, tuple[KeySpace, dict[str, tuple[KeyKind, int | None]]]] = {}
_PARSED_MAX = 4096
_astuple = msgspec.structs.astuple


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
    if type(key) is not str and isinstance(key, KeyKind):
        kind, key_index, where = key, None, key.value
    else:
        where = key if type(key) is str else str(key)
        try:
            kind, key_index = _parse_cached(keys, where)
        except KeySpaceError as exc:
            raise MessageKindError(exc.problem, key=where) from None
    if data[:14] == NOTHING_HEAD:  # 14: len(NOTHING_HEAD); a node's "nothing this tick" on an output
        if kind not in _NOTHING_KINDS:
            raise MessageKindError(f"'nothing' (kind none) is sent only on a node's outputs, not on a key of kind "
                                   f"'{kind.value}'", key=where, field="kind")
        return _nothing(where, data)
    if kind is KeyKind.NODE:
        kind = expect if expect is not None else _payload_kind(data, where)
    what: Any = kind  # a KeyKind, or a user's type (its class, or its name)
    if type(what) is str:  # a user's type by name: its class if declared here, else its envelope and fields
        declared = USER_TYPES.get(what)
        if declared is None:
            return _untyped(what, where, data)
        what = declared
    codec = _CODECS.get(what) or _codec(what)
    if codec is None:
        raise MessageKindError(f"keys of kind '{kind.value}' carry no message", key=where)
    try:
        wire = codec.decoder.decode(data)
    except Exception as exc:  # noqa: BLE001 - msgspec's ValidationError, DecodeError, RecursionError ...
        raise _explain(codec, kind, where, data, exc) from None
    try:
        msg = codec.cls(*_astuple(wire)[codec.head:])
    except MessageError as exc:
        raise exc.at_key(where) from None
    if codec.indexed:
        index = msg.index  # type: ignore[attr-defined]
        if key_index is not None and index != key_index:
            raise MessageFieldError(f"index {index} differs from the key's sensor index {key_index}",
                                    key=where, field="index")
        if not key_index_ok(keys, index):
            raise MessageFieldError(f"{index} out of range 0..{keys.range_sensors - 1}", key=where, field="index")
    return msg


def _explain(codec: _Codec, kind: KeyKind, where: str, data: Any, refusal: BaseException) -> MessageError:
    """Why the decoder refused ``data``: the bytes read again with msgpack, the envelope and
    the fields checked in turn (the message's construction check names the field and the
    problem); msgspec's own words when none of that finds it."""
    m = _unpacked(data, where)
    if not isinstance(m, dict):
        return m
    wrong = _envelope_problem(codec, m, where)
    if wrong is not None:
        return wrong
    try:
        for name in codec.vectors:
            if m[name] is not None:
                m[name] = wire_vector(m[name], name)  # a vector must come as its wire map
        codec.cls(**m)
    except MessageError as exc:
        return exc.at_key(where)
    except Exception as exc:  # noqa: BLE001 - whatever it is, the bytes are refused with msgspec's reason
        refusal = exc
    return _from_msgspec(refusal, where)


def _unpacked(data: Any, where: str) -> dict[Any, Any] | MessageError:
    """The refused bytes read again with msgpack: the map, or why they are not one."""
    try:
        m = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except msgpack.ExtraData as exc:  # one msgpack object, then more bytes
        more = f"{len(exc.extra)} more byte{'s' if len(exc.extra) != 1 else ''}"
        if type(exc.unpacked) is dict:
            return MessageFormatError(f"trailing bytes after the msgpack map ({more})", key=where)
        return MessageFormatError(f"not a msgpack map: a msgpack {_msgpack_type(exc.unpacked)} followed by {more}",
                                  key=where)
    except Exception as exc:  # noqa: BLE001 - msgpack raises ValueError, FormatError, StackError, TypeError ...
        why = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
        return MessageFormatError(f"not valid msgpack ({why})", key=where)
    if type(m) is not dict:
        return MessageFormatError(f"not a msgpack map: a msgpack {_msgpack_type(m)}", key=where)
    return m


def _envelope_problem(codec: _Codec, m: dict[Any, Any], where: str) -> MessageError | None:
    """What is wrong with a refused map's envelope (version, kind, type) or its set of
    fields; None when they are right. Takes the envelope's fields out of ``m``."""
    if "v" not in m:
        return MessageVersionError("missing schema version field 'v'", key=where, field="v")
    v = m.pop("v")
    if type(v) is not int or v != SCHEMA_VERSION:
        return MessageVersionError(f"schema version {v!r}, this code speaks {SCHEMA_VERSION}", key=where, field="v")
    mkind = m.pop("kind", None)
    want = codec.cls.KIND.value
    if mkind != want:
        return MessageKindError(f"message kind {mkind!r} does not match the key's kind '{want}'",
                                key=where, field="kind")
    if codec.type is not None or "type" in m:
        mtype = m.pop("type", None)
        if mtype != codec.type:
            return MessageKindError(f"message type {mtype!r}, the key carries {codec.type or 'data'}",
                                    key=where, field="type")
    if m.keys() != codec.fields:
        missing = sorted(codec.fields - m.keys())
        if missing:
            return MessageFieldError("missing", key=where, field=missing[0])
        return MessageFieldError("unexpected field", key=where, field=sorted(map(str, m.keys() - codec.fields))[0])
    return None


_MSGPACK_TYPES = {bool: "boolean", int: "integer", float: "float", str: "string", bytes: "binary", list: "array",
                  type(None): "nil"}


def _msgpack_type(x: Any) -> str:
    """The msgpack name of a decoded object's type (``ExtType``: extension)."""
    return _MSGPACK_TYPES.get(type(x), "extension" if isinstance(x, msgpack.ExtType) else type(x).__name__)


_AT = re.compile(r" - at `\$\.?([A-Za-z_][A-Za-z0-9_]*)?[^`]*`$")


def _from_msgspec(exc: BaseException, where: str) -> MessageError:
    """msgspec's refusal as a MessageError naming the top-level field its path starts with."""
    text = str(exc) or type(exc).__name__
    m = _AT.search(text)
    field = m.group(1) if m else None
    problem = text[:m.start()] if m else text
    problem = problem[:1].lower() + problem[1:]
    if field == "v":
        return MessageVersionError(problem, key=where, field=field)
    if field == "kind":
        return MessageKindError(problem, key=where, field=field)
    if field is None and not isinstance(exc, msgspec.ValidationError):
        return MessageFormatError(f"not valid msgpack ({problem})", key=where)
    return MessageFieldError(problem, key=where, field=field)


def _payload_kind(data: bytes | bytearray | memoryview, where: str) -> Any:
    """The kind a payload on a graph's own key says it is (checked again by the decode): a
    KeyKind, or a user's type (its class when declared here, else its name)."""
    got, _ = peek(data)
    if got == KeyKind.DATA.value:
        name = peek_type(data)
        if name is not None:
            return USER_TYPES.get(name, name)
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


class _Peek(msgspec.Struct, gc=False):
    kind: Any = None
    stamp: Any = None


_peek = msgspec.msgpack.Decoder(_Peek)


class _PeekType(msgspec.Struct, gc=False):
    type: Any = None


_peek_type = msgspec.msgpack.Decoder(_PeekType)


def _plain_vector(v: Any) -> Any:
    """A wire vector (:class:`~.checks.WireVector`'s map) as its list of floats; anything else as it is."""
    if type(v) is dict and v.get("dtype") == "<f8" and type(v.get("data")) is bytes:
        return np.frombuffer(v["data"], dtype=_F8).tolist()
    return v


class _NothingWire(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    v: Literal[SCHEMA_VERSION]  # type: ignore[valid-type]  # msgspec reads the constant's value at run time
    kind: Literal["none"]
    stamp: Any
    sender: Any


_nothing_decoder = msgspec.msgpack.Decoder(_NothingWire)
_NOTHING_KINDS = frozenset({KeyKind.NODE, KeyKind.FIELD_TARGET, KeyKind.FIELD_OBSTACLE, KeyKind.FIELD_TRACKING,
                            KeyKind.SHARE})
"""Where a node may send :class:`~.user.Nothing`: its outputs other than the world's answer
(cmd/wheels), which the world needs every tick."""


def _nothing(where: str, data: Any) -> Message:
    try:
        wire = _nothing_decoder.decode(data)
        return Nothing(wire.stamp, wire.sender)
    except MessageError as exc:
        raise exc.at_key(where) from None
    except Exception as exc:  # noqa: BLE001 - msgspec's refusal
        raise _from_msgspec(exc, where) from None


def peek_type(data: bytes | bytearray | memoryview) -> str | None:
    """The ``type`` a user message's payload names, None when it names none (unvalidated)."""
    try:
        name = _peek_type.decode(data).type
    except Exception:  # noqa: BLE001 - unreadable, whatever the reason
        return None
    return name if type(name) is str else None


def _untyped(name: str, where: str, data: Any) -> Message:
    """A user message of type ``name`` whose declaration this process lacks: the envelope
    checked (version, kind, type, stamp, sender), its fields read as plain data."""
    try:
        m = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except Exception as exc:  # noqa: BLE001 - msgpack's many errors
        raise MessageFormatError(f"not valid msgpack ({type(exc).__name__}: {exc})", key=where) from None
    if type(m) is not dict:
        raise MessageFormatError(f"not a msgpack map: a msgpack {_msgpack_type(m)}", key=where)
    if m.pop("v", None) != SCHEMA_VERSION:
        raise MessageVersionError(f"schema version missing or not {SCHEMA_VERSION}", key=where, field="v")
    if m.pop("kind", None) != KeyKind.DATA.value:
        raise MessageKindError("message kind is not 'data'", key=where, field="kind")
    got = m.pop("type", None)
    if got != name:
        raise MessageKindError(f"message type {got!r}, the key carries {name}", key=where, field="type")
    missing = [f for f in ("stamp", "sender") if f not in m]
    if missing:
        raise MessageFieldError("missing", key=where, field=missing[0])
    stamp, sender = m.pop("stamp"), m.pop("sender")
    values = {k: _plain_vector(v) for k, v in m.items()}
    try:
        return UntypedData(stamp, sender, name, values)
    except MessageError as exc:
        raise exc.at_key(where) from None


def peek(data: bytes | bytearray | memoryview) -> tuple[str | None, float | None]:
    """(kind, stamp) of a payload without validating it, (None, None) when unreadable.

    For recorders that must file even malformed messages at a sim time."""
    try:
        m = _peek.decode(data)
    except Exception:  # noqa: BLE001 - unreadable, whatever the reason
        return None, None
    kind, stamp = m.kind, m.stamp
    kind = kind if type(kind) is str else None
    stamp = float(stamp) if type(stamp) in (int, float) and math.isfinite(stamp) else None
    return kind, stamp


# --------------------------------------------------------------------------- for people


def _plain_hook(x: Any) -> Any:
    if type(x) is np.ndarray:
        return x.tolist()
    raise TypeError(f"{type(x).__name__} is not a field type of the protocol")


def _lists(x: Any) -> Any:
    if type(x) is tuple or type(x) is list:
        return [_lists(v) for v in x]
    if type(x) is dict:
        return {k: _lists(v) for k, v in x.items()}
    return x


def to_plain(msg: Message) -> dict[str, Any]:
    """``msg`` as plain data (arrays and tuples as lists, entries as maps), for printing and JSON;
    a user's message with its ``type``."""
    if type(msg) is Nothing:
        return {"kind": "none", "stamp": msg.stamp, "sender": msg.sender}
    if type(msg) is UntypedData:
        return {"kind": msg.KIND.value, "type": msg.type, "stamp": msg.stamp, "sender": msg.sender,
                **_lists(msgspec.to_builtins(msg.values, enc_hook=_plain_hook))}
    doc = _lists(msgspec.to_builtins(msg, enc_hook=_plain_hook))
    if isinstance(msg, UserMessage):
        return {"kind": msg.KIND.value, "type": msg.TYPE, **doc}
    return {"kind": msg.KIND.value, **doc}


def summary(msg: Message, max_items: int = 6) -> str:
    """A one-line description of ``msg`` (long arrays shortened), for ``topic echo``."""
    what = msg.TYPE if isinstance(msg, UserMessage) else msg.type if type(msg) is UntypedData else \
        "none (nothing sent)" if type(msg) is Nothing else msg.KIND.value
    parts = [f"{what} t={msg.stamp:.3f} from={msg.sender}"]
    fields = msg.values if type(msg) is UntypedData else {n: getattr(msg, n) for n in msg.__struct_fields__[2:]}
    for name, v in fields.items():
        if isinstance(v, np.ndarray):
            head = ", ".join(f"{x:.3g}" for x in v[:max_items])
            more = (f", ... ({v.shape[0]} values, max {v.max():.3g} at {int(v.argmax())})"
                    if v.shape[0] > max_items else "")
            v = f"[{head}{more}]"
        elif isinstance(v, float):
            v = f"{v:.4g}"
        elif isinstance(v, dict | msgspec.Struct):
            v = msgspec.to_builtins(v, enc_hook=_plain_hook)
        parts.append(f"{name}={v}")
    return " ".join(parts)
