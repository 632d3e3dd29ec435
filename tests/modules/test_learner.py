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
    experience_pairs,
    learn_step,
    map_misfit,
    model_of,
)
from cekm_swarm.modules.learning_nodes import LearningObstacleLocalization
from cekm_swarm.node.api import Context, Inputs, start_node
from cekm_swarm.protocol import Data, MapVersion, SenseOdometry, SenseRange, with_stamp
from cekm_swarm.robot import KHEPERA
from cekm_swarm.ticks import TICK_S


@pytest.fixture(scope="module")
def base():
    return make_network("R6", np.random.default_rng(3))


def ctx(model, node="learner", instance=None, robot="r1"):
    return Context(robot, node, instance, (robot,), mode="inprocess", model_source=model, backend="numpy")


def odometry(ticks, set_lr=(0.05, 0.06), blocked=False):
    """The record of ``ticks`` at constant set speeds, the encoders measuring them exactly."""
    n = len(ticks)
    left, right = set_lr[0] * TICK_S, set_lr[1] * TICK_S
    return SenseOdometry(ticks[-1] * TICK_S if ticks else 0.0, "world", tuple(ticks), (set_lr[0],) * n,
                         (set_lr[1],) * n, (left,) * n, (right,) * n, (blocked,) * n, TICK_S)


def test_wheel_displacement_is_the_4_1_plants_arc_over_one_step():
    for vl, vr in ((0.05, 0.06), (0.08, -0.02), (-0.03, -0.03), (0.01, 0.01), (0.02, -0.02)):
        x, y, th, _ = move.py_func(0.0, 0.0, 0.0, vl, vr, STEP_S, KHEPERA.axle)
        want = displacement.py_func(0.0, 0.0, 0.0, x, y, th)
        got = wheel_displacement(vl * TICK_S, vr * TICK_S, TICK_S, KHEPERA.axle, STEP_S)
        assert got == pytest.approx(want, abs=1e-12)


def test_a_learning_step_is_the_models_own_rule(base):
    """The node's update on a hand-built step equals IndirectEKM.learn with v from the odometry."""
    net, ref = copy_model(base), copy_model(base)
    c = (0.05, 0.0625)
    counts = LearnerCounts()
    v = learn_step(net, 0.006, 0.008, TICK_S, False, c, 7.0, KHEPERA.axle, counts)
    v_ref = wheel_displacement(0.006, 0.008, TICK_S, KHEPERA.axle, STEP_S)
    assert counts.error == float(np.hypot(*(np.array(c) - ref.output(v_ref))))  # Eq. 13 before, numpy's winner
    ref.learn(v_ref, np.array(c), 7.0)
    assert v is not None and counts.applied == 1
    assert np.array_equal(net.w, ref.w) and np.array_equal(net.M, ref.M) and np.array_equal(net.Rinv, ref.Rinv)
    assert not np.array_equal(net.w, base.w)  # it learned, on its own copy
    assert base.w is not net.w


@pytest.mark.parametrize("row, c, field", [((0.006, 0.008, False), (0.0, 0.0), "stopped"),
                                           ((0.0, 0.0, False), (0.05, 0.05), "stopped"),
                                           ((0.006, 0.008, True), (0.05, 0.06), "blocked")])
def test_no_learning_on_a_stopped_or_blocked_step(base, row, c, field):
    net, counts = copy_model(base), LearnerCounts()
    assert learn_step(net, row[0], row[1], TICK_S, row[2], c, 0.0, KHEPERA.axle, counts) is None
    assert getattr(counts, field) == 1 and counts.applied == 0
    assert np.array_equal(net.w, base.w) and np.array_equal(net.M, base.M)


def run_learner(node, runs, every=8):
    """The learner's runs at ticks 0, every, 2 every, ... on a steady record."""
    out = []
    for r in range(runs):
        k = r * every
        ticks = list(range(max(1, k - 15), k + 1)) if k else []
        out.append(node.step(k * TICK_S, Inputs({"odometry": odometry(ticks)}))["map"])
    return out


def test_each_run_learns_each_new_tick_once_and_makes_a_version_holding_its_digest(base):
    node = start_node(Learner, ctx(base), Learner.Params(start_step=0))
    msgs = run_learner(node, 4)
    assert [m.version for m in msgs] == [0, 1, 2, 3]  # a version per run that learned
    assert [m.applied for m in msgs] == [0, 8, 16, 24]  # the record overlaps: each tick learned once
    for m in msgs:
        assert m.digest == map_digest(m.w, m.M)
        assert m.steps == m.applied + m.skipped
    assert [h[0] for h in node.history] == [0, 1, 2, 3]
    ref = copy_model(base)  # the same steps, by hand
    for i in range(24):
        ref.learn(
            wheel_displacement(0.05 * TICK_S, 0.06 * TICK_S, TICK_S, KHEPERA.axle, STEP_S),
            np.array([0.05, 0.06]),
            float(i),
        )
    assert np.array_equal(node.net.w, ref.w) and np.array_equal(node.net.M, ref.M)


def follower(base, instance=3):
    return start_node(
        LearningObstacleLocalization, ctx(base, "obstacle", instance), LearningObstacleLocalization.Params()
    )


