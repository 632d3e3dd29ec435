import numpy as np
import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.models.networks import IndirectEKM, make_network, parameter_count, parse_network_name

TABLE1 = {"B15": 1350, "D15": 900, "G9": 486, "G12": 864, "G15": 1350, "R15": 1350}


@pytest.mark.parametrize("name,count", TABLE1.items())
def test_parameter_counts_equal_table1(name, count):
    kind, size = parse_network_name(name)
    assert parameter_count(kind, size) == count
    net = make_network(name, np.random.default_rng(0))
    stored = {"indirect-gd": ("w", "M"), "indirect-rls": ("w", "M"), "direct": ("w", "C"),
              "bfn": ("w", "widths", "W")}[kind]
    assert sum(getattr(net, a).size for a in stored) == count


@pytest.mark.parametrize("bad", ["X15", "R", "R1", "R99", "15", ""])
def test_bad_network_names_are_refused(bad):
    with pytest.raises(ParameterError, match="network"):
        parse_network_name(bad)


@pytest.mark.parametrize("name", TABLE1)
def test_goal_state_stops_every_network(name):
    net = make_network(name, np.random.default_rng(1))
    assert np.array_equal(net.command(np.array([0.0, 0.0])), [0.0, 0.0])
    assert np.any(net.command(np.array([0.5, 0.5])) != 0.0)


def test_indirect_command_is_eq11_with_k_equal_s():
    net = make_network("R15", np.random.default_rng(2))
    u = np.array([0.3, 0.02])
    c = net.command(u)
    from cekm_swarm.models.competition import winner
    s = winner(u, net.w, net.comp)
    x = np.array([net.w[s, 0] + ((u[0] - net.w[s, 0] + np.pi) % (2 * np.pi) - np.pi), net.learn_p.d_scale * u[1]])
    full = net.M[s] @ x
    expected = (
        full if np.all(np.abs(full) <= net.v_max) else net.M[s] @ [net.w[s, 0], net.learn_p.d_scale * net.w[s, 1]]
    )
    np.testing.assert_allclose(c, expected)


def test_kinematic_initial_guess_moves_straight_for_a_target_ahead():
    net = IndirectEKM.kinematic(15)
    c = net.command(np.array([0.0, 0.08]))
    assert c[0] > 0 and np.isclose(c[0], c[1])  # both wheels forward equally
    c = net.command(np.array([0.5, 0.001]))
    assert c[1] > c[0]  # target to the left: turn left


def test_learning_moves_the_winner_toward_the_displacement():
    net = make_network("G9", np.random.default_rng(3))
    w0 = net.w.copy()
    v, c = np.array([0.1, 0.05]), np.array([0.05, 0.06])
    net.learn(v, c, t=0.0)
    moved = np.flatnonzero(np.any(net.w != w0, axis=1))
    assert moved.size > 0
    assert np.all(np.abs(net.w[moved, 1] - v[1]) <= np.abs(w0[moved, 1] - v[1]) + 1e-12)


def _small_bfn():
    """A 2 x 2 B-network by hand: centres at alpha +-1 rad, d 0 and 0.1 m; units 0 and 1 have won."""
    from cekm_swarm.models.lattice import Lattice
    from cekm_swarm.models.networks import BasisFunctionNetwork

    w = np.array([[-1.0, 0.0], [1.0, 0.0], [-1.0, 0.1], [1.0, 0.1]])
    widths = np.tile([1.0, 0.05], (4, 1))
    W = np.array([[0.01, 0.02], [0.03, 0.04], [0.05, 0.06], [0.07, 0.08]])
    return BasisFunctionNetwork(Lattice(2), w, widths, W, np.array([True, True, False, False]))


def test_bfn_command_matches_hand_computed_values():
    """u = (0.5, 0.04): only the won units 0 and 1 take part; the direction set A(0.5) among them
    is unit 1 (|0.5 - 1| = 0.5 against 1.5), so d is presented at its edge, d_1 = 0; then
    q_0 = 1.5^2 / 2 = 1.125, q_1 = 0.5^2 / 2 = 0.125, phi = (e^-1, 1) / (1 + e^-1)."""
    net = _small_bfn()
    phi0, phi1 = 0.2689414213699951, 0.7310585786300049
    np.testing.assert_allclose(net.activations(np.array([0.5, 0.04])), [phi0, phi1, 0.0, 0.0], rtol=1e-12)
    np.testing.assert_allclose(
        net.command(np.array([0.5, 0.04])), [phi0 * 0.01 + phi1 * 0.03, phi0 * 0.02 + phi1 * 0.04], rtol=1e-12
    )


