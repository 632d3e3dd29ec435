"""The learner node and the map versions every EKM node of a learning robot follows
(cekm_swarm.modules.learner; docs/learning.md): fast unit tests, no processes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cekm_swarm.experiments.arena import displacement, move
from cekm_swarm.models.learning import map_digest, wheel_displacement
from cekm_swarm.models.networks import make_network
from cekm_swarm.modules.learner import (
    STEP_S,
    Learner,
    LearnerCounts,
    TeamLearner,
    copy_model,
    experience_pair,
    learn_step,
    map_misfit,
)
from cekm_swarm.modules.learning_nodes import LearningObstacleLocalization
from cekm_swarm.node.api import Context, Inputs, start_node
from cekm_swarm.protocol import Data, MapVersion, SenseOdometry, SenseRange, WheelCommand, with_stamp
from cekm_swarm.robot import KHEPERA
from cekm_swarm.ticks import TICK_S


@pytest.fixture(scope="module")
def base():
    return make_network("R6", np.random.default_rng(3))


def ctx(model, node="learner", instance=None, robot="r1"):
    return Context(robot, node, instance, (robot,), mode="inprocess", model_source=model, backend="numpy")


def odometry(left, right, blocked=False, t=TICK_S):
    return SenseOdometry(t, "world", left, right, TICK_S, blocked)


def test_wheel_displacement_is_the_4_1_plants_arc_over_one_step():
    for vl, vr in ((0.05, 0.06), (0.08, -0.02), (-0.03, -0.03), (0.01, 0.01), (0.02, -0.02)):
        x, y, th, _ = move.py_func(0.0, 0.0, 0.0, vl, vr, STEP_S, KHEPERA.axle)
        want = displacement.py_func(0.0, 0.0, 0.0, x, y, th)
        got = wheel_displacement(vl * TICK_S, vr * TICK_S, TICK_S, KHEPERA.axle, STEP_S)
        assert got == pytest.approx(want, abs=1e-12)


def test_a_learning_step_is_the_models_own_rule(base):
    """The node's update on a hand-built step equals IndirectEKM.learn with v from the odometry."""
    net, ref = copy_model(base), copy_model(base)
    odo, c = odometry(0.006, 0.008), (0.05, 0.0625)
    counts = LearnerCounts()
    v = learn_step(net, odo, c, 7.0, KHEPERA.axle, counts)
    ref.learn(wheel_displacement(0.006, 0.008, TICK_S, KHEPERA.axle, STEP_S), np.array(c), 7.0)
    assert v is not None and counts.applied == 1
    assert np.array_equal(net.w, ref.w) and np.array_equal(net.M, ref.M) and np.array_equal(net.Rinv, ref.Rinv)
    assert not np.array_equal(net.w, base.w)  # it learned, on its own copy
    assert base.w is not net.w


@pytest.mark.parametrize("odo, c, field", [(odometry(0.006, 0.008), (0.0, 0.0), "stopped"),
                                           (odometry(0.0, 0.0), (0.05, 0.05), "stopped"),
                                           (odometry(0.006, 0.008, blocked=True), (0.05, 0.06), "blocked")])
def test_no_learning_on_a_stopped_or_blocked_step(base, odo, c, field):
    net, counts = copy_model(base), LearnerCounts()
    assert learn_step(net, odo, c, 0.0, KHEPERA.axle, counts) is None
    assert getattr(counts, field) == 1 and counts.applied == 0
    assert np.array_equal(net.w, base.w) and np.array_equal(net.M, base.M)


def run_learner(node, ticks, cmd=(0.05, 0.06)):
    out = []
    for k in range(ticks):
        t = k * TICK_S
        inputs = {"odometry": odometry(cmd[0] * TICK_S, cmd[1] * TICK_S, t=t),
                  "command": None if k == 0 else WheelCommand(t - TICK_S, "r1/motor", *cmd, k - 1)}
        out.append(node.step(t, Inputs(inputs))["map"])
    return out


def test_a_new_version_is_made_at_the_last_tick_of_each_period_and_holds_its_digest(base):
    node = start_node(Learner, ctx(base), Learner.Params(publish_every=8, start_step=0))
    msgs = run_learner(node, 17)
    assert [m.version for m in msgs] == [0] * 7 + [1] * 8 + [2] * 2  # made at ticks 7 and 15
    for m in msgs:
        assert m.digest == map_digest(m.w, m.M, m.rinv)
        assert m.steps == m.applied + m.skipped
    assert msgs[7].applied == 7 and msgs[-1].applied == 16
    assert [h[0] for h in node.history] == [0, 1, 2]


def follower(base, instance=3):
    return start_node(LearningObstacleLocalization, ctx(base, "obstacle", instance), LearningObstacleLocalization.Params())


