"""The cooperative-EKM modules against the reference equations (models.fields, models.competition)."""

import numpy as np
import pytest

from cekm_swarm.controller.cooperative import CooperativeEKM
from cekm_swarm.controller.readings import RangeReading, TargetReading, range_readings
from cekm_swarm.models.competition import winner
from cekm_swarm.models.fields import integrate, motor_control, motor_winner, obstacle_field, target_field
from cekm_swarm.models.networks import make_network
from cekm_swarm.models.params import FieldParams


@pytest.fixture(scope="module")
def ekm():
    return CooperativeEKM(make_network("R15", np.random.default_rng(4)))


def test_target_localization_eqs_2_to_6(ekm):
    act = ekm.localize_target(TargetReading(0.4, 0.9), stamp=1.0)
    s = winner(np.array([0.4, 0.9]), ekm.model.w, ekm.model.comp)
    assert act.winner == s and act.stamp == 1.0 and (act.alpha, act.d) == (0.4, 0.9)
    np.testing.assert_allclose(act.a, target_field(ekm.model.w, s, FieldParams()), rtol=1e-12)


def test_target_not_sensed_and_goal_state(ekm):
    gone = ekm.localize_target(TargetReading(float("nan"), float("nan"), False), 0.0)
    assert gone.winner is None and gone.a is None
    goal = ekm.localize_target(TargetReading(0.0, 0.0), 0.0)
    assert goal.at_goal and goal.a is None
    for t in (None, gone, goal):
        out = ekm.integrate(t, [])
        assert (out.v_l, out.v_r) == (0.0, 0.0)  # no target, or the goal state: the robot stops


def test_obstacle_localization_eqs_7_8(ekm):
    act = ekm.localize_obstacle(RangeReading(3, np.pi / 2, 0.12), 0.5)
    s = winner(np.array([np.pi / 2, 0.12]), ekm.model.w, ekm.model.comp)
    assert act.index == 3 and act.winner == s
    np.testing.assert_allclose(act.b, obstacle_field(ekm.model.w, s, FieldParams()), rtol=1e-12)
    none = ekm.localize_obstacle(RangeReading(4, 2.0, None), 0.5)
    assert none.winner is None and none.b is None


def test_batched_obstacle_modules_equal_the_single_ones_exactly(ekm):
    readings = range_readings(np.array([0.05, np.nan, 0.1, 0.0, np.nan, 0.17, 0.02, 0.11, np.nan, 0.08, 0.13, 0.04]),
                              np.linspace(-np.pi, np.pi, 12, endpoint=False), 0.03)
    batch = ekm.localize_obstacles(readings, 2.0)
    for r, b in zip(readings, batch, strict=True):
        one = ekm.localize_obstacle(r, 2.0)
        assert one.winner == b.winner and one.index == b.index
        if one.b is None:
            assert b.b is None
        else:
            assert np.array_equal(one.b, b.b)


def test_integration_and_motor_control_eqs_9_to_11(ekm):
    rng = np.random.default_rng(0)
    m = ekm.model
    for _ in range(50):
        target = ekm.localize_target(TargetReading(rng.uniform(-np.pi, np.pi), rng.uniform(0.001, 2.0)), 0.0)
        readings = [RangeReading(j, -np.pi + j * np.pi / 6, rng.uniform(0.03, 0.2) if rng.random() < 0.5 else None)
                    for j in range(12)]
        obs = ekm.localize_obstacles(readings, 0.0)
        out = ekm.integrate(target, obs)
        e = integrate(target.a, [o.b for o in obs if o.b is not None])
        k = motor_winner(np.where(ekm.eligible, e, -np.inf))
        c = np.clip(motor_control(m.M, m.w, np.array([target.alpha, target.d]), k, target.winner, m.v_max,
                                  m.learn_p.d_scale), -m.v_max, m.v_max)
        assert out.k == k and out.s == target.winner
        np.testing.assert_allclose([out.v_l, out.v_r], c, rtol=1e-12, atol=1e-15)


def test_range_readings_convert_surface_range_to_centre_distance():
    rs = range_readings(np.array([0.05, np.nan]), np.array([0.0, 1.0]), 0.03)
    assert rs[0].d == pytest.approx(0.08) and rs[1].d is None and rs[1].alpha == 1.0


