import numpy as np
import pytest

from cekm_swarm.angles import wrap
from cekm_swarm.models import fast
from cekm_swarm.models.competition import direction_set, weighted_difference, winner
from cekm_swarm.models.params import CompetitionParams


def test_wrap_range_and_identity():
    a = np.linspace(-20, 20, 4001)
    w = wrap(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    assert np.allclose(np.sin(w), np.sin(a)) and np.allclose(np.cos(w), np.cos(a))
    assert wrap(np.pi) == np.pi and wrap(-np.pi) == np.pi


def test_direction_beats_distance():
    """A neuron with the right direction but the wrong distance beats a nearer one off-direction (Eq. 4)."""
    p = CompetitionParams(direction_tolerance=0.02)
    w = np.array([[0.05, 0.10],   # 0.05 rad off, exact distance: nearest by D
                  [0.00, 0.00]])  # exact direction, 0.1 m off
    u = np.array([0.0, 0.10])
    d = weighted_difference(u, w, p)
    assert d[0] < d[1]  # by plain distance neuron 0 would win
    assert winner(u, w, p) == 1
    # with a tolerance that admits both directions, distance decides
    assert winner(u, w, CompetitionParams(direction_tolerance=0.1)) == 0


def test_wrap_around_at_pi():
    p = CompetitionParams(direction_tolerance=0.05)
    w = np.array([[np.pi - 0.2, 0.05], [-np.pi + 0.01, 0.05], [0.0, 0.05]])
    u = np.array([np.pi - 0.01, 0.05])  # 0.02 rad from neuron 1 across +-pi
    assert winner(u, w, p) == 1
    assert direction_set(u, w, p).tolist() == [False, True, False]


def test_fast_winner_equals_reference():
    rng = np.random.default_rng(3)
    p = CompetitionParams()
    pv = fast.pack_params(
        p, __import__("cekm_swarm.models.params", fromlist=["LearningParams"]).LearningParams(), 0.15625, 1e-3
    )
    w = np.stack([rng.uniform(-np.pi, np.pi, 225), rng.uniform(0, 0.16, 225)], axis=1)
    for _ in range(500):
        u = np.array([rng.uniform(-4, 4), rng.uniform(0, 0.3)])
        assert fast.winner(u[0], u[1], w, pv) == winner(u, w, p)


@pytest.mark.parametrize("bad", [dict(beta_alpha=0), dict(beta_d=-1), dict(direction_tolerance=-0.1)])
def test_bad_parameters_are_refused(bad):
    with pytest.raises(ValueError, match="CompetitionParams"):
        CompetitionParams(**bad)