def test_bfn_learning_step_matches_hand_computed_values():
    """One learn(v, c, t=0) with v = (0.5, 0.04), c = (0.1, 0):
    * output weights, gradient descent on every unit: W_i += eta_bfn phi_i (c - phi . W);
    * winner of v (Eq. 2-4 over all centres): unit 1; sigma(0) = 1, so G = exp(-|r_1 - r_i|^2 / 2)
      = (e^-0.5, 1, e^-1, e^-0.5) over lattice positions (0,0), (0,1), (1,0), (1,1);
    * widths toward the nearest lattice neighbour's distance in Eq. 3's metric: every unit's nearest
      is its direction-axis neighbour, 2 rad away (its distance-axis one is 0.1 m x 2 pi / 0.16 = 3.93),
      so the targets are (2 rad, 2 x 0.16 / (2 pi) m); sigma += eta_width G (target - sigma);
    * centres by Eq. 12: w_i += eta_w G (v - w_i)."""
    net = _small_bfn()
    lp = net.learn_p
    phi = np.array([0.2689414213699951, 0.7310585786300049, 0.0, 0.0])
    out = np.array([phi[0] * 0.01 + phi[1] * 0.03, phi[0] * 0.02 + phi[1] * 0.04])
    err = np.array([0.1, 0.0]) - out
    W_expected = net.W + lp.eta_bfn * phi[:, None] * err[None, :]
    G = np.exp(-np.array([1.0, 0.0, 2.0, 1.0]) / 2.0)
    target = np.array([2.0, 2.0 * 0.16 / (2.0 * np.pi)])
    widths_expected = net.widths + (lp.eta_width * G)[:, None] * (target[None, :] - net.widths)
    v = np.array([0.5, 0.04])
    w_expected = net.w + (lp.eta_w * G)[:, None] * (v[None, :] - net.w)  # no angle crosses +-pi here
    net.learn(v, np.array([0.1, 0.0]), 0.0)
    np.testing.assert_allclose(net.W, W_expected, rtol=1e-12)
    np.testing.assert_allclose(net.widths, widths_expected, rtol=1e-12)
    np.testing.assert_allclose(net.w, w_expected, rtol=1e-12, atol=1e-15)
    assert net.won.tolist() == [True, True, False, False]  # unit 1 won again


def test_bfn_fast_path_equals_the_hand_computed_case():
    from cekm_swarm.models import fast
    from cekm_swarm.models.networks import BFN_WIDTH_FLOOR

    ref = _small_bfn()
    w, P, R = fast.network_arrays(ref)
    p = fast.pack_params(ref.comp, ref.learn_p, 0.15625, BFN_WIDTH_FLOOR)
    c = np.empty(2)
    fast.command(fast.KIND_BFN, 0.5, 0.04, w, P, R, p, c)
    np.testing.assert_allclose(c, ref.command(np.array([0.5, 0.04])), rtol=1e-12)
    fast.learn(fast.KIND_BFN, 0.5, 0.04, 0.1, 0.0, 0.0, w, P, R, 2, p, np.empty(4, dtype=np.int64), np.empty(4))
    ref.learn(np.array([0.5, 0.04]), np.array([0.1, 0.0]), 0.0)
    w2, P2, R2 = fast.network_arrays(ref)
    np.testing.assert_allclose(w, w2, rtol=1e-12)
    np.testing.assert_allclose(P, P2, rtol=1e-12)
    np.testing.assert_array_equal(R, R2)


def test_bfn_paper_rule_every_unit_drives_the_output_and_widths_approach_the_nearest_centre():
    """The paper's B15 on the same 2 x 2 network: all four units take part (the direction set
    A(0.5) is then units 1 and 3, whose farthest centre is d = 0.1, so d = 0.04 is presented
    as it is), and one learning step moves each updated width toward the distance to its
    nearest centre in Eq. 3's metric. Unit i's nearest centre is, here as with the lattice
    rule, its direction-axis neighbour 2 rad away, so the width targets match the lattice
    rule's; the output differs (units 2 and 3 now count)."""
    from cekm_swarm.models import fast
    from cekm_swarm.models.networks import BFN_WIDTH_FLOOR, nearest_centre_widths

    net = _small_bfn()
    net.rule = "paper"
    u = np.array([0.5, 0.04])
    q = np.array([1.5 ** 2 / 2 + 0.8 ** 2 / 2, 0.5 ** 2 / 2 + 0.8 ** 2 / 2, 1.5 ** 2 / 2 + 1.2 ** 2 / 2,
                  0.5 ** 2 / 2 + 1.2 ** 2 / 2])
    phi = np.exp(-q) / np.exp(-q).sum()
    np.testing.assert_allclose(net.activations(u), phi, rtol=1e-12)
    np.testing.assert_allclose(net.output(u), phi @ net.W, rtol=1e-12)
    np.testing.assert_allclose(nearest_centre_widths(net.w, 0, net.comp), [2.0, 2.0 * 0.16 / (2 * np.pi)], rtol=1e-12)
    w, P, R = fast.network_arrays(net)
    p = fast.pack_params(net.comp, net.learn_p, 0.15625, BFN_WIDTH_FLOOR, "paper")
    c = np.empty(2)
    fast.output(fast.KIND_BFN, 0.5, 0.04, w, P, R, p, c)
    np.testing.assert_allclose(c, net.output(u), rtol=1e-12)
    # a centre moved next to unit 0: its nearest centre is no longer a lattice neighbour
    net.w[3] = [-0.9, 0.01]
    rho = np.sqrt(0.1 ** 2 + net.comp.beta_d * 0.01 ** 2)
    np.testing.assert_allclose(nearest_centre_widths(net.w, 0, net.comp),
                               [rho, rho / np.sqrt(net.comp.beta_d)], rtol=1e-12)
    w, P, R = fast.network_arrays(net)
    fast.learn(fast.KIND_BFN, 0.5, 0.04, 0.1, 0.0, 0.0, w, P, R, 2, p, np.empty(4, dtype=np.int64), np.empty(4))
    net.learn(u, np.array([0.1, 0.0]), 0.0)
    w2, P2, R2 = fast.network_arrays(net)
    np.testing.assert_allclose(w, w2, rtol=1e-12)
    np.testing.assert_allclose(P, P2, rtol=1e-12)


def test_bfn_rule_is_checked():
    from cekm_swarm.models.networks import BasisFunctionNetwork

    with pytest.raises(ParameterError, match="rule"):
        BasisFunctionNetwork.untrained(3, np.random.default_rng(0), rule="other")
