"""A long-running process's memory kept flat (the world server): once a minute its cyclic
garbage collected and the C heap's free memory given back to the system.

Python's collector (made lazy by :mod:`.gc_tuning` so it stays out of a tick's way) leaves a
cycle that outlived a young collection to the full one, which with the start-up heap frozen
comes only after about two million allocations: minutes. Until then such garbage piles up;
measured in the world server of a 2-robot real-time run, 2.9 MB from minute 1 to minute 4,
flat after (docs/faults.md, 'An hour on a bad link'). :meth:`HeapTrimmer.collect` runs the
full collection once a minute instead; the frozen start-up heap is not walked, so it walks
only what the run allocated since and still holds (its time is in ``outcome.json``,
``heap``).

glibc's allocator keeps the memory a process freed for later use (in every thread's arena:
Zenoh's threads, the recorder's, the main one), so a long run's resident size climbs with
what it once held at its busiest, not with what it holds. ``malloc_trim(0)`` hands the free
pages back. Measured on the world server of a 2-robot real-time run four minutes in: 1.3 MB
of its 77.5 MB resident given back; 11 ms for the first call, under 1 ms after (docs/faults.md,
'An hour on a bad link'). Other C libraries (musl) and other systems have no such call:
:func:`trim` then does nothing."""

from __future__ import annotations

import ctypes
import gc
import sys
import time
from collections.abc import Callable
from typing import Any

TRIM_EVERY_S = 60.0
"""Wall seconds between two trims of a long-running process."""


def _malloc_trim() -> Callable[[int], int] | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(None).malloc_trim  # the process's own C library; glibc has it
    except (OSError, AttributeError):
        return None


_TRIM = _malloc_trim()


def trim() -> bool:
    """Give the heap's free memory back to the system; True if the C library could."""
    return bool(_TRIM is not None and _TRIM(0))


class HeapTrimmer:
    """Tidies at most every ``every_s`` wall seconds: :meth:`due` tells when, the caller
    runs :meth:`collect` (on its loop, between two ticks) and :func:`trim` (off its event
    loop: ctypes releases the GIL for the call)."""

    def __init__(self, every_s: float = TRIM_EVERY_S) -> None:
        self.every_s = every_s
        self.available = _TRIM is not None
        self._last: float | None = None
        self.collections = 0
        self.collected = 0  # objects the full collections freed
        self.collect_ms_max = 0.0

    def collect(self) -> float:
        """A full collection of the cyclic garbage; how long it took, in ms."""
        t0 = time.perf_counter()
        self.collected += gc.collect()
        ms = 1000 * (time.perf_counter() - t0)
        self.collections += 1
        self.collect_ms_max = max(self.collect_ms_max, ms)
        return ms

    def summary(self) -> dict[str, Any]:
        """For ``outcome.json``: the collections run, the objects they freed, the longest (ms)."""
        return {"collections": self.collections, "collected": self.collected,
                "collect_ms_max": round(self.collect_ms_max, 3), "trim": self.available}

    def due(self, now: float) -> bool:
        if self._last is None:
            self._last = now  # the first trim a period after the start: the start-up is not the run
            return False
        if now - self._last < self.every_s:
            return False
        self._last = now
        return True
