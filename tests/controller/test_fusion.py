"""Command-fusion baseline: the Braitenberg avoider's signs, the goal stop, and the
section 4.2 outcomes of the baseline in real worlds (trapped by the U and the doorway,
passes the lone disc)."""

import math

import numpy as np
import pytest

from cekm_swarm.controller.fusion import CommandFusion
from cekm_swarm.controller.readings import TargetReading, range_readings
from cekm_swarm.models.networks import IndirectEKM

ANGLES = np.array([j * math.pi / 6 for j in range(12)])
ANGLES = np.angle(np.exp(1j * ANGLES))


@pytest.fixture(scope="module")
def fusion():
    return CommandFusion(IndirectEKM.kinematic(5))


def readings(**seen):
    """Surface ranges by sensor index, NaN elsewhere."""
    surf = np.full(12, np.nan)
    for j, r in seen.items():
        surf[int(j[1:])] = r
    return range_readings(surf, ANGLES, 0.03)


def test_nothing_sensed_no_avoidance(fusion):
    assert np.allclose(fusion.avoid_command(readings()), 0.0)


def test_obstacle_front_left_turns_right_and_backs(fusion):
    vl, vr = fusion.avoid_command(readings(s1=0.05))  # sensor 1 at +pi/6 (left)
    assert vr < 0 and vr < vl  # right wheel backward, faster: turns right, away


def test_obstacle_front_right_turns_left(fusion):
    vl, vr = fusion.avoid_command(readings(s11=0.05))  # -pi/6 (right)
    assert vl < 0 and vl < vr


def test_head_on_obstacle_turns_away_from_the_side_sensing_more(fusion):
    vl, vr = fusion.avoid_command(readings(s0=0.05, s1=0.08, s11=0.12))
    assert vr < vl  # more on the left: turn right
    vl, vr = fusion.avoid_command(readings(s0=0.05, s1=0.12, s11=0.08))
    assert vl < vr


def test_rear_sensors_do_not_drive(fusion):
    assert np.allclose(fusion.avoid_command(readings(s6=0.02, s5=0.05, s7=0.05)), 0.0)


def test_closer_obstacle_pushes_harder(fusion):
    near = fusion.avoid_command(readings(s1=0.02))
    far = fusion.avoid_command(readings(s1=0.15))
    assert np.abs(near).sum() > np.abs(far).sum()


def test_goal_state_stops_target_command(fusion):
    assert np.allclose(fusion.target_command(TargetReading(0.3, 0.0)), 0.0)
    assert np.allclose(fusion.target_command(TargetReading(float("nan"), float("nan"), False)), 0.0)


def test_fused_command_is_clipped(fusion):
    c = fusion.fuse(np.array([1.0, 1.0]), np.array([1.0, -5.0]))
    assert np.all(np.abs(c) <= fusion.model.v_max + 1e-12)


@pytest.mark.parametrize("scenario,seed,reached", [("lone_obstacle", 1, True), ("concave", 1, False),
                                                   ("doorway", 2, False)])
def test_fusion_outcomes_in_real_worlds(scenario, seed, reached):
    pytest.importorskip("pymunk")
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.navigation_run import run_scenario
    from world import load_scenario

    run = run_scenario(load_scenario(scenario), "fusion", default_model(progress=False), seed, max_time=60.0)
    assert run.outcome["r1"]["reached"] is reached
    if reached:
        assert run.outcome["r1"]["collisions"] == 0
