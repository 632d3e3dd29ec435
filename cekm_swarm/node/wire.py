"""A node process's wire: what it receives decoded, what it sends encoded, both by the
protocol's one declaration of each message (:mod:`cekm_swarm.protocol.codec`: msgspec
decodes and encodes in C, a few us a message, so there is no second, faster copy of any
message's checks to keep equal to the first).

* :class:`Decoder`: a received payload as a validated message of the key's kind, or None
  (dropped and counted, with the key, the field and the problem).
* :class:`Encoder`: a message's wire bytes.
"""

from __future__ import annotations

from cekm_swarm.protocol import DropCounter, KeyKind, KeySpace, Message, encode


class Decoder:
    """Validated messages from (key, kind, payload); malformed ones dropped and counted."""

    def __init__(self, keys: KeySpace, drops: DropCounter) -> None:
        self.keys, self.drops = keys, drops

    def decode(self, key: str, kind: KeyKind, payload: bytes) -> Message | None:
        """The message on ``key`` (of kind ``kind`` on a graph's own key), or None when dropped."""
        return self.drops.decode(key, payload, expect=kind)


class Encoder:
    """The wire bytes of outgoing messages: ``encoder(msg) == encode(msg)``."""

    def __call__(self, msg: Message) -> bytes:
        return encode(msg)
