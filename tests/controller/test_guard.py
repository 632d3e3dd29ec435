"""The guard: a command kept off the hits of the last ticks (cekm_swarm.controller.guard)."""

import math

import numpy as np
import pytest

from cekm_swarm.controller.guard import Guard, GuardParams, clearances, guard, remembered
from cekm_swarm.robot import KHEPERA

BODY, AXLE, V = KHEPERA.body_radius, KHEPERA.axle, KHEPERA.v_max
P = GuardParams()


def ray(x: float, y: float, angle: float, free: float) -> list[float]:
    return [x, y, math.cos(angle), math.sin(angle), free]


def test_a_hit_no_ray_sees_through_is_remembered():
    old = np.array([[0.06, 0.04]])  # seen by an earlier ray, now between two rays
    rays = np.array([ray(0.0, 0.0, 0.0, 0.15), ray(0.0, 0.0, math.pi / 2, 0.15)])
    assert remembered([old, np.zeros((0, 2))], rays, P.eps).tolist() == [[0.06, 0.04]]


def test_a_hit_a_ray_now_sees_through_is_forgotten():
    old = np.array([[0.06, 0.0], [0.2, 0.0]])  # the first in free space now, the second beyond the free length
    rays = np.array([ray(0.0, 0.0, 0.0, 0.15)])
    assert remembered([old], rays, P.eps).tolist() == [[0.2, 0.0]]


def test_this_ticks_hits_are_among_the_remembered():
    now = np.array([[0.1, 0.0]])
    rays = np.array([ray(0.0, 0.0, 0.0, 0.1 - 0.02)])  # free short of its own hit
    assert remembered([now], rays, P.eps).tolist() == [[0.1, 0.0]]


def test_the_memory_keeps_the_last_ticks_only():
    g = Guard(GuardParams(memory=2))
    rays = np.zeros((0, 5))
    for k in range(4):
        g.update(np.array([[1.0 + k, 0.0]]), rays)
    assert g.points[:, 0].tolist() == [3.0, 4.0]


def test_clearances_straight_at_a_point_and_turning_in_place():
    point = np.array([[0.1, 0.0]])
    c = clearances((0.0, 0.0, 0.0), np.array([[V, V], [V, -V], [-V, -V]]), point, BODY, AXLE, 0.256, 0.064)
    assert c[0] == pytest.approx(0.1 - BODY - 4 * 0.064 * V)
    assert c[1] == pytest.approx(0.1 - BODY)  # a turn in place: the centre stays
    assert c[2] == pytest.approx(0.1 - BODY)  # backing away: now is the least


def test_a_command_into_a_corner_is_replaced_by_the_nearest_that_keeps_the_margin():
    corner = np.array([[0.05, 0.03]])  # ahead on the left, 0.058 m from the centre
    cmd = (0.08, 0.14)  # a left arc into it
    out = guard((0.0, 0.0, 0.0), cmd, corner, BODY, AXLE, V, P)
    assert out != cmd and out != (0.0, 0.0)
    assert clearances((0.0, 0.0, 0.0), np.array([out]), corner, BODY, AXLE, P.horizon, P.step)[0] >= P.margin
    s = np.linspace(-V, V, P.speeds)
    nearer = [(a, b) for a in s for b in s if math.hypot(a - cmd[0], b - cmd[1]) < math.hypot(out[0] - cmd[0],
                                                                                            out[1] - cmd[1])]
    assert nearer and (clearances((0.0, 0.0, 0.0), np.array(nearer), corner, BODY, AXLE, P.horizon, P.step)
                       < P.margin).all()  # every grid command nearer to it closes on the corner


def test_a_safe_command_is_left_alone():
    wall = np.array([[x, 0.06] for x in np.linspace(-0.2, 0.3, 11)])  # a wall beside, parallel
    assert guard((0.0, 0.0, 0.0), (V, V), wall, BODY, AXLE, V, P) == (V, V)
    assert guard((0.0, 0.0, 0.0), (V, V), np.zeros((0, 2)), BODY, AXLE, V, P) == (V, V)


def test_nearer_than_the_margin_already_it_may_move_away_but_not_closer():
    point = np.array([[0.033, 0.0]])  # 3 mm ahead of the body
    assert guard((0.0, 0.0, 0.0), (-V, -V), point, BODY, AXLE, V, P) == (-V, -V)
    out = guard((0.0, 0.0, 0.0), (V, V), point, BODY, AXLE, V, P)
    assert clearances((0.0, 0.0, 0.0), np.array([out]), point, BODY, AXLE, P.horizon, P.step)[0] >= 0.003 - 1e-12


def test_no_replacement_closes_on_a_point_from_any_pose():
    rng = np.random.default_rng(7)
    for _ in range(300):
        pose = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-math.pi, math.pi)))
        angles = rng.uniform(-math.pi, math.pi, 3)
        dist = rng.uniform(BODY + 0.001, BODY + 0.08, 3)
        points = np.column_stack([pose[0] + dist * np.cos(angles), pose[1] + dist * np.sin(angles)])
        cmd = (float(rng.uniform(-V, V)), float(rng.uniform(-V, V)))
        out = guard(pose, cmd, points, BODY, AXLE, V, P)
        now = clearances(pose, np.array([cmd]), points, BODY, AXLE, 0.0, P.step)[0]
        after = clearances(pose, np.array([out]), points, BODY, AXLE, P.horizon, P.step)[0]
        assert after >= min(P.margin, now) - 1e-12
        assert out != (0.0, 0.0) or cmd == (0.0, 0.0)


@pytest.mark.parametrize(("field", "value"), [("margin", -0.1), ("horizon", 0.0), ("memory", -1), ("speeds", 4),
                                              ("speeds", 1)])
def test_out_of_range_parameters_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=field):
        GuardParams(**{field: value}).check()
