import numpy as np

from cekm_swarm.models import learning
from cekm_swarm.models.lattice import Lattice, neighbourhood


def _data(rng, n=40):
    V = np.stack([rng.uniform(-1, 1, n), rng.uniform(-2, 2, n)], axis=1)
    true_M = np.array([[0.3, -0.1], [0.2, 0.4]])
    C = V @ true_M.T + 0.01 * rng.standard_normal((n, 2))
    return V, C


def test_rls_with_lambda_one_equals_regularized_batch_least_squares():
    """lambda = 1, G = 1: RLS from R^-1 = I and M0 is exactly the ridge solution
    M = (sum c v^T + M0) (sum v v^T + I)^-1 (the prior R = I, M0 counted as data)."""
    rng = np.random.default_rng(0)
    V, C = _data(rng)
    M0 = rng.uniform(-0.1, 0.1, (2, 2))
    M, Rinv = M0[None].copy(), np.eye(2)[None].copy()
    idx, g = np.array([0]), np.array([1.0])
    for v, c in zip(V, C, strict=True):
        learning.recursive_least_squares(M, Rinv, v[None], c, idx, g, forgetting=1.0, trace_cap=1e300)
    expected = (C.T @ V + M0) @ np.linalg.inv(V.T @ V + np.eye(2))
    np.testing.assert_allclose(M[0], expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Rinv[0], np.linalg.inv(V.T @ V + np.eye(2)), rtol=1e-10)


def test_rls_with_lambda_one_equals_batch_least_squares_from_a_vague_prior():
    rng = np.random.default_rng(1)
    V, C = _data(rng)
    M, Rinv = np.zeros((1, 2, 2)), (1e8 * np.eye(2))[None].copy()
    for v, c in zip(V, C, strict=True):
        learning.recursive_least_squares(M, Rinv, v[None], c, np.array([0]), np.array([1.0]), 1.0, 1e300)
    lstsq = np.linalg.lstsq(V, C, rcond=None)[0].T
    np.testing.assert_allclose(M[0], lstsq, rtol=1e-6, atol=1e-8)


def test_rls_gain_form_eq17_matches_textbook_gain():
    """Eq. 17 with R^-1 after Eq. 16 equals M += (c - M v) K^T, K = P v / (lambda/G + v^T P v)."""
    rng = np.random.default_rng(2)
    P0 = np.array([[2.0, 0.3], [0.3, 0.5]])
    M0 = rng.standard_normal((2, 2))
    v, c, g, lam = np.array([0.4, -1.3]), np.array([0.1, -0.2]), 0.37, 0.99
    M, R = M0[None].copy(), P0[None].copy()
    learning.recursive_least_squares(M, R, v[None], c, np.array([0]), np.array([g]), lam, 1e300)
    K = P0 @ v / (lam / g + v @ P0 @ v)
    np.testing.assert_allclose(M[0], M0 + np.outer(c - M0 @ v, K), rtol=1e-12)


def test_rls_trace_cap_bounds_covariance():
    M, R = np.zeros((1, 2, 2)), np.eye(2)[None].copy()
    for _ in range(5000):  # forgetting without information winds R^-1 up
        learning.recursive_least_squares(
            M, R, np.array([[1e-6, 0.0]]), np.zeros(2), np.array([0]), np.array([1.0]), 0.99, 50.0
        )
    assert np.trace(R[0]) <= 50.0 + 1e-9


def test_gradient_descent_eq15_step():
    M = np.zeros((3, 2, 2))
    x = np.array([[1.0, 2.0]])
    learning.gradient_descent(M, x, np.array([1.0, -1.0]), np.array([1]), np.array([0.5]), eta=0.1)
    np.testing.assert_allclose(M[1], 0.05 * np.outer([1.0, -1.0], [1.0, 2.0]))
    assert not M[0].any() and not M[2].any()


def test_input_weight_update_eq12_wraps():
    w = np.array([[3.1, 0.1]])
    learning.update_input_weights(w, np.array([-3.1, 0.2]), np.array([0]), np.array([1.0]), eta=0.5)
    # the short way round across +-pi, not through 0
    assert w[0, 0] > 3.1 or w[0, 0] < -3.1
    assert abs(w[0, 1] - 0.15) < 1e-12


def test_branch_keeps_linear_model_continuous_at_pi():
    assert np.isclose(learning.on_branch(-3.1, np.array([3.1]))[0], 2 * np.pi - 3.1)
    assert learning.on_branch(0.0, np.array([0.5]))[0] == 0.0


def test_lattice_initial_weights_and_neighbourhood():
    lat = Lattice(15)
    w = lat.initial_weights()
    assert w.shape == (225, 2)
    assert np.isclose(w[:, 0].min(), -np.pi) and w[:, 0].max() < np.pi  # no duplicate column at +-pi
    assert np.isclose(w[:, 1].min(), 0.0) and np.isclose(w[:, 1].max(), 0.16)
    g = neighbourhood(lat.positions(), 16, sigma=1.0)
    assert g[16] == 1.0 and np.isclose(g[17], np.exp(-0.5)) and np.isclose(g[0], np.exp(-1.0))
