"""Which stamps a receiver believes: the sane window around sim time.

A stamp is a peer's claim. Believed blindly it did harm: a stamp of 1e18 overflowed the
MCAP writer (the world server died), made every later field "stale" in a real-time motor
(the robot stopped for good) and froze a lockstep motor on a tick that never comes. So a
receiver takes a stamp only when it is finite, within [0, MAX_STAMP_S], on the tick grid
(every message of the runtime is stamped with a tick's sim time, ``cekm_swarm.ticks``),
and within a window around *now*:

* the world server owns the clock: now is its sim time;
* a module process has no clock of its own: now is the newest stamp it has taken (none
  yet, or none for ``QUIET_S`` of wall time, as after a router outage while a real-time
  world ticked on: any stamp in bounds is taken; docs/robustness.md says what that leaves
  open).

Anything else is dropped by the caller and counted per source (:class:`DropCounter`).
"""

from __future__ import annotations

import math
import time

from cekm_swarm.ticks import TICK_S, tick_of, tick_time

MAX_STAMP_S = 1e7
"""No run lasts 116 days of sim time; a stamp beyond this is bogus whatever the clock says."""
PAST_S = 8 * TICK_S
"""How far behind now a stamp may be: a tick's fields and commands arrive within a tick, a
re-published target reading is one tick old, real-time staleness limits are 2-4 ticks."""
FUTURE_S = 8 * TICK_S
"""How far ahead of a module's newest stamp a stamp may be (the world's next tick is one
tick ahead; a module restarted or starved for a while sees a jump of a few)."""
ANY_STAMP = math.inf
"""The window (behind and ahead) of a module whose one input is a reading the world holds
(a pure node of that reading alone, ``RunPlan.held_readings``): none, only the bounds and
the grid. It hears from the world only when its reading changes, so it has no recent now to
judge by; and it keeps no state, so a stamp it should not believe only makes an output
stamped the same, which its readers judge by their own window (the motor hears from the
world every tick). A window of its own made the world send every held reading again every
8 ticks, to keep it inside."""
QUIET_S = 1.0
"""Wall seconds without a believable stamp after which a module takes the next stamp in
bounds as now (the world's messages come every 0.128 s, or every re-publish second)."""
_GRID_TOL = 1e-9  # stamps are round(k * 0.128, 9)


def on_grid(stamp: float) -> bool:
    """True when ``stamp`` is a tick's sim time."""
    return abs(stamp - tick_time(tick_of(stamp))) <= _GRID_TOL


def stamp_problem(stamp: object, now: float | None, past: float = PAST_S, future: float = FUTURE_S,
                  grid: bool = True) -> str | None:
    """Why ``stamp`` is not believable at sim time ``now`` (None: it is). ``now`` None:
    only the absolute bounds (and the grid) apply."""
    if (type(stamp) is float and 0.0 <= stamp <= MAX_STAMP_S  # the common case first: a few comparisons
            and (now is None or now - past - _GRID_TOL <= stamp <= now + future + _GRID_TOL)):
        if not grid:
            return None
        k = round(stamp / TICK_S)  # tick_of and tick_time written out: every message takes this path
        if abs(stamp - round(k * TICK_S, 9)) <= _GRID_TOL:
            return None
    if type(stamp) is not float and type(stamp) is not int:
        return f"stamp {stamp!r} is not a number"
    if not math.isfinite(stamp):
        return f"stamp {stamp!r} is not finite"
    if not 0.0 <= stamp <= MAX_STAMP_S:
        return f"stamp {stamp!r} outside [0, {MAX_STAMP_S:g}] s"
    if now is not None and not now - past - _GRID_TOL <= stamp <= now + future + _GRID_TOL:
        return f"stamp {stamp!r} outside the window [{now - past:.3f}, {now + future:.3f}] s around sim time {now:.3f}"
    if grid and not on_grid(stamp):
        return f"stamp {stamp!r} is not a tick's sim time (k * {TICK_S} s)"
    return None


class StampWindow:
    """A module's stamp check: :func:`stamp_problem` around the newest stamp taken so far.

    ``check(stamp)`` returns the reason to drop, or None and takes the stamp (moving now
    forward). Used on one thread (a module's Zenoh callback)."""

    __slots__ = ("past", "future", "quiet", "newest", "taken_at")

    def __init__(self, past: float = PAST_S, future: float = FUTURE_S, quiet: float = QUIET_S) -> None:
        self.past, self.future, self.quiet = past, future, quiet
        self.newest: float | None = None
        self.taken_at = -math.inf

    def check(self, stamp: float) -> str | None:
        wall = time.monotonic()
        newest = self.newest if wall - self.taken_at <= self.quiet else None  # quiet for long: re-anchor
        why = stamp_problem(stamp, newest, self.past, self.future)
        if why is None:
            if newest is None or stamp > newest:
                self.newest = float(stamp)
            self.taken_at = wall
        return why
