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
    expected = full if np.all(np.abs(full) <= net.v_max) else net.M[s] @ [net.w[s, 0], net.learn_p.d_scale * net.w[s, 1]]
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
