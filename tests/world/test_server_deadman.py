"""The world server's dead-man rule, without Zenoh: a robot whose commands stop is stopped
at the last tick boundary before its silence would pass the limit, even when boundaries
come late by up to the margin."""

from __future__ import annotations

from world.deadman import DEADMAN_MARGIN_S, Deadman
from world.episode import TICK_S


def silence_at_stop(last_heard: float, lateness: float) -> float:
    """Seconds of silence when the robot is stopped, boundaries each ``lateness`` s late."""
    dm = Deadman(["r1"], 0.5, 0.0)
    dm.heard("r1", last_heard)
    k = 0
    while True:
        now = k * TICK_S + lateness
        stop, newly = dm.check("r1", now, TICK_S)
        if stop:
            assert newly
            # the robot moves on its last command until this boundary
            return now - last_heard
        k += 1


def test_stopped_within_the_limit_for_any_phase_and_late_boundaries():
    for i in range(64):
        last = i * TICK_S / 64
        for lateness in (0.0, 0.5 * DEADMAN_MARGIN_S, DEADMAN_MARGIN_S):
            s = silence_at_stop(last, lateness)
            assert s <= 0.5
            assert s > 0.5 - TICK_S - DEADMAN_MARGIN_S  # and not much earlier than needed


def test_a_command_clears_the_stop():
    dm = Deadman(["r1"], 0.5, 0.0)
    assert dm.check("r1", 1.0, TICK_S) == (True, True)
    assert dm.check("r1", 1.128, TICK_S) == (True, False)
    dm.heard("r1", 1.2)
    assert dm.check("r1", 1.256, TICK_S) == (False, False)