def test_stale_malformed_and_misfit_map_messages_are_refused(base):
    node = start_node(Learner, ctx(base), Learner.Params(start_step=0))
    msgs = run_learner(node, 3)
    f = follower(base)
    v2 = next(m for m in msgs if m.version == 2)
    assert f.check_input("map", v2) is None
    f.step(v2.stamp + TICK_S, Inputs({"reading": None, "map": v2}))
    assert f.version == 2
    v1 = next(m for m in msgs if m.version == 1)
    assert f.check_input("map", v1) is None  # older than what the node holds: not refused on receipt (no stall) ...
    f.step(v1.stamp + TICK_S, Inputs({"reading": None, "map": v1}))
    assert f.version == 2 and f.dropped == 1 and "stale" in f.last_drop  # ... but dropped and counted when met
    bad = MapVersion(v2.stamp, v2.sender, 3, v2.steps, v2.applied, v2.skipped, v2.digest, v2.w + 1e-9, v2.M)
    assert "digest" in f.check_input("map", bad)
    other = make_network("R5", np.random.default_rng(0))
    small = copy_model(other)
    misfit = MapVersion(v2.stamp, v2.sender, 4, 0, 0, 0, map_digest(small.w, small.M),
                        small.w.reshape(-1), small.M.reshape(-1))
    assert "lattice" in f.check_input("map", misfit)
    assert map_misfit(v2, 2, base.lattice.n) is None  # the version it holds, again: used as it is


def test_a_restarted_node_catches_up_to_the_current_version(base):
    """A node that starts (or restarts) mid-run holds version 0; the learner's next message
    holds the whole current map, and from it the node's outputs are those of a node that
    followed every version."""
    node = start_node(Learner, ctx(base), Learner.Params(start_step=0))
    msgs = run_learner(node, 4)
    steady, fresh = follower(base), follower(base)
    for m in msgs:
        steady.step(m.stamp + TICK_S, Inputs({"reading": None, "map": m}))
    last = msgs[-1]
    reading = SenseRange(last.stamp + TICK_S, "world", 3, 0.4, 0.05)
    want = steady.step(reading.stamp, Inputs({"reading": reading, "map": last}))["field"]
    got = fresh.step(reading.stamp, Inputs({"reading": reading, "map": with_stamp(last, last.stamp)}))["field"]
    assert fresh.version == steady.version == last.version == 3
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
    pairs = {"r3": [[0.3, 0.05, 0.04, 0.06]], "r1": [[-0.2, 0.02, 0.03, 0.01], [0.1, 0.03, 0.02, 0.03]]}
    team = {r: Data(0.0, f"{r}/learner", {"pairs": p}) for r, p in pairs.items()}
    team["r4"] = Data(0.0, "r4/learner", {"pairs": [[1.0, 2.0], "x"]})  # not pairs: left out
    out = node.step(8 * TICK_S, Inputs({"odometry": odometry([7, 8], (0.05, 0.0625)), "team": team, "maps": {}}))
    ref = copy_model(base)
    rows = pairs["r1"] + pairs["r3"]  # robot-id order
    for i, row in enumerate(rows):
        ref.learn(np.array(row[:2]), np.array(row[2:]), float(i))
    v = wheel_displacement(0.05 * TICK_S, 0.0625 * TICK_S, TICK_S, KHEPERA.axle, STEP_S)
    for i in range(2):
        ref.learn(v, np.array([0.05, 0.0625]), float(len(rows) + i))
    assert np.array_equal(node.net.w, ref.w) and np.array_equal(node.net.M, ref.M)
    assert node.counts.team == 3 and node.counts.applied == 2
    own = experience_pairs(out["experience"])
    assert len(own) == 2 and np.array_equal(own[0][1], [0.05, 0.0625]) and np.array_equal(own[0][0], v)


def test_a_team_learner_that_joins_late_starts_from_the_teammate_map_that_learned_most(base):
    team_ctx = Context("r3", "learner", None, ("r1", "r2", "r3"), mode="inprocess", model_source=base, backend="numpy")
    teammates = {}
    for robot, runs in (("r2", 3), ("r1", 3)):
        other = start_node(Learner, ctx(base, robot=robot), Learner.Params(start_step=0))
        teammates[robot] = run_learner(other, runs)[-1]
    assert teammates["r1"].applied == teammates["r2"].applied == 16
    late = start_node(TeamLearner, team_ctx, TeamLearner.Params(start_step=0))
    out = late.step(40 * TICK_S, Inputs({"odometry": None, "team": {}, "maps": teammates}))["map"]
    assert out.version == 1 and out.digest == teammates["r1"].digest  # r1's: the first of equals in robot-id order
    assert late.counts.team == 16
    again = late.step(48 * TICK_S, Inputs({"odometry": None, "team": {}, "maps": teammates}))["map"]
    assert again.version == 1  # once only
    first = start_node(TeamLearner, team_ctx, TeamLearner.Params(start_step=0))  # a run's tick 0: nobody has run
    assert first.step(0.0, Inputs({"odometry": odometry([]), "team": {}, "maps": {}}))["map"].version == 0


def test_a_readers_version_is_the_messages_map_sharing_its_m(base):
    """An EKM node's model of a version (``model_of(reader=True)``): the map a private copy
    holds, M the message's own read-only array (not copied), w a writable copy; the EKM built
    on it gives the same winners, fields and commands as one built on the copy."""
    from cekm_swarm.controller.cooperative import CooperativeEKM

    msg = run_learner(start_node(Learner, ctx(base), Learner.Params(start_step=0)), 3)[-1]
    reader, copy = model_of(base, msg, reader=True), model_of(base, msg)
    assert np.array_equal(reader.w, copy.w) and np.array_equal(reader.M, copy.M)
    assert np.shares_memory(reader.M, msg.M) and not reader.M.flags.writeable and reader.w.flags.writeable
    fast, ref = CooperativeEKM(reader, tabulate=False, backend="numba"), CooperativeEKM(copy, backend="numpy")
    for alpha, d in ((0.3, 0.05), (-2.0, 0.12), (3.1, 0.01)):
        s = fast.winner(alpha, d)
        assert s == ref.winner(alpha, d)
        assert np.array_equal(fast.obstacle_activity(s), ref.obstacle_activity(s))
        assert np.array_equal(fast.target_activity(s), ref.target_activity(s))
