"""The world's one use of pymunk internals: Chipmunk's C functions through pymunk's cffi
binding, for the hot loops (a ray cast 0.4 us instead of 3.0 us through
``Space.segment_query_first``; 12 a robot a tick, in every experiment's millions of
robot-ticks; the space's step without the wrapper's checks). pymunk is pinned to the
range this is tested with (``pyproject.toml``), and ``tests/world/test_chipmunk.py`` fails
loudly, naming what changed, on a pymunk whose internals differ: the symbols, and the
results equal to the public API's.

Why the public API cannot do it: it gives the same answers (the test holds that), but
each call pays for Python objects the hot loop never uses. ``Space.segment_query_first``
allocates a new query-info struct, looks the hit shape's Python object up and returns a
``SegmentQueryInfo`` with two ``Vec2d`` on every call (``point_query_nearest`` likewise),
where the world needs one float; ``Space.step`` checks the bodies, locks the space and
runs its add/remove-later and post-step bookkeeping in Python at every sub-step, for a
space whose bodies and shapes never change once built. So the world makes its filters and
info structs once and calls Chipmunk directly. ``pymunk.batch``, the public fast path,
reads and writes the bodies' state (:mod:`world.sim` uses it) but has no queries."""

from __future__ import annotations

from typing import Any

import pymunk

PYMUNK_RANGE = ((7, 0), (8, 0))
"""pymunk versions tested with (at least the first, below the second)."""

try:
    from pymunk._chipmunk_cffi import ffi, lib
except ImportError as exc:  # pragma: no cover - a pymunk outside the pinned range
    raise ImportError(f"world/chipmunk.py needs pymunk {PYMUNK_RANGE[0]} <= version < {PYMUNK_RANGE[1]} "
                      f"(pymunk._chipmunk_cffi: {exc}); this is pymunk {pymunk.version}") from None


def cp_space(space: pymunk.Space) -> Any:
    """The Chipmunk space behind a pymunk space."""
    return space._space


def version_ok(version: str = pymunk.version) -> bool:
    major_minor = tuple(int(p) for p in version.split(".")[:2])
    return PYMUNK_RANGE[0] <= major_minor < PYMUNK_RANGE[1]


space_step = lib.cpSpaceStep
segment_query_first = lib.cpSpaceSegmentQueryFirst
point_query_nearest = lib.cpSpacePointQueryNearest


def segment_info() -> Any:
    return ffi.new("cpSegmentQueryInfo *")


def point_info() -> Any:
    return ffi.new("cpPointQueryInfo *")


def shape_filter(group: int, categories: int, mask: int) -> Any:
    return ffi.new("cpShapeFilter *", (group, categories, mask))[0]


def vect(x: float, y: float) -> Any:
    return ffi.new("cpVect *", (x, y))[0]
