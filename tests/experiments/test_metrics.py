import math

import numpy as np

from cekm_swarm.experiments.metrics import mean_std, score, welch_p
from cekm_swarm.experiments.trial import TestOutcome


def test_score_eqs_18_to_20_and_eps_versions():
    o = TestOutcome(
        final_dist=np.array([0.001, 0.003]), stopped=np.array([True, False]), steps=np.array([10, 20]),
        path=np.array([1.1, 2.0]), straight=np.array([1.0, 2.0]),
        t_eps=np.array([[5.0, 4.0], [np.nan, 8.0]]), path_eps=np.array([[1.05, 1.0], [np.nan, 2.2]]))
    s = score(o, step_s=1.0)
    assert math.isclose(s.E_mm, 2.0)
    assert math.isclose(s.T_s_per_m, (10 / 1.0 + 20 / 2.0) / 2)
    assert math.isclose(s.D, (0.1 + 0.0) / 2)
    assert s.ended_by_budget == 1
    np.testing.assert_allclose(s.P, [0.5, 1.0])
    np.testing.assert_allclose(s.T_eps, [5.0, (4.0 + 4.0) / 2])
    np.testing.assert_allclose(s.D_eps, [0.05, (0.0 + 0.1) / 2])


def test_mean_std_and_welch():
    assert mean_std([1.0, 3.0]) == {"mean": 2.0, "std": math.sqrt(2.0)}
    assert mean_std([np.nan]) == {"mean": None, "std": None}
    assert welch_p([1, 2, 3, 4, 5], [1, 2, 3, 4, 5]) > 0.99
    assert welch_p([1, 1.1, 0.9, 1.05, 0.95], [3, 3.1, 2.9, 3.05, 2.95]) < 1e-6
    assert welch_p([1, 1, 1], [1, 1, 1]) == 1.0
