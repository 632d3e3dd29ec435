"""The trained model over Zenoh: the launcher serves the model file's bytes on a
queryable at ``<root>/world/model``; a module started with ``--model zenoh`` asks for
them instead of reading a file, so a robot host needs no copy of the model.

The reply carries the file's bytes unchanged and, as its attachment, their SHA-256; the
asker checks the digest and then reads the bytes with the same checks as a file
(:func:`cekm_swarm.models.io.load_model_bytes`).
"""

from __future__ import annotations

import hashlib
import logging
import time
from pathlib import Path

import zenoh

from .config import MAX_MESSAGE_BYTES
from .errors import RuntimeTransportError

log = logging.getLogger(__name__)

ZENOH_MODEL = "zenoh"
"""The ``--model`` value that means: fetch the model from the launcher's queryable."""


def is_zenoh_source(model: str) -> bool:
    """True when a ``--model`` value asks for the served model rather than a file."""
    return model == ZENOH_MODEL


class ModelServer:
    """A queryable on ``key`` answering every query with the bytes of the file at ``path``
    (read once, now: a file replaced later is not served).

    A file whose reply would be over the transport's :data:`MAX_MESSAGE_BYTES` cannot
    travel (the router drops it silently): every query then gets an error reply saying
    so, and the asker fails at once with it instead of waiting for a reply that never
    comes."""

    def __init__(self, session: zenoh.Session, key: str, path: str | Path) -> None:
        self.key = key
        self.path = Path(path)
        self.blob = self.path.read_bytes()
        self.digest = hashlib.sha256(self.blob).hexdigest()
        self.served = 0
        self.refusal: str | None = None
        reply_bytes = len(self.blob) + len(self.digest)
        if reply_bytes > MAX_MESSAGE_BYTES:
            self.refusal = (f"the model {self.path.name} is too large to serve over Zenoh: {reply_bytes} bytes "
                            f"with its digest, over MAX_MESSAGE_BYTES ({MAX_MESSAGE_BYTES}); give each robot "
                            f"host the file (--model PATH) instead of --model-from-zenoh")
            log.warning("%s: %s", key, self.refusal)
        self._q: zenoh.Queryable[None] | None = session.declare_queryable(
            key, zenoh.handlers.Callback(self._reply, indirect=True))

    def _reply(self, query: zenoh.Query) -> None:
        if self.refusal is not None:
            query.reply_err(self.refusal.encode())
            return
        query.reply(self.key, self.blob, encoding=zenoh.Encoding("application/octet-stream"),
                    attachment=self.digest.encode())
        self.served += 1

    def close(self) -> None:
        """Stop serving (idempotent)."""
        if self._q is not None:
            self._q.undeclare()
            self._q = None


def fetch_model_bytes(session: zenoh.Session, key: str, timeout: float = 30.0) -> bytes:
    """The model bytes served on ``key``, asking again every second until ``timeout`` s
    have passed (the launcher may still be starting). Raises RuntimeTransportError naming
    the key if nothing answers, if the server refuses (a model too large to serve: at
    once, with its reason), or if the bytes do not match their digest."""
    deadline = time.monotonic() + timeout
    last_error = "no queryable answered"
    while True:
        for reply in session.get(key, timeout=min(1.0, max(0.05, deadline - time.monotonic()))):
            if reply.ok is None:
                assert reply.err is not None  # a reply is ok or an error
                text = reply.err.payload.to_bytes()[:400].decode("utf-8", "replace")
                if text == "Timeout":  # Zenoh's own, when a queryable did not answer in time: ask again
                    last_error = "a queryable did not answer in time"
                    continue
                # the server's answer, final: a model too large to serve
                raise RuntimeTransportError(f"model from {key}: the server refused: {text}")
            sample = reply.ok
            blob = sample.payload.to_bytes()
            digest = sample.attachment.to_bytes().decode() if sample.attachment is not None else None
            if digest != hashlib.sha256(blob).hexdigest():
                raise RuntimeTransportError(f"model from {key}: {len(blob)} bytes do not match their SHA-256 "
                                            f"({digest!r}); refusing them")
            return blob
        if time.monotonic() >= deadline:
            raise RuntimeTransportError(f"model from {key}: {last_error} within {timeout:.0f} s "
                                        "(is a launcher with the world server running?)")
