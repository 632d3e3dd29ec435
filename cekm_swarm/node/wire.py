"""A node process's wire: decoding what it receives and encoding what it sends, fast where
the messages repeat, always giving exactly what :func:`~cekm_swarm.protocol.decode` and
:func:`~cekm_swarm.protocol.encode` give (tested on random sequences).

* :class:`Decoder`: a reading or a field through the protocol's fast checks
  (:mod:`cekm_swarm.protocol.hotpath`: a few us instead of a full decode; a field's vector
  checked once per distinct vector), anything else through the full decode.
* :class:`Encoder`: a message whose only change from one it sent before is its stamp (an
  obstacle field of the same winner: the tabulated row of Eq. 8) is spliced from the
  earlier bytes, only the stamp packed; anything else is encoded in full.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

from cekm_swarm.protocol import (DropCounter, KeyKind, KeySpace, KeySpaceError, ObstacleField, SenseRange, SenseTarget,
                                 TargetField, encode)
from cekm_swarm.protocol.hotpath import (Splice, VectorCache, obstacle_field_values, sense_range_values,
                                         sense_target_values, target_field_values, unpack)


def _trusted(cls: type, **values: Any) -> Any:
    """A message built from values the fast checks passed (they are what ``decode`` accepts
    and builds): set as they are, without checking them again."""
    msg = object.__new__(cls)
    for k, v in values.items():
        setattr(msg, k, v)
    return msg


class Decoder:
    """Validated messages from (key, kind, payload); malformed ones dropped and counted."""

    def __init__(self, keys: KeySpace, drops: DropCounter) -> None:
        self.keys, self.drops = keys, drops
        self.vectors = VectorCache()
        self._index: dict[str, int | None] = {}

    def _key_index(self, key: str) -> int | None:
        hit = self._index.get(key, -1)
        if hit == -1:
            try:
                hit = self.keys.parse(key).index
            except KeySpaceError:
                hit = None
            if len(self._index) < 4096:
                self._index[key] = hit
        return hit

    def decode(self, key: str, kind: KeyKind, payload: bytes) -> Any:
        fast = None
        if kind is KeyKind.SENSE_RANGE or kind is KeyKind.FIELD_OBSTACLE or kind is KeyKind.FIELD_TARGET \
                or kind is KeyKind.SENSE_TARGET:
            fast = self._fast(key, kind, payload)
        return fast if fast is not None else self.drops.decode(key, payload, expect=kind)

    def _fast(self, key: str, kind: KeyKind, payload: bytes) -> Any:
        m = unpack(payload)
        if kind is KeyKind.SENSE_RANGE:
            j = self._key_index(key)
            u = None if j is None else sense_range_values(m, j)
            if u is None:
                return None
            return _trusted(SenseRange, stamp=u[0], sender=m["sender"], index=j, alpha=u[1], d=u[2])
        if kind is KeyKind.FIELD_OBSTACLE:
            j = self._key_index(key)
            u = None if j is None else obstacle_field_values(m, j, self.vectors)
            if u is None:
                return None
            return _trusted(ObstacleField, stamp=u[0], sender=u[1], index=j, winner=u[2], b=u[3])
        if kind is KeyKind.FIELD_TARGET:
            u = target_field_values(m, self.vectors)
            if u is None:
                return None
            return _trusted(TargetField, stamp=u[0], sender=u[1], winner=u[2], a=u[3], alpha=u[4], d=u[5],
                            at_goal=False)
        u = sense_target_values(m)
        if u is None:
            return None
        return _trusted(SenseTarget, stamp=u[0], sender=m["sender"], alpha=u[1], d=u[2], visible=u[3])


class Encoder:
    """The wire bytes of outgoing messages: ``encoder(msg) == encode(msg)``.

    A message with arrays is spliced when its arrays are the very objects (read-only) and
    its other fields the values of one it sent before, but for the stamp: a field of the
    same winner is the same row of the same table (``CooperativeEKM.obstacle_activity``).
    The arrays are kept referenced while cached, so their identity stays theirs."""

    LIMIT = 1024

    def __init__(self) -> None:
        self._seen: OrderedDict[tuple, Any] = OrderedDict()  # identity -> Splice, or the arrays seen once

    def __call__(self, msg: Any) -> bytes:
        if not msg._ARRAYS:  # small messages: a full encode costs what a lookup would
            return encode(msg)
        parts: list[Any] = [type(msg), msg.sender]
        for name in msg._BODY:
            v = getattr(msg, name)
            if v is None or type(v) in (bool, int, float, str):
                parts.append(v)
            elif type(v) is np.ndarray and not v.flags.writeable:
                parts.append(id(v))
            else:
                return encode(msg)  # maps, lists, writeable arrays: in full
        ident = tuple(parts)
        hit = self._seen.get(ident)
        if type(hit) is Splice:
            return hit(msg.stamp)
        if hit is None:  # first sight: remember it (and hold its arrays), encode in full
            self._remember(ident, tuple(getattr(msg, n) for n in msg._ARRAYS))
            return encode(msg)
        splice = Splice(msg, ("stamp",))  # seen again: worth a splice
        self._remember(ident, splice, hit)
        return splice(msg.stamp)

    def _remember(self, ident: tuple, value: Any, arrays: Any = None) -> None:
        self._seen[ident] = value if arrays is None else value
        if arrays is not None:
            self._held = getattr(self, "_held", {})
            self._held[ident] = arrays
        if len(self._seen) > self.LIMIT:
            old, _ = self._seen.popitem(last=False)
            getattr(self, "_held", {}).pop(old, None)
