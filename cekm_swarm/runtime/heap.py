"""The C heap's free memory given back to the system, now and then, in a process that runs
for hours (the world server).

glibc's allocator keeps the memory a process freed for later use (in every thread's arena:
Zenoh's threads, the recorder's, the main one), so a long run's resident size climbs with
what it once held at its busiest, not with what it holds. ``malloc_trim(0)`` hands the free
pages back. Measured on the world server of a 2-robot real-time run four minutes in: 1.3 MB
of its 77.5 MB resident given back; 11 ms for the first call, under 1 ms after (docs/faults.md,
'An hour on a bad link'). Other C libraries (musl) and other systems have no such call:
:func:`trim` then does nothing."""

from __future__ import annotations

import ctypes
import sys
from collections.abc import Callable

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

M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter
MMAP_THRESHOLD = 128 * 1024
"""Bytes from which an allocation gets pages of its own, given back when it is freed:
glibc's initial threshold, held there (see :func:`hold_mmap_threshold`)."""


def hold_mmap_threshold(nbytes: int = MMAP_THRESHOLD) -> bool:
    """Keep glibc's mmap threshold at ``nbytes``; True if the C library took it.

    glibc raises the threshold to the size of any large block that is freed (up to 32 MB),
    after which blocks below it come from the heap. The world's log frees a 1 MB chunk
    buffer every few seconds, so later large buffers (its compressed chunks and the like)
    then land in the heap between long-lived objects and can leave holes it does not give
    back. In two 2-robot real-time runs side by side, one each way, the world server's
    anonymous memory grew 3.3 MB from minute 1 to minute 6.5 with the moving threshold and
    2.3 MB with it held (one pair of runs: docs/faults.md, 'An hour on a bad link')."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    return bool(mallopt(M_MMAP_THRESHOLD, nbytes))


def trim() -> bool:
    """Give the heap's free memory back to the system; True if the C library could."""
    return bool(_TRIM is not None and _TRIM(0))


class HeapTrimmer:
    """Trims at most every ``every_s`` wall seconds: :meth:`due` tells when, the caller
    runs :func:`trim` (off its event loop: ctypes releases the GIL for the call)."""

    def __init__(self, every_s: float = TRIM_EVERY_S) -> None:
        self.every_s = every_s
        self.available = _TRIM is not None
        self._last: float | None = None

    def due(self, now: float) -> bool:
        if not self.available:
            return False
        if self._last is None:
            self._last = now  # the first trim a period after the start: the start-up is not the run
            return False
        if now - self._last < self.every_s:
            return False
        self._last = now
        return True