def test_stale_malformed_and_misfit_map_messages_are_refused(base):
    node = start_node(Learner, ctx(base), Learner.Params(publish_every=2, start_step=0))
    msgs = run_learner(node, 6)
    f = follower(base)
    v2 = next(m for m in msgs if m.version == 2)
    assert f.check_input("map", v2) is None
    f.step(v2.stamp + TICK_S, Inputs({"reading": None, "map": v2}))
    assert f.version == 2
    v1 = next(m for m in msgs if m.version == 1)
    assert f.check_input("map", v1) is None  # older than what the node holds: not refused on receipt (no stall) ...
    f.step(v1.stamp + TICK_S, Inputs({"reading": None, "map": v1}))
    assert f.version == 2 and f.dropped == 1 and "stale" in f.last_drop  # ... but dropped and counted when met
    bad = MapVersion(v2.stamp, v2.sender, 3, v2.steps, v2.applied, v2.skipped, v2.digest, v2.w + 1e-9, v2.M, v2.rinv)
    assert "digest" in f.check_input("map", bad)
    other = make_network("R5", np.random.default_rng(0))
    small = copy_model(other)
    misfit = MapVersion(v2.stamp, v2.sender, 4, 0, 0, 0, map_digest(small.w, small.M, small.Rinv),
                        small.w.reshape(-1), small.M.reshape(-1), small.Rinv.reshape(-1))
    assert "lattice" in f.check_input("map", misfit)
    assert map_misfit(v2, 2, base.lattice.n) is None  # the version it holds, again: used as it is


def test_a_restarted_node_catches_up_to_the_current_version(base):
    """A node that starts (or restarts) mid-run holds version 0; the learner's next message
    holds the whole current map, and from it the node's outputs are those of a node that
    followed every version."""
    node = start_node(Learner, ctx(base), Learner.Params(publish_every=2, start_step=0))
    msgs = run_learner(node, 9)
    steady, fresh = follower(base), follower(base)
    for m in msgs:
        steady.step(m.stamp + TICK_S, Inputs({"reading": None, "map": m}))
    last = msgs[-1]
    reading = SenseRange(last.stamp + TICK_S, "world", 3, 0.4, 0.05)
    want = steady.step(reading.stamp, Inputs({"reading": reading, "map": last}))["field"]
    got = fresh.step(reading.stamp, Inputs({"reading": reading, "map": with_stamp(last, last.stamp)}))["field"]
    assert fresh.version == steady.version == last.version > 2
    assert got.winner == want.winner and np.array_equal(got.b, want.b)
    old = follower(base).step(reading.stamp, Inputs({"reading": reading, "map": None}))["field"]
    assert not (old.winner == got.winner and np.array_equal(old.b, got.b))  # the map version made a difference


def test_lazy_field_rows_equal_the_tabulated_ones(base):
    from dataclasses import replace

    from cekm_swarm.controller.cooperative import CooperativeEKM

    ekm = CooperativeEKM(base, backend="numpy")
    lazy = replace(ekm, tabulate=False)
    for s in (0, 7, base.lattice.n - 1):
        assert np.array_equal(ekm.target_activity(s), lazy.target_activity(s))
        assert np.array_equal(ekm.obstacle_activity(s), lazy.obstacle_activity(s))
    assert math.isfinite(float(lazy.obstacle_activity(3)[0]))


def test_a_team_learner_learns_its_teammates_pairs_in_robot_id_order_then_its_own(base):
    team_ctx = Context("r2", "learner", None, ("r3", "r1", "r2"), mode="inprocess", model_source=base, backend="numpy")
    node = start_node(TeamLearner, team_ctx, TeamLearner.Params(start_step=0))
    pairs = {"r3": ([0.3, 0.05], [0.04, 0.06]), "r1": ([-0.2, 0.02], [0.03, 0.01])}
    team = {r: Data(0.0, f"{r}/learner", {"v": v, "c": c}) for r, (v, c) in pairs.items()}
    team["r4"] = Data(0.0, "r4/learner", {"v": None, "c": None})  # learned nothing: skipped
    odo, cmd = odometry(0.006, 0.008), WheelCommand(0.0, "r2/motor", 0.05, 0.0625, 0)
    out = node.step(TICK_S, Inputs({"odometry": odo, "command": cmd, "team": team}))
    ref = copy_model(base)
    for i, r in enumerate(("r1", "r3")):  # robot-id order
        ref.learn(np.array(pairs[r][0]), np.array(pairs[r][1]), float(i))
    ref.learn(wheel_displacement(0.006, 0.008, TICK_S, KHEPERA.axle, STEP_S), np.array([0.05, 0.0625]), 2.0)
    assert np.array_equal(node.net.w, ref.w) and np.array_equal(node.net.M, ref.M)
    assert node.counts.team == 2 and node.counts.applied == 1
    own = experience_pair(out["experience"])
    assert own is not None and np.array_equal(own[1], [0.05, 0.0625])
    assert experience_pair(Data(0.0, "x", {"v": [1.0], "c": [0.0, 0.0]})) is None  # not a pair: ignored
