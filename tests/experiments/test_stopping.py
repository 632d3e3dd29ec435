"""The two stop rules of section 4.1 (experiments/stopping.py), each pinned on hand-built cases,
and the circling their plants produce (docs/reproduction-4.1.md section 1)."""

import math

import numpy as np
import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments import trial
from cekm_swarm.experiments.arena import Arena, drive, executed_command, sense_target
from cekm_swarm.experiments.circling import kinematic_command
from cekm_swarm.experiments.stopping import GOAL_STOP, PAPER_STOP, StopRule, stopped
from cekm_swarm.experiments.streams import Schedule, TrialStreams
from cekm_swarm.models import fast
from cekm_swarm.models.lattice import Lattice
from cekm_swarm.models.networks import BFN_WIDTH_FLOOR, DirectEKM, IndirectEKM
from cekm_swarm.robot import KHEPERA

EPS = np.array([0.005])
SCHEDULE = Schedule(steps=10, test_interval=10, test_targets=3, test_budget=30)


def test_stop_rule_formula():
    """command: a network command under half the 8 mm/s unit on both wheels is a stop; goal: only
    an executed command of 0 is (on continuous wheels that is the goal state's c = 0)."""
    assert PAPER_STOP.motor_resolution == KHEPERA.speed_unit == 0.008 and PAPER_STOP.code == 0.008
    assert GOAL_STOP.code == 0.0
    assert stopped(0.0039, -0.0039, 0.0039, -0.0039, PAPER_STOP.code)
    assert not stopped(0.0041, 0.0, 0.0041, 0.0, PAPER_STOP.code)
    assert not stopped(0.0039, -0.0039, 0.0039, -0.0039, GOAL_STOP.code)
    assert stopped(0.0039, -0.0039, 0.0, 0.0, GOAL_STOP.code)  # executed as 0 (a quantized plant): a stop
    assert stopped(0.003, 0.0, 0.003, 0.0, StopRule("command", 0.01).code)
    for bad in (dict(rule="sensor"), dict(motor_resolution=0.0), dict(motor_resolution=1.0)):
        with pytest.raises(ParameterError, match="StopRule"):
            StopRule(**bad)


def _creep(u):
    return np.array([0.0039, -0.0035])


def test_a_small_command_ends_a_test_target_only_under_the_command_rule():
    """A controller that always commands (3.9, -3.5) mm/s: under the paper's rule the robot has
    stopped at once (step 0, E = the starting distance); under the goal rule it is never at the
    goal state, so it creeps until the step budget ends each target."""
    streams = TrialStreams(1, 0, Arena(), SCHEDULE)
    paper = trial.test_reference(_creep, streams, EPS, PAPER_STOP)
    assert paper.stopped.all() and (paper.steps == 0).all() and (paper.path == 0).all()
    assert not paper.at_goal.any()  # stopped by its command, away from the goal state
    np.testing.assert_allclose(paper.final_dist[0], paper.straight[0])
    goal = trial.test_reference(_creep, streams, EPS, GOAL_STOP)
    assert not goal.stopped.any() and (goal.steps == SCHEDULE.test_budget).all() and (goal.path > 0).all()


def _direct_network(goal_command):
    """A 2 x 2 direct EKM by hand: every neuron stores 'forward at 0.1 m/s' except the one
    nearest the goal state (alpha 0, d 0), which stores goal_command."""
    w = np.array([[0.0, 0.0], [math.pi / 2, 0.0], [0.0, 0.1], [-math.pi / 2, 0.1]])
    C = np.tile([0.1, 0.1], (4, 1))
    C[0] = goal_command
    return DirectEKM(Lattice(2), w, C)


def test_at_the_goal_state_a_direct_ekm_stops_only_if_its_winner_stores_a_small_command():
    """Under the goal rule every network stops at the goal state (c = 0 by that rule). Under
    the paper's rule the direct EKM outputs its winner's stored c_s there: a stop only if c_s
    is under half the motor's unit; the indirect EKM's output there is M_s 0 = 0 (Eq. 1)."""
    u0 = np.array([0.0, 0.0])
    moving = _direct_network([0.006, -0.006])
    assert np.array_equal(moving.command(u0), [0.0, 0.0])
    np.testing.assert_array_equal(moving.output(u0), [0.006, -0.006])
    q = executed_command(0.006, -0.006, Arena().vector())
    assert stopped(0.0, 0.0, 0.0, 0.0, GOAL_STOP.code) and not stopped(0.006, -0.006, *q, PAPER_STOP.code)
    assert stopped(*_direct_network([0.003, -0.002]).output(u0), 0.003, -0.002, PAPER_STOP.code)
    r = IndirectEKM.untrained(9, "rls", np.random.default_rng(0))
    assert np.all(np.abs(r.output(u0)) < 1e-12) and np.array_equal(r.command(u0), [0.0, 0.0])


