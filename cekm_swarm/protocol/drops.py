"""Counting and logging malformed messages so a receiver drops them and keeps running."""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

from .errors import MessageError
from .keys import DEFAULT_KEYS, KeyKind, KeySpace
from .messages import Message, decode

log = logging.getLogger("cekm_swarm.protocol")


@dataclass(frozen=True, slots=True)
class DropRecord:
    """What was dropped from one source key: how many, and the first reason."""

    source: str
    count: int
    first_reason: str


MAX_SOURCES = 256
"""Sources counted apart; a peer may invent keys without end, so drops from any further
source are counted together under :data:`OTHER_SOURCES` (and logged once)."""
OTHER_SOURCES = "(other sources)"


class DropCounter:
    """Per source key: counts dropped (malformed, wrong-version, unbelievable stamp)
    messages and logs the first one of each source once, with its reason; later ones are
    only counted. At most ``max_sources`` sources are told apart (then one more line), so
    memory and warning lines stay bounded whatever a peer sends.

    Thread-safe, so a Zenoh callback thread and an event loop may share one.
    """

    def __init__(self, name: str = "receiver", logger: logging.Logger | None = None,
                 keys: KeySpace = DEFAULT_KEYS, max_sources: int = MAX_SOURCES) -> None:
        self.name = name
        self.keys = keys
        self.max_sources = max_sources
        self._log = logger or log
        self._lock = threading.Lock()
        self._counts: dict[str, int] = {}
        self._first: dict[str, str] = {}

    def drop(self, source: str, reason: BaseException | str) -> None:
        """Count one dropped message from ``source``; log it if it is the source's first."""
        text = str(reason)
        with self._lock:
            if source not in self._counts and len(self._counts) >= self.max_sources:
                source = OTHER_SOURCES
            n = self._counts.get(source, 0)
            self._counts[source] = n + 1
            if n == 0:
                self._first[source] = text
        if n == 0:
            self._log.warning("%s: dropped a message from %s (further drops from it are only counted): %s",
                              self.name, source, text)

    def decode(self, key: str, data: bytes, expect: KeyKind | None = None) -> Message | None:
        """Decode ``data`` received on ``key`` (of kind ``expect`` on a graph's own key); on
        a MessageError drop it and return None."""
        try:
            return decode(key, data, keys=self.keys, expect=expect)
        except MessageError as exc:
            self.drop(key, exc)
            return None

    @property
    def total(self) -> int:
        """Messages dropped from all sources."""
        with self._lock:
            return sum(self._counts.values())

    def count(self, source: str) -> int:
        """Messages dropped from ``source``."""
        with self._lock:
            return self._counts.get(source, 0)

    def by_source(self) -> dict[str, int]:
        """Drops per source (a copy), for reports."""
        with self._lock:
            return dict(sorted(self._counts.items()))

    def records(self) -> list[DropRecord]:
        """One record per source that had drops, sorted by source."""
        with self._lock:
            return [DropRecord(s, self._counts[s], self._first[s]) for s in sorted(self._counts)]

    def __repr__(self) -> str:
        return f"DropCounter({self.name!r}, total={self.total})"
