"""The K-means tracking baselines (Luke et al., AAMAS 2005; MASON's KMeansEngine): the
assignment and the goal update on hand-built cases, and what each variant can know."""

import math

import pytest

from cekm_swarm.controller.kmeans import KMeansTracker, assign, cluster_mean, local_view, update_goal, usable_shares
from cekm_swarm.models.params import KMeansParams
from cekm_swarm.modules.kmeans import KMeansGlobal, KMeansLocal
from cekm_swarm.node.api import Context
from cekm_swarm.protocol import SensePose, SenseTargets, WorldState
from cekm_swarm.protocol.messages import RobotState, TargetState
from cekm_swarm.robot import RobotBody


def test_each_target_goes_to_its_nearest_robot_and_a_tie_to_the_first_robot():
    robots = {"r2": (4.0, 0.0), "r1": (0.0, 0.0)}
    targets = {"t1": (1.0, 0.5), "t2": (3.0, -1.0), "t3": (2.0, 0.0), "t4": (5.0, 2.0)}
    assert assign(targets, robots) == {"t1": "r1", "t2": "r2", "t3": "r1", "t4": "r2"}  # t3: equidistant
    labels = assign(targets, robots)
    assert cluster_mean(targets, labels, "r1") == pytest.approx((1.5, 0.25))
    assert cluster_mean(targets, labels, "r2") == pytest.approx((4.0, 0.5))
    assert cluster_mean(targets, {}, "r1") is None


def test_the_goal_moves_a_quarter_of_the_way_to_the_mean_each_update():
    assert update_goal(None, (2.0, 1.0), 0.25) == (2.0, 1.0)  # no goal yet: the mean
    assert update_goal((0.0, 0.0), (4.0, -8.0), 0.25) == pytest.approx((1.0, -2.0))  # 0.75 goal + 0.25 mean
    k = KMeansTracker("r1", 0.5, 0.15625)
    pose = (0.0, 0.0, 0.0)
    f1 = k.update(0.256, pose, {"r2": (10.0, 0.0)}, {"t1": (1.0, 0.0), "t2": (1.0, 2.0), "t9": (9.0, 0.0)})
    assert k.goal == pytest.approx((1.0, 1.0)) and not f1.searching  # t9 is r2's
    f2 = k.update(0.512, pose, {"r2": (10.0, 0.0)}, {"t1": (3.0, 0.0), "t2": (3.0, 2.0)})
    assert k.goal == pytest.approx((0.75 * 1.0 + 0.25 * 3.0, 1.0))
    # the pull points at the goal, at full strength when it is farther than v* arrive_s
    assert math.atan2(f2.fy, f2.fx) == pytest.approx(math.atan2(1.0, 1.5))
    assert math.hypot(f2.fx, f2.fy) == pytest.approx(1.0)
    near = KMeansTracker("r1", 0.5, 0.15625)
    f = near.update(0.256, pose, {}, {"t1": (0.05, 0.0)})
    assert math.hypot(f.fx, f.fy) == pytest.approx(0.05 / 0.15625)  # slows onto a near goal


def test_a_robot_with_no_target_drives_to_a_random_waypoint_and_holds_it():
    p = KMeansParams()
    k = KMeansTracker("r1", 0.5, 0.15625, p)
    pose = (1.0, 1.0, 0.0)
    a = k.update(0.256, pose, {}, {})
    assert a.searching and math.hypot(a.aim[0] - 1.0, a.aim[1] - 1.0) <= p.wander_radius * 0.5
    b = k.update(0.512, pose, {}, {})
    assert b.aim == a.aim  # held
    c = k.update(0.256 + p.wander_hold_s, pose, {}, {})
    assert c.aim != a.aim  # held long enough: a new one
    again = KMeansTracker("r1", 0.5, 0.15625, p)
    assert again.update(0.256, pose, {}, {}).aim == a.aim  # the same robot and start: the same stream


def test_the_local_variant_knows_only_sensed_targets_and_teammates_shares():
    pose = (0.0, 0.0, math.pi / 2)
    robots, targets = local_view(pose, {"t1": (0.0, 0.4)},
                                 {"r2": ((3.0, 0.0, 0.0), {"t2": (3.2, 0.0), "t1": (0.0, 0.41)})})
    assert robots == {"r2": (3.0, 0.0)}
    assert set(targets) == {"t1", "t2"} and targets["t1"] == pytest.approx((0.0, 0.4))  # its own sighting first
    shares = {"r2": (0.256, (3.0, 0.0, 0.0), {}), "r3": (0.512, (1.0, 1.0, 0.0), {}), "r4": (-1.0, (0, 0, 0), {})}
    assert set(usable_shares(shares, 0.512, 1.0)) == {"r2"}  # r3: this tick's (waits); r4: too old


def _body() -> RobotBody:
    return RobotBody(target_range=0.5)


def test_an_unsensed_target_is_unknown_to_local_kmeans_and_known_to_global_kmeans():
    """One robot at the origin, one target 2 m away (beyond its 0.5 m range): local K-means
    wanders, global K-means heads for the target."""
    ctx = Context("r1", "target", team=("r1",), body=_body())
    local = KMeansLocal(ctx)
    local.setup()
    out = local.step(0.256, {"pose": SensePose(0.256, "world", (0.0, 0.0, 0.0)),
                             "targets": SenseTargets(0.256, "world", {}), "team": {}})
    assert out["force"].values["searching"] is True and out["share"].targets == {}
    glob = KMeansGlobal(ctx)
    glob.setup()
    st = WorldState(0.256, "world", {"r1": RobotState(x=0.0, y=0.0, theta=0.0)}, {"t1": TargetState(x=0.0, y=2.0)}, {})
    f = glob.step(0.256, {"state": st})["force"].values
    assert f["searching"] is False and f["goal"] == [0.0, 2.0]
    assert f["fx"] == pytest.approx(0.0, abs=1e-12) and f["fy"] == pytest.approx(1.0)  # straight to its left