def test_fast_kernels_follow_the_rules_on_the_hand_built_direct_ekm():
    """The numba test kernel on the hand-built direct EKM, robot on the target: under goal it
    stops at step 0 with E under the sensor's 0.5 mm; under command the stored (6, -6) mm/s
    spins it in place until the budget; with a stored (3, -2) mm/s it stops at step 0."""
    arena = Arena(size=5.0)
    for goal_command, rule, expect_stop in (([0.006, -0.006], GOAL_STOP, True), ([0.006, -0.006], PAPER_STOP, False),
                                            ([0.003, -0.002], PAPER_STOP, True)):
        net = _direct_network(goal_command)
        w, P, R = fast.network_arrays(net)
        batch = trial.NetworkBatch("direct", 2, w[None], P[None], R[None],
                                   fast.pack_params(net.comp, net.learn_p, arena.v_max, BFN_WIDTH_FLOOR))
        streams = TrialStreams(3, 0, arena, SCHEDULE)
        targets = np.tile(arena.centre, (SCHEDULE.test_targets, 1)) + 1e-4  # 0.14 mm from the start
        streams.__dict__["test_set"] = (targets, *streams.test_set[1:])
        out = trial.test_batch(batch, [streams], EPS, rule)[0]
        ref = trial.test_reference(trial.network_command(net, rule), streams, EPS, rule)
        assert out.stopped.tolist() == ref.stopped.tolist() == [expect_stop] * 3, (goal_command, rule)
        assert out.at_goal.tolist() == ref.at_goal.tolist() == [expect_stop] * 3  # on the target: d reads 0
        np.testing.assert_allclose(out.final_dist, ref.final_dist, rtol=1e-9, atol=1e-12)
        if expect_stop:
            assert (out.steps == 0).all() and (out.final_dist < 0.0005).all()
        else:
            assert (out.steps == SCHEDULE.test_budget).all()