def test_motor_candidates_exclude_reverse_and_unconverged_neurons():
    from cekm_swarm.controller.cooperative import motor_candidates

    net = make_network("R9", np.random.default_rng(1))
    w = net.w
    reverse = (np.abs(w[:, 0]) > np.pi / 2) & (w[:, 1] > 0.02)
    assert reverse.any()
    np.testing.assert_array_equal(motor_candidates(net), ~reverse)
    assert motor_candidates(net, allow_reverse=True).all()
    net.converged = np.zeros(len(w), dtype=bool)
    net.converged[:10] = True
    np.testing.assert_array_equal(motor_candidates(net, allow_reverse=True), net.converged)


def test_the_rear_turns_are_the_rear_candidates_the_reverse_rule_keeps():
    """turns_to_rear: exactly the neurons of the rear half that motor_candidates keeps without
    allow_reverse (turns in place, d <= reverse_min_d); none of the forward half."""
    from cekm_swarm.controller.cooperative import motor_candidates, turns_to_rear

    net = make_network("R9", np.random.default_rng(1))
    w = np.array([[3.0, 0.01], [-2.0, 0.02], [3.0, 0.05], [0.3, 0.01], [np.pi / 2, 0.0]])
    assert [turns_to_rear(w, k) for k in range(len(w))] == [True, True, False, False, False]
    assert not turns_to_rear(w, 0, reverse_min_d=0.005)
    rear = np.abs(net.w[:, 0]) > np.pi / 2
    kept = motor_candidates(net)
    assert [turns_to_rear(net.w, k) for k in range(len(net.w))] == (rear & kept).tolist()


def test_convergence_mask_tells_a_converged_map_from_an_untrained_one():
    from cekm_swarm.experiments.training import convergence_mask
    from cekm_swarm.models.networks import IndirectEKM

    kinematic = convergence_mask(IndirectEKM.kinematic(9))
    untrained = convergence_mask(make_network("R9", np.random.default_rng(2)))
    small_angle = np.abs(IndirectEKM.kinematic(9).w[:, 0]) < 0.8
    assert kinematic[small_angle].all()  # M0 moves the robot by w_i where the arc is near its chord
    assert untrained.mean() < 0.5 < kinematic.mean()


def test_numba_and_numpy_backends_are_identical():
    """The in-process runner (numba winners) and the module processes (numpy winners) must
    decide identically, bit for bit, for the distributed lockstep run to equal it."""
    net = make_network("R15", np.random.default_rng(9))
    fast_ekm, numpy_ekm = CooperativeEKM(net), CooperativeEKM(net, backend="numpy")
    rng = np.random.default_rng(1)
    for _ in range(300):
        t = TargetReading(rng.uniform(-np.pi, np.pi), rng.uniform(0.0005, 2.0))
        rs = [RangeReading(j, -np.pi + j * np.pi / 6, rng.uniform(0.03, 0.2) if rng.random() < 0.6 else None)
              for j in range(12)]
        a, b = fast_ekm.localize_target(t, 0.0), numpy_ekm.localize_target(t, 0.0)
        assert a.winner == b.winner and np.array_equal(a.a, b.a)
        oa, ob = fast_ekm.localize_obstacles(rs, 0.0), numpy_ekm.localize_obstacles(rs, 0.0)
        assert [o.winner for o in oa] == [o.winner for o in ob]
        assert fast_ekm.integrate(a, oa) == numpy_ekm.integrate(b, ob)


def test_remembered_winners_equal_the_competition():
    """The winner memo answers exactly what the competition (Eqs. 2-4) would, for repeated
    quantised sensor inputs, and stays bounded."""
    from cekm_swarm.controller import cooperative

    net = make_network("R15", np.random.default_rng(4))
    ekm = CooperativeEKM(net, backend="numpy")
    rng = np.random.default_rng(5)
    for _ in range(2000):
        alpha = -np.pi + int(rng.integers(12)) * np.pi / 6
        d = round(rng.uniform(0.03, 0.2) / 0.005) * 0.005  # 5 mm steps, as the world's distance sensors
        assert ekm.localize_obstacle(RangeReading(0, alpha, d), 0.0).winner == ekm._compete(alpha, d)
    assert 0 < len(ekm._winners) <= cooperative.WINNER_MEMO
    for k in range(cooperative.WINNER_MEMO + 10):  # distinct inputs: the memo starts again, never grows past its bound
        ekm.localize_target(TargetReading(0.1, 0.001 * (k + 1)), 0.0)
    assert len(ekm._winners) <= cooperative.WINNER_MEMO
