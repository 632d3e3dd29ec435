"""A robot's pose from its own wheel commands (cekm_swarm.controller.dead_reckoning)."""

import pytest

from cekm_swarm.controller.dead_reckoning import DeadReckoning, executed

AXLE = 0.053


def test_dead_reckoning_executes_the_commands_of_a_differential_drive():
    dr = DeadReckoning()
    dr.move(0.0, 0.1, 0.1, AXLE)  # the first call sets the clock only
    dr.move(2.0, 0.1, 0.1, AXLE)
    assert dr.pose == pytest.approx((0.2, 0.0, 0.0))
    dr.move(3.0, -0.05, 0.05, AXLE)  # in place: omega = 0.1 / axle
    assert dr.pose[:2] == pytest.approx((0.2, 0.0)) and dr.pose[2] == pytest.approx(0.1 / AXLE)


def test_a_command_is_executed_with_each_wheel_clamped_to_v_max():
    assert executed(0.3, -0.2, 0.156) == (0.156, -0.156)
    assert executed(0.1, -0.05, 0.156) == (0.1, -0.05)
