"""The trail field (cekm_swarm.controller.trail): progress, and which motor neurons it
inhibits, on a dead-reckoned pose."""

import math

import numpy as np
import pytest

from cekm_swarm.controller.dead_reckoning import DeadReckoning
from cekm_swarm.controller.trail import Trail, TrailParams, paper_turn

AXLE = 0.053


def lattice(n: int = 72) -> np.ndarray:
    """A motor lattice of directions only (alpha_k around the circle, d_k 0.05 m)."""
    alpha = np.linspace(-math.pi, math.pi, n, endpoint=False)
    return np.column_stack([alpha, np.full(n, 0.05)])


def drive(trail: Trail, dr: DeadReckoning, t0: float, t1: float, v_l: float, v_r: float, target_d=None,
          dt: float = 0.128) -> float:
    t = t0
    while t < t1 - 1e-9:
        dr.move(t, v_l, v_r, AXLE)
        trail.update(t, dr.pose, target_d)
        t += dt
    return t


def test_no_field_while_the_target_comes_nearer():
    tr, dr = Trail(), DeadReckoning()
    d = 1.0
    for k in range(200):  # 25 s, always getting nearer
        dr.move(k * 0.128, 0.1, 0.1, AXLE)
        tr.update(k * 0.128, dr.pose, d)
        d -= 0.01
        assert tr.field(k * 0.128, dr.pose, lattice()) is None


def test_after_patience_without_progress_it_inhibits_the_neurons_toward_old_places():
    tr, dr = Trail(), DeadReckoning()
    w = lattice()
    t = drive(tr, dr, 0.0, 2.0, 0.1, 0.1, target_d=1.0)  # 0.2 m along +x: places behind the robot
    t = drive(tr, dr, t, t + math.pi * AXLE / 0.04, -0.02, 0.02, target_d=1.0)  # turn round in place
    assert abs(math.remainder(dr.pose[2] - math.pi, 2 * math.pi)) < 0.1  # now facing the places it passed
    assert tr.field(t, dr.pose, w) is None  # they are recent, and patience has not run out
    t = drive(tr, dr, t, t + 10.0, 0.0, 0.0, target_d=1.0)  # stands still, no progress
    b = tr.field(t, dr.pose, w)
    assert b is not None and b.shape == (len(w),)
    ahead = int(np.argmin(np.abs(w[:, 0])))  # the neuron pointing straight ahead: at the old places
    behind = int(np.argmax(np.abs(w[:, 0])))
    assert b[ahead] > 0.3 and b[behind] < 0.01 * b[ahead]
    assert np.all(b <= TrailParams().gain + 1e-12) and np.all(b >= 0.0)


def test_places_are_forgotten_after_memory_and_a_new_best_resets_patience():
    p = TrailParams(memory=5.0)
    tr, dr = Trail(p), DeadReckoning()
    t = drive(tr, dr, 0.0, 20.0, 0.0, 0.0, target_d=1.0)
    assert tr.places and t - tr.places[0][0] <= 5.0 + 1e-9
    assert tr.best == (1.0, 0.0)
    tr.update(t, dr.pose, 0.9)
    assert tr.best == (0.9, t) and tr.field(t, dr.pose, lattice()) is None


def test_zero_gain_is_no_field():
    tr, dr = Trail(TrailParams(gain=0.0)), DeadReckoning()
    t = drive(tr, dr, 0.0, 30.0, 0.05, 0.1, target_d=1.0)  # circles without progress
    assert tr.field(t, dr.pose, lattice()) is None


def test_acting_for_counts_from_patience_after_the_last_progress():
    tr, dr = Trail(TrailParams(patience=8.0)), DeadReckoning()
    tr.update(0.0, dr.pose, 1.0)
    assert tr.acting_for(5.0) == pytest.approx(-3.0) and tr.acting_for(10.0) == pytest.approx(2.0)
    assert tr.field(5.0, dr.pose, lattice()) is None  # not acting yet
    tr.update(12.0, dr.pose, 0.9)  # progress: patience starts again
    assert tr.acting_for(12.0) == pytest.approx(-8.0) and tr.acting_for(21.0) == pytest.approx(1.0)


@pytest.mark.parametrize("acting_for,turn", [(-3.0, False), (0.0, False), (5.0, False), (19.99, False), (20.0, True),
                                             (39.99, True), (40.0, False), (59.0, False), (61.0, True)])
def test_the_papers_widths_take_every_second_period_once_the_trail_acts(acting_for, turn):
    assert paper_turn(acting_for, 20.0) is turn
    assert paper_turn(acting_for, 0.0) is False  # period 0: never


@pytest.mark.parametrize("name,value,words", [("gain", -0.1, "trail gain must be >= 0"),
                                              ("sigma", 0.0, "trail sigma must be > 0"),
                                              ("radius", -1.0, "trail radius must be > 0")])
def test_bad_parameters_are_refused_by_name(name, value, words):
    with pytest.raises(ValueError, match=words):
        TrailParams(**{name: value}).check()
