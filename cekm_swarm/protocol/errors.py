"""Errors of the message protocol: every one names the key, the field and the problem."""

from __future__ import annotations

from cekm_swarm.errors import CekmError


class ProtocolError(CekmError):
    """Base class of the protocol's errors (key space and messages)."""


class KeySpaceError(ProtocolError, ValueError):
    """A key, key root, robot id, module name or sensor index is not valid."""

    def __init__(self, what: str, problem: str) -> None:
        self.what = what
        self.problem = problem
        super().__init__(f"{what}: {problem}")


class MessageError(ProtocolError, ValueError):
    """A message cannot be encoded or decoded; ``key`` and ``field`` say where.

    ``key`` is the Zenoh key (or message kind) the bytes came from, None when a
    message object is built directly; ``field`` is None when the problem is not
    in one field (bytes that are not msgpack, a payload that is not a map).
    """

    def __init__(self, problem: str, *, key: str | None = None, field: str | None = None) -> None:
        self.key = key
        self.field = field
        self.problem = problem
        super().__init__(self._text())

    def _text(self) -> str:
        parts = []
        if self.key is not None:
            parts.append(f"key '{self.key}'")
        if self.field is not None:
            parts.append(f"field '{self.field}'")
        return ": ".join(parts + [self.problem])

    def at_key(self, key: str) -> MessageError:
        """The same error located at ``key`` (for errors raised before the key was known)."""
        self.key = key
        self.args = (self._text(),)
        return self


class MessageFormatError(MessageError):
    """The bytes are not one msgpack map (truncated, trailing bytes, wrong type)."""


class MessageVersionError(MessageError):
    """The schema version field is missing or not the version this code speaks."""


class MessageKindError(MessageError):
    """The message's kind is unknown or does not match the key it arrived on."""


class MessageFieldError(MessageError):
    """A field is missing, unexpected, of the wrong type, not finite or out of range."""


class MessageArrayError(MessageFieldError):
    """An array field has the wrong layout, dtype, shape or byte length."""
