import math

import numpy as np
import pytest

from cekm_swarm.models.fields import integrate, motor_control, motor_winner, obstacle_field, target_field
from cekm_swarm.models.params import FieldParams

P = FieldParams()
W = np.array([[0.0, 0.10], [1.0, 0.10], [0.0, 0.15], [0.0, 0.05], [3.0, 0.10], [-3.0, 0.10]])


def test_target_field_eq6_at_hand_computed_points():
    a = target_field(W, 0, P)
    assert a[0] == 1.0
    assert math.isclose(a[1], math.exp(-1.0 / (2 * 2.475 ** 2)))
    assert math.isclose(a[2], math.exp(-0.05 ** 2 / (2 * 0.0495 ** 2)))
    # the angle difference is wrapped: 3 and -3 rad are 0.283 rad apart
    a4 = target_field(W, 4, P)
    assert math.isclose(a4[5], math.exp(-(2 * math.pi - 6.0) ** 2 / (2 * 2.475 ** 2)))


def test_target_field_is_distance_sensitive_and_angle_insensitive():
    a = target_field(W, 0, P)
    assert a[1] > 0.9 and a[2] < 0.7  # 1 rad away barely matters; 5 cm away does


def test_obstacle_field_eq8_both_branches():
    b = obstacle_field(W, 0, P)  # obstacle at (0, 0.10)
    assert b[0] == 1.0
    beyond = math.exp(-0.05 ** 2 / (2 * 2.475 ** 2))  # neuron 2 is beyond the obstacle (d_i >= d_s)
    near = math.exp(-0.05 ** 2 / (2 * 0.02475 ** 2))  # neuron 3 is nearer than it
    assert math.isclose(b[2], beyond) and math.isclose(b[3], near)
    assert b[2] > 0.99 > 0.5 > b[3]  # neurons beyond the obstacle are inhibited too
    assert math.isclose(b[1], math.exp(-1.0 / (2 * P.sigma_b_alpha ** 2)) * 1.0)


def test_integration_eq9_and_winner_eq10():
    a = target_field(W, 0, P)
    b1, b2 = obstacle_field(W, 0, P), obstacle_field(W, 2, P)
    e = integrate(a, [b1, b2])
    np.testing.assert_allclose(e, a - b1 - b2)
    assert motor_winner(e) == int(np.argmax(e))
    assert np.array_equal(integrate(a, []), a)


def test_motor_control_eq11_branches():
    M = np.zeros((3, 2, 2))
    M[0] = [[0.01, 0.02], [0.03, 0.04]]
    M[1] = [[0.5, 0.5], [0.5, 0.5]]
    M[2] = [[0.02, 0.0], [0.0, 0.02]]
    w = np.array([[0.1, 0.05], [0.2, 0.06], [0.3, 0.07]])
    ds, vmax = 10.0, 0.15
    u = np.array([0.15, 0.055])
    # k = s and |M_k u| <= c*: c = M_k u
    np.testing.assert_allclose(motor_control(M, w, u, 0, 0, vmax, ds), M[0] @ [0.15, 0.55])
    # k = s but M_k u beyond c*: c = M_k w_k
    np.testing.assert_allclose(motor_control(M, w, u, 1, 1, vmax, ds), M[1] @ [0.2, 0.6])
    # k != s: c = M_k w_k even though M_k u would be within c*
    np.testing.assert_allclose(motor_control(M, w, u, 2, 0, vmax, ds), M[2] @ [0.3, 0.7])


@pytest.mark.parametrize("name", ["sigma_a_alpha", "sigma_b_d_near"])
def test_field_params_must_be_positive(name):
    with pytest.raises(ValueError, match=name):
        FieldParams(**{name: 0.0})