@pytest.mark.parametrize("name", ["R9", "D9", "B9"])
@pytest.mark.parametrize("rule", [GOAL_STOP, PAPER_STOP])
def test_reference_and_fast_paths_agree_under_each_rule(name, rule):
    from cekm_swarm.models.networks import make_network

    schedule = Schedule(steps=200, test_interval=100, test_targets=3, test_budget=40, train_budget=40)
    arena = Arena()
    streams = [TrialStreams(11, 0, arena, schedule)]
    net = make_network(name, streams[0].init_rng(), bfn_rule="paper")
    w, P, R = fast.network_arrays(net)
    batch = trial.NetworkBatch(net.kind, 9, w[None], P[None], R[None],
                               fast.pack_params(net.comp, net.learn_p, arena.v_max, BFN_WIDTH_FLOOR, "paper"))
    fast_out = trial.run_batch(batch, streams, EPS, stop=rule, train_stop=rule)[0]
    ref_out = trial.run_reference(net, streams[0], EPS, stop=rule, train_stop=rule)
    for r, f in zip(ref_out, fast_out, strict=True):
        np.testing.assert_array_equal(r.stopped, f.stopped)
        np.testing.assert_array_equal(r.steps, f.steps)
        np.testing.assert_allclose(r.final_dist, f.final_dist, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(batch.W[0], fast.network_arrays(net)[0], rtol=1e-7, atol=1e-9)


@pytest.mark.slow
def test_trace_is_the_measured_test_path():
    """trace_test records the very path test_batch measures (same kernel), target by target."""
    arena = Arena()
    schedule = Schedule(steps=10, test_interval=10, test_targets=4, test_budget=60)
    streams = TrialStreams(2, 0, arena, schedule)
    net = IndirectEKM.kinematic(9)
    w, P, R = fast.network_arrays(net)
    batch = trial.NetworkBatch(net.kind, 9, w[None], P[None], R[None],
                               fast.pack_params(net.comp, net.learn_p, arena.v_max, BFN_WIDTH_FLOOR))
    out = trial.test_batch(batch, [streams], EPS, PAPER_STOP)[0]
    traces = trial.trace_test(batch, 0, streams, PAPER_STOP)
    lengths = np.sum(~np.isnan(traces[:, :, 0]), axis=1)
    # a stop at step j records steps 0..j; a budget end records every step
    np.testing.assert_array_equal(lengths, np.where(out.stopped, out.steps + 1, schedule.test_budget))
    targets = streams.test_set[0]
    last = traces[np.arange(4), lengths - 1]
    stopped_rows = out.stopped
    np.testing.assert_array_equal(
        np.hypot(targets[stopped_rows, 0] - last[stopped_rows, 0], targets[stopped_rows, 1] - last[stopped_rows, 1]),
        out.final_dist[stopped_rows],
    )


# ---------------------------------------------------------------- the circling


def _pivot_cycle(speed_unit: float, steps: int = 12):
    """The exact kinematic controller (the arc that moves the robot onto the sensed target in
    one step) from 2 mm short of a target 0.1 rad to the left, under the paper's stop rule,
    on noise-free wheels: returns the sensed (alpha, d) and the executed command per step."""
    arena = Arena(speed_unit=speed_unit).vector()
    pose = np.array([1.0, 1.0, 0.0])
    tx, ty = 1.0 + 0.002 * math.cos(0.1), 1.0 + 0.002 * math.sin(0.1)
    seen = []
    empty = np.empty(0)
    for _ in range(steps):
        a, d = sense_target(pose[0], pose[1], pose[2], tx, ty, 1.0, 1.0, KHEPERA.target_resolution)
        c = (0.0, 0.0) if d == 0.0 else kinematic_command(a, d, abs(a) > math.pi / 2)
        q = executed_command(*c, arena)
        seen.append((a, d, q))
        if stopped(*c, *q, PAPER_STOP.code):
            break
        drive(pose, q[0], q[1], np.ones((32, 2)), arena, tx, ty, empty, empty, empty, 0.0, 0.0)
    return seen


def test_the_exact_controller_stops_on_continuous_wheels():
    """The kinematically exact command for (0.1 rad, 2 mm), about (-3.2, 7.1) mm/s, is not a stop
    (the turn is needed at any d: the inverse of a differential drive at d -> 0 is a spin by
    2 alpha, not c = 0); executed as commanded it lands on the target, which reads d = 0."""
    seen = _pivot_cycle(0.0)
    a, d, q = seen[0]
    assert d == pytest.approx(0.002) and a == pytest.approx(0.1, abs=1e-9)
    assert q == pytest.approx((-0.0032, 0.0071), abs=2e-4)
    assert len(seen) == 2 and seen[-1][1] == 0.0


def test_wheels_quantized_to_8_mm_s_make_the_exact_controller_circle():
    """On wheels quantized to 8 mm/s the same command executes as (0, 8) mm/s, a pivot that moves
    the centre 4.1 mm (the smallest move the plant has in a 1.024 s step): past the target, which
    is then 2 mm behind; the exact command back executes as (0, -8) and the robot is where it
    began. Neither reading is a stop (both wheels would need to be under 4 mm/s, which needs
    |alpha| < 0.04 rad at 2 mm): a 2-cycle until the budget, as R15's in the quantized runs."""
    seen = _pivot_cycle(KHEPERA.speed_unit)
    assert len(seen) == 12  # never stopped
    for k, (a, d, q) in enumerate(seen):
        assert d == pytest.approx(0.002)
        if k % 2 == 0:
            assert a == pytest.approx(0.1, abs=0.01) and q == pytest.approx((0.0, 0.008))
        else:
            assert abs(a) > math.pi - 0.15 and q == pytest.approx((0.0, -0.008))
    pivot = KHEPERA.speed_unit / 2 * 1.024
    assert pivot == pytest.approx(0.0041, abs=1e-4) and pivot > 2 * 0.002  # the smallest move overshoots


def test_kinematic_command_lands_on_the_input():
    """Executed on noise-free wheels, the exact command moves the robot by u = (alpha, d): forward
    for a target ahead, backward (turning 2 (alpha - pi)) for one behind."""
    av = Arena(size=10.0).vector()
    empty = np.empty(0)
    for alpha, d, back in ((0.3, 0.05, False), (-1.2, 0.02, False), (2.8, 0.03, True), (-2.5, 0.004, True)):
        pose = np.array([5.0, 5.0, 0.4])
        tx, ty = 5.0 + d * math.cos(0.4 + alpha), 5.0 + d * math.sin(0.4 + alpha)
        drive(pose, *kinematic_command(alpha, d, back), np.ones((32, 2)), av, 0, 0, empty, empty, empty, 0, 0)
        assert math.hypot(tx - pose[0], ty - pose[1]) < 1e-9, (alpha, d)


@pytest.mark.slow
def test_circling_command_writes_the_picture_and_the_summary(tmp_path):
    from cekm_swarm.cli import run_cli_args

    assert run_cli_args(["experiment", "circling", "--network", "R9", "--seed", "3", "--trial", "1", "--steps", "10000",
                         "--target", "2", "--speed-unit", "0.008", "--out", str(tmp_path)]) == 0
    png = tmp_path / "circling-R9-seed3-trial1-target2.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import json

    doc = json.loads((tmp_path / "circling-R9-seed3-trial1-target2.json").read_text())
    ep = doc["episode"]
    assert doc["target"] == 2 and ep["steps"] >= 1 and ep["winners"]
    assert {"neuron", "w_d_mm", "command_mm_s_mean", "kinematic_mm_s_mean", "converged"} <= set(ep["winners"][0])
