"""The reference runner (readable networks, Python loop) and the fast batched numba runner agree."""

import numpy as np
import pytest

from cekm_swarm.experiments import trial
from cekm_swarm.experiments.arena import Arena
from cekm_swarm.experiments.streams import Schedule, TrialStreams
from cekm_swarm.models import fast
from cekm_swarm.models.networks import BFN_WIDTH_FLOOR, make_network

# short enough that floating-point differences (numpy vs libm exp, summation order) have not yet
# tipped a near-tie in the competition; past a few hundred steps the closed loop is chaotic
SCHEDULE = Schedule(steps=200, test_interval=100, test_targets=3, test_budget=40, train_budget=40)
EPS = np.array([0.001, 0.005, 0.03])


@pytest.mark.parametrize("name", ["R9", "G9", "D9", "B9"])
def test_reference_and_fast_paths_are_equal(name):
    arena = Arena()
    streams = [TrialStreams(11, t, arena, SCHEDULE) for t in range(2)]
    nets = [make_network(name, s.init_rng()) for s in streams]
    arrays = [fast.network_arrays(n) for n in nets]
    batch = trial.NetworkBatch(
        nets[0].kind,
        nets[0].lattice.size,
        *(np.stack([a[q] for a in arrays]) for q in range(3)),
        fast.pack_params(nets[0].comp, nets[0].learn_p, arena.v_max, BFN_WIDTH_FLOOR),
    )
    fast_out = trial.run_batch(batch, streams, EPS)
    for b, (net, st) in enumerate(zip(nets, streams, strict=True)):
        ref_out = trial.run_reference(net, st, EPS)
        w, P, R = fast.network_arrays(net)
        np.testing.assert_allclose(batch.W[b], w, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(batch.P[b], P, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(batch.R[b], R, rtol=1e-7, atol=1e-9)
        assert len(ref_out) == len(fast_out[b]) == 3
        for r, f in zip(ref_out, fast_out[b], strict=True):
            np.testing.assert_array_equal(r.stopped, f.stopped)
            np.testing.assert_array_equal(r.steps, f.steps)
            np.testing.assert_allclose(r.final_dist, f.final_dist, rtol=1e-6, atol=1e-8)
            np.testing.assert_allclose(r.path, f.path, rtol=1e-6, atol=1e-8)
            np.testing.assert_allclose(r.t_eps, f.t_eps, rtol=1e-6, atol=1e-8)


def test_trials_of_a_batch_are_independent():
    """A trial's result does not depend on which other trials share its batch."""
    arena = Arena()
    streams = [TrialStreams(5, t, arena, SCHEDULE) for t in range(3)]

    def run(sts):
        nets = [make_network("R9", s.init_rng()) for s in sts]
        arrays = [fast.network_arrays(n) for n in nets]
        batch = trial.NetworkBatch("indirect-rls", 9, *(np.stack([a[q] for a in arrays]) for q in range(3)),
                                   fast.pack_params(nets[0].comp, nets[0].learn_p, arena.v_max, BFN_WIDTH_FLOOR))
        return batch, trial.run_batch(batch, sts, EPS)

    b_all, out_all = run(streams)
    b_one, out_one = run(streams[2:])
    np.testing.assert_array_equal(b_all.P[2], b_one.P[0])
    np.testing.assert_array_equal(out_all[2][-1].final_dist, out_one[0][-1].final_dist)


def test_streams_are_common_across_networks_and_seeded():
    arena = Arena()
    a, b = TrialStreams(1, 0, arena, SCHEDULE), TrialStreams(1, 0, arena, SCHEDULE)
    np.testing.assert_array_equal(a.test_set[0], b.test_set[0])
    np.testing.assert_array_equal(a.train_chunk(1, 10)[0], b.train_chunk(1, 10)[0])
    assert not np.array_equal(a.test_set[0], TrialStreams(2, 0, arena, SCHEDULE).test_set[0])
    assert not np.array_equal(a.test_set[0], TrialStreams(1, 1, arena, SCHEDULE).test_set[0])
    t = a.test_set[0]
    assert t.min() >= arena.target_margin and t.max() <= arena.size - arena.target_margin


@pytest.mark.parametrize("name,bfn_rule", [("R15", "paper"), ("G12", "paper"), ("D15", "paper"), ("B15", "paper"),
                                           ("B15", "trained-units")])
def test_fast_rules_equal_reference_rules_step_by_step(name, bfn_rule):
    """Each learning step, each command and each output of the fast path equals the reference's,
    from the same state, over many random inputs (no closed loop, so no chaos to amplify
    differences)."""
    rng = np.random.default_rng(42)
    net = make_network(name, rng, bfn_rule=bfn_rule)
    params = fast.pack_params(net.comp, net.learn_p, 0.15625, BFN_WIDTH_FLOOR, bfn_rule)
    w, P, R = fast.network_arrays(net)
    n = w.shape[0]
    idx, g, c = np.empty(n, dtype=np.int64), np.empty(n), np.empty(2)
    for t in range(300):
        v = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(0, 0.17)])
        cmd = rng.uniform(-0.15, 0.15, 2)
        net.learn(v, cmd, float(t * 50))
        fast.learn(
            fast.KIND_CODE[net.kind],
            v[0],
            v[1],
            cmd[0],
            cmd[1],
            float(t * 50),
            w,
            P,
            R,
            net.lattice.size,
            params,
            idx,
            g,
        )
        rw, rP, rR = fast.network_arrays(net)
        np.testing.assert_allclose(w, rw, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(P, rP, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(R, rR, rtol=1e-10, atol=1e-14)
        w[:], P[:], R[:] = rw, rP, rR  # re-synchronize so each step is compared from one state
        u = np.array([rng.uniform(-4, 4), rng.uniform(0.0005, 3.0)])
        fast.command(fast.KIND_CODE[net.kind], u[0], u[1], w, P, R, params, c)
        np.testing.assert_allclose(c, net.command(u), rtol=1e-10, atol=1e-14)
        u0 = np.array([rng.uniform(-4, 4), 0.0]) if t % 3 == 0 else u  # the goal state too
        fast.output(fast.KIND_CODE[net.kind], u0[0], u0[1], w, P, R, params, c)
        np.testing.assert_allclose(c, net.output(u0), rtol=1e-10, atol=1e-14)
