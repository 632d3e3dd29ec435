"""The stamp window: what a receiver believes of a peer's stamp."""

import math

import pytest

from cekm_swarm.protocol.stamps import FUTURE_S, MAX_STAMP_S, PAST_S, StampWindow, on_grid, stamp_problem
from cekm_swarm.ticks import TICK_S, tick_time


@pytest.mark.parametrize("stamp", [1e18, 1e300, MAX_STAMP_S + 1.0, -1.0, -1e-9, math.nan, math.inf, -math.inf,
                                   "1.0", None, [0.0]])
def test_a_stamp_no_run_can_have_is_refused_at_any_time(stamp):
    assert stamp_problem(stamp, None) is not None
    assert stamp_problem(stamp, 12.8) is not None


def test_the_window_around_now_and_the_tick_grid():
    now = tick_time(100)
    assert stamp_problem(now, now) is None
    assert stamp_problem(tick_time(100 - 8), now) is None and stamp_problem(tick_time(100 - 9), now) is not None
    assert stamp_problem(tick_time(100 + 8), now) is None and stamp_problem(tick_time(100 + 9), now) is not None
    assert stamp_problem(tick_time(101), now, future=0.0) is not None  # the world: nothing ahead of its clock
    assert "tick" in stamp_problem(now + 0.05, now)
    assert stamp_problem(now + 0.05, now, grid=False) is None
    assert all(on_grid(tick_time(k)) for k in range(0, 100_000, 7))
    assert PAST_S == FUTURE_S == 8 * TICK_S


def test_a_module_window_follows_the_newest_stamp_it_took():
    w = StampWindow()
    assert w.check(1e18) is not None and w.newest is None  # a refused stamp moves nothing
    assert w.check(tick_time(50)) is None and w.newest == tick_time(50)
    assert w.check(tick_time(49)) is None and w.newest == tick_time(50)  # late but near: taken
    assert w.check(tick_time(30)) is not None  # an old tick
    assert w.check(tick_time(2000)) is not None  # far ahead: now does not jump
    assert w.newest == tick_time(50)


def test_a_module_window_re_anchors_after_a_quiet_spell():
    """After a router outage a real-time world's time has moved on by more than the window:
    a module that heard nothing believable for ``quiet`` wall seconds takes the next stamp."""
    w = StampWindow(quiet=0.0)
    assert w.check(tick_time(50)) is None
    assert w.check(tick_time(500)) is None and w.newest == tick_time(500)
    assert w.check(1e18) is not None  # bounds still hold
    held = StampWindow(quiet=3600.0)
    assert held.check(tick_time(50)) is None and held.check(tick_time(500)) is not None
