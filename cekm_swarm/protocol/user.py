"""A user's own typed messages: a message type declared in the user's module, as the
shipped ones are, and given what they have: a decoder against its declaration (a message
that does not fit is dropped and counted), a type the graph check compares between the
nodes that send and read it, decoded lines in ``cekm topic echo`` and ``cekm log cat``.

>>> from cekm_swarm.protocol import Angle, Distance, UserMessage
>>> class FreeDirection(UserMessage):
...     '''The freest direction (rad, robot frame) and how far it is free (m).'''
...     alpha: Angle
...     clearance: Distance
>>> FreeDirection(0.256, "r1/free", 0.3, 0.5).alpha
0.3

It travels on a node's own key as ``{"v": 1, "kind": "data", "type": "FreeDirection",
"stamp", "sender", <its fields in order>}``. Its name on the wire is the class's name, or
``TYPE = "..."`` when it sets one; its kind in a graph is ``data:FreeDirection``. A process
that has not imported the declaration (the world's recorder, ``cekm topic echo`` without
the module on its path) still checks the envelope and reads the fields as plain data
(:class:`UntypedData`)."""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any, ClassVar, get_type_hints

import msgspec

from .errors import MessageKindError
from .keys import KeyKind
from .schema import MESSAGE_TYPES, Message, Plain, Sender, Stamp  # noqa: F401 - Stamp, Sender: the envelope

USER_TYPES: dict[str, type[UserMessage]] = {}
"""Every user message type this process has declared, by its name on the wire."""

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.-]{0,63}\Z")


class UserMessage(Message):
    """Base class of a message type of the user's own: subclass it and declare its fields
    with the protocol's field types (:mod:`.schema`: ``Finite``, ``Angle``, ``Distance``,
    ``Count``, ``Vector``, ...) or plain Python types; override :meth:`check` for rules
    between fields. Build it as any message, ``FreeDirection(t, sender, alpha, clearance)``,
    or let the runner fill in the envelope: a step may return ``{"free": {"alpha": 0.3,
    "clearance": 0.5}}``."""

    TYPE: ClassVar[str]

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        name = cls.__dict__.get("TYPE") or cls.__name__
        if not _NAME.match(name):
            raise TypeError(f"{cls.__qualname__}: message type name {name!r} must be a letter, then at most 63 "
                            f"letters, digits, '_', '-' or '.'")
        clash = sorted({"v", "kind", "type"} & set(cls.__dict__.get("__annotations__", {})))
        if clash:
            raise TypeError(f"{cls.__qualname__}: field {clash[0]!r} is a name of the envelope (v, kind, type, stamp, "
                            f"sender); call it something else")
        cls.TYPE = name
        USER_TYPES[name] = cls


UserMessage.KIND = KeyKind.DATA  # set after the class: it is no kind's one message class (Data is)


class UntypedData(Message):
    """A user message whose declaration this process has not imported: its envelope
    checked, its ``type`` name and its fields as plain data (``values``), in order."""

    type: str
    values: dict[str, Plain]


UntypedData.KIND = KeyKind.DATA


class Nothing(Message):
    """What a node sent on an output at ``stamp`` when its step gave None for it: nothing
    this tick. A reader's step sees None for a one-key port and no entry in a many-key
    port's dict; in lockstep it tells the reader not to wait for that value. On the wire
    ``{"v": 1, "kind": "none", "stamp", "sender"}``."""


Nothing.KIND = KeyKind.DATA  # never the kind of a key: a reader meets it on the output's own key

NOTHING_HEAD = b"\x84\xa1v\x01\xa4kind\xa4none"
"""How the wire bytes of a :class:`Nothing` begin (a msgpack map of 4: v = 1, kind = none)."""


def json_schema(cls: type[UserMessage]) -> dict[str, Any]:
    """A JSON Schema of user message type ``cls`` as it travels (its map's fields, their
    types and ranges, its docstring): what the run's MCAP log keeps for its channels, so a
    reader without the declaration knows what the fields are."""
    hints = get_type_hints(cls, include_extras=True)
    props: dict[str, Any] = {"v": {"const": 1}, "kind": {"const": "data"}, "type": {"const": cls.TYPE}}
    for name in cls.__struct_fields__:
        try:
            props[name] = msgspec.json.schema(hints[name])
        except (TypeError, ValueError):  # a Vector: its wire map
            props[name] = {"description": "a float64 vector: {dtype: '<f8', shape: [n], data: n * 8 bytes}"}
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": cls.TYPE,
            "description": " ".join((cls.__doc__ or "").split()), "type": "object", "properties": props,
            "required": list(props)}


def user_schemas(types: Iterable[type]) -> dict[str, dict[str, Any]]:
    """``{kind: JSON Schema}`` of every user message type among ``types`` (``data:FreeDirection``)."""
    return {kind_of(t): json_schema(t) for t in types if isinstance(t, type) and issubclass(t, UserMessage)}


def kind_of(cls: type[Message]) -> str:
    """The kind a graph gives a port of message class ``cls``: ``field/target`` for the
    protocol's, ``data:FreeDirection`` for a user's type."""
    if isinstance(cls, type) and issubclass(cls, UserMessage):
        return f"data:{cls.TYPE}"
    return cls.KIND.value


def is_message_type(cls: Any) -> bool:
    """True for a protocol message class and for a user's :class:`UserMessage` type."""
    return cls in MESSAGE_TYPES.values() or (isinstance(cls, type) and issubclass(cls, UserMessage)
                                              and cls is not UserMessage)


def expect_of(kind: str) -> Any:
    """What :func:`~.codec.decode` expects on a key of graph kind ``kind``: a KeyKind, the
    user's class when this process declared it, or its type name (decoded as :class:`UntypedData`)."""
    if kind.startswith("data:"):
        name = kind[5:]
        return USER_TYPES.get(name, name)
    try:
        return KeyKind(kind)
    except ValueError:
        raise MessageKindError(f"message kind {kind!r} is not a kind of the protocol") from None


class ParamChange(UserMessage):
    """A parameter of a running node changed (``cekm param set``): the node sends it on its
    parameter key (``<root>/<robot>/param/<node>``, :meth:`~.keys.KeySpace.param`) when the
    change applies, stamped with the sim time of the node's first run with the new value,
    so the run's log (``run.mcap``) holds every change beside the messages it changed.
    ``value`` and ``was``: the parameter's new and previous values (plain data)."""

    TYPE: ClassVar[str] = "cekm.ParamChange"
    node: str
    name: str
    value: Plain
    was: Plain


PARAM_CHANGE_KIND = kind_of(ParamChange)
"""The graph kind of a parameter key (``data:cekm.ParamChange``): what the world's recorder expects on it."""
