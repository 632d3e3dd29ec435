"""The tracking controllers as pure functions: target weights, the scripted two-robots-
one-target situation, A-CMOMMT's force profile, and the lockstep share semantics."""

import math

import numpy as np
import pytest

from cekm_swarm.controller.acmommt import ACMOMMT, robot_force, target_force
from cekm_swarm.controller.team import TeammateShare, TeamView, to_robot, to_world
from cekm_swarm.controller.tracking import TrackingEKM, standoff_distance, target_weight, teammate_weight
from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.models.params import ACMOMMTParams, TrackingParams

R = 0.5


@pytest.fixture(scope="module")
def model():
    return default_model()


def test_target_weight_falls_as_more_teammates_observe():
    p = TrackingParams()
    w = [target_weight(n, p) for n in range(5)]
    assert w[0] == 1.0
    assert all(a > b for a, b in zip(w, w[1:], strict=False)) and w[-1] >= 0.0


def test_weights_in_the_controller_count_nearer_observers(model):
    """The sensed target's weight is 1 alone, and falls with each nearer teammate whose share reports it."""
    ctl = TrackingEKM("r1", model, R)
    pose = (1.0, 1.0, 0.0)
    sensed = {"a": (0.0, 0.3)}  # 0.3 m ahead: at (1.3, 1.0)
    weights = []
    for n in range(4):
        view = TeamView("r1")
        for k in range(n):  # teammates at 0.1 m from the target, reporting it
            view.receive(f"q{k}", TeammateShare(0.0, (1.3, 1.1 + 0.01 * k, 0.0), {"a": (1.3, 1.0)}))
        weights.append(ctl.localize(0.256, pose, sensed, view).weights["a"])
    assert weights[0] == 1.0 and all(a > b for a, b in zip(weights, weights[1:], strict=False))
    # a teammate farther from the target than this robot does not lower its weight
    view = TeamView("r1")
    view.receive("q", TeammateShare(0.0, (1.7, 1.0, 0.0), {"a": (1.3, 1.0)}))
    assert ctl.localize(0.256, pose, sensed, view).weights["a"] == 1.0


def test_teammate_weight_shape():
    p = TrackingParams()
    assert teammate_weight(0.0, R, p) == 1.0 and teammate_weight(p.teammate_near * R, R, p) == 1.0
    assert teammate_weight(p.teammate_far * R, R, p) == 0.0
    mid = 0.5 * (p.teammate_near + p.teammate_far) * R
    assert teammate_weight(mid, R, p) == pytest.approx(0.5)


def _step(pose, vl, vr, dt=0.128, axle=0.053):
    """Ideal differential drive (exact arc), in 4 sub-steps."""
    x, y, th = pose
    for _ in range(4):
        h = dt / 4
        v, w = 0.5 * (vl + vr), (vr - vl) / axle
        x += v * h * math.cos(th + 0.5 * w * h)
        y += v * h * math.sin(th + 0.5 * w * h)
        th = math.remainder(th + w * h, 2 * math.pi)
    return (x, y, th)


def test_two_robots_on_one_target_do_not_both_stay_while_another_is_unobserved(model):
    """Scripted: r1 and r2 both see target a; target b was last reported by r3, whose
    share has since timed out, so nobody observes b. Closed loop on an ideal drive, shares
    exchanged every 0.256 s: the nearer robot keeps a, the other leaves a for b."""
    a_pos, b_pos = (1.0, 1.0), (2.0, 1.8)
    poses = {"r1": (1.15, 1.0, math.pi), "r2": (1.0, 0.7, math.pi / 2)}
    ctls = {r: TrackingEKM(r, model, R) for r in poses}
    views = {r: TeamView(r) for r in poses}
    for v in views.values():
        v.receive("r3", TeammateShare(0.0, (1.9, 1.7, 0.0), {"b": b_pos}))
    acts = {}
    first = {}
    for tick in range(1, 400):
        t = round(tick * 0.128, 9)
        if tick % 2 == 0:
            shares = {}
            for r, pose in poses.items():
                sensed = {k: to_robot(pose, p) for k, p in (("a", a_pos), ("b", b_pos))
                          if math.dist(pose[:2], p) <= R}
                acts[r] = ctls[r].localize(t, pose, sensed, views[r])
                if tick == 4:  # the first tick with the teammate's share (one tick late)
                    first[r] = acts[r]
                shares[r] = TeammateShare(t, pose, {k: to_world(pose, *u) for k, u in sensed.items()})
            for q, s in shares.items():
                for r in poses:
                    views[r].receive(q, s)
        for r in poses:
            out = ctls[r].integrate(acts.get(r), [])
            poses[r] = _step(poses[r], out.v_l, out.v_r)
    assert first["r1"].weights["a"] == 1.0 and not first["r1"].searching
    assert first["r2"].weights["a"] < 1.0 and first["r2"].searching
    d = {r: (math.dist(p[:2], a_pos), math.dist(p[:2], b_pos)) for r, p in poses.items()}
    assert d["r1"][0] <= R  # r1 kept a
    assert d["r2"][1] <= R  # r2 went to b


def test_acmommt_force_profile_at_its_breakpoints():
    p = ACMOMMTParams()
    do1, do2, do3, do4 = p.do1 * R, p.do2 * R, p.do3 * R, p.do4 * R
    assert target_force(0.0, R, p) == -1.0
    assert target_force(do1, R, p) == pytest.approx(0.0, abs=1e-12)
    assert target_force(do2, R, p) == pytest.approx(1.0)
    assert target_force(do3, R, p) == 1.0
    assert target_force(do4, R, p) == pytest.approx(0.0, abs=1e-12)
    assert target_force(do4 + 0.1, R, p) == 0.0
    assert target_force(0.5 * do1, R, p) == pytest.approx(-0.5)  # linear between breakpoints
    assert target_force(0.5 * (do1 + do2), R, p) == pytest.approx(0.5)
    assert target_force(0.5 * (do3 + do4), R, p) == pytest.approx(0.5)
    dr1, dr2 = p.dr1 * R, p.dr2 * R
    assert robot_force(0.0, R, p) == -1.0 and robot_force(dr1, R, p) == -1.0
    assert robot_force(0.5 * (dr1 + dr2), R, p) == pytest.approx(-0.5)
    assert robot_force(dr2, R, p) == pytest.approx(0.0, abs=1e-12) and robot_force(dr2 + 0.01, R, p) == 0.0


def test_acmommt_drives_toward_a_far_target_and_backs_off_a_near_one():
    ctl = ACMOMMT("r1", R, 0.17, 0.03, 0.053, 0.16 / 1.024)
    far = ctl.localize(0.0, (0.0, 0.0, 0.0), {"a": (0.0, 0.4)}, TeamView("r1"))
    vl, vr = ctl.integrate(far, [])
    assert vl > 0 and vr > 0 and vl == pytest.approx(vr)
    near = ctl.localize(0.0, (0.0, 0.0, 0.0), {"a": (0.0, 0.02)}, TeamView("r1"))
    assert near.fx < 0  # too close: repelled


def test_shares_are_used_one_tick_late_and_dropped_when_stale_or_gone():
    view = TeamView("r1", share_timeout_s=1.0)
    view.receive("r2", TeammateShare(0.256, (0.0, 0.0, 0.0), {}))
    assert "r2" not in view.teammates(0.256)  # same tick: not yet
    assert "r2" in view.teammates(0.512)
    assert "r2" not in view.teammates(1.5)  # stale
    view.receive("r1", TeammateShare(0.256, (0.0, 0.0, 0.0), {}))
    assert "r1" not in view.shares  # own share ignored
    view.drop("r2")
    assert view.teammates(0.512) == {}


def test_frames_round_trip():
    pose = (0.3, -0.2, 2.5)
    for alpha, d in ((0.0, 0.3), (-2.0, 0.1), (3.0, 0.45)):
        a2, d2 = to_robot(pose, to_world(pose, alpha, d))
        assert a2 == pytest.approx(alpha) and d2 == pytest.approx(d)


def test_stand_off_turns_in_place_near_a_target(model):
    """A target inside the stand-off is localized at the goal state: the winning move is short."""
    ctl = TrackingEKM("r1", model, R, TrackingParams(assign_radius=0.0))  # its own field, not an assignment's
    act = ctl.localize(0.0, (1.0, 1.0, 0.0), {"a": (0.5, 0.1)}, TeamView("r1"))
    out = ctl.integrate(act, [])
    assert ctl.ekm.w[out.k][1] < 0.03
    assert np.isfinite([out.v_l, out.v_r]).all()


def test_the_stand_off_shrinks_with_the_targets_speed():
    p = TrackingParams(standoff=0.7, standoff_speed_s=2.0)
    assert standoff_distance(None, 0.5, p) == pytest.approx(0.35)  # no track yet: the stand-off
    assert standoff_distance(0.05, 0.5, p) == pytest.approx(0.25)
    assert standoff_distance(0.5, 0.5, p) == 0.0  # never below 0
    assert standoff_distance(0.05, 0.5, TrackingParams(standoff=0.7, standoff_speed_s=0.0)) == pytest.approx(
        0.35
    )  # off


def test_a_fast_target_inside_the_stand_off_is_followed_from_nearer(model):
    """The same sightings of a target circling the robot at 0.6 R and 0.1 m/s: with a fixed
    stand-off (0.7 R) it is localized at the goal state; with the speed's, beyond it."""
    pose = (1.0, 1.0, 0.0)
    u_d = {}
    for on in (0.0, 2.0):
        # face_angle off: the target circles to 2.5 rad, beyond the turn-in-place rule's 1 rad
        ctl = TrackingEKM("r1", model, R, TrackingParams(standoff_speed_s=on, face_angle=math.pi, assign_radius=0.0))
        view = TeamView("r1")
        for k in range(30):
            t = 0.256 * k
            phi = 0.1 * t / (0.6 * R)
            act = ctl.localize(t, pose, {"a": (phi, 0.6 * R)}, view)
        u_d[on] = act.inputs[0][2]
    assert u_d[0.0] == 0.0
    assert u_d[2.0] > 0.05 * R


def test_a_target_behind_is_turned_to_in_place(model):
    """A target beside or behind the robot (|alpha| > face_angle) is localized at
    (+-face_angle, 0), a goal state on its side: the robot turns in place toward it. With
    the rule off (face_angle = pi) the same sighting makes the robot drive a forward arc
    (its own winner is a reverse neuron, which may not win), away from the target."""
    pose = (1.0, 1.0, 0.0)
    for alpha in (2.6, -2.6, 1.6, -1.5):
        ctl = TrackingEKM("r1", model, R, TrackingParams(face_angle=1.0, assign_radius=0.0))
        act = ctl.localize(0.0, pose, {"a": (alpha, 0.8 * R)}, TeamView("r1"))
        (s, la, u_d, wt), = act.inputs
        assert (la, u_d, wt) == (math.copysign(1.0, alpha), 0.0, 1.0)
        out = ctl.integrate(act, [])
        assert out.k == s  # Eq. 11 with the localized input
        assert math.copysign(1.0, out.v_r - out.v_l) == math.copysign(1.0, alpha)  # toward its side
        assert abs(out.v_l + out.v_r) / 2.0 < 0.01  # in place: it does not drive away
    off = TrackingEKM("r1", model, R, TrackingParams(face_angle=math.pi, assign_radius=0.0))
    out = off.integrate(off.localize(0.0, pose, {"a": (2.6, 0.9 * R)}, TeamView("r1")), [])
    assert out.s is None and (out.v_l + out.v_r) / 2.0 > 0.05


def test_the_assigned_centroid_is_met_where_it_is_going(model):
    """assign_lead_s: a lone target moving steadily is localized assign_lead_s ahead of where
    it is, along its track's velocity (0: where it is)."""
    pose = (1.0, 1.0, 0.0)
    v = 0.02  # m/s, sideways
    led = {}
    for lead in (0.0, 1.0):
        ctl = TrackingEKM("r1", model, R, TrackingParams(assign_lead_s=lead, face_angle=math.pi))
        view = TeamView("r1")
        for k in range(60):
            t = 0.256 * k
            where = (1.3, 1.0 + v * t)
            act = ctl.localize(t, pose, {"a": to_robot(pose, where)}, view)
        (s, ga, gd, wt), = act.inputs
        led[lead] = np.subtract(to_world(pose, ga, gd), where)
    assert np.allclose(led[0.0], 0.0, atol=1e-9)
    assert np.allclose(led[1.0], (0.0, v * 1.0), atol=0.002)


def test_a_target_ahead_is_localized_as_before(model):
    """Within face_angle of the heading nothing changes: the same inputs with the rule on and off."""
    pose = (1.0, 1.0, 0.0)
    sensed = {"a": (0.5, 0.9 * R), "b": (-0.9, 0.6 * R), "c": (0.2, 0.1 * R)}
    acts = [TrackingEKM("r1", model, R, TrackingParams(face_angle=fa)).localize(0.0, pose, sensed, TeamView("r1"))
            for fa in (1.0, math.pi)]
    assert acts[0].inputs == acts[1].inputs
    assert np.array_equal(acts[0].a, acts[1].a)


def test_face_angle_is_validated():
    for bad in (0.0, -1.0, 3.2, float("nan")):
        with pytest.raises(ParameterError):
            TrackingParams(face_angle=bad)


def test_assign_lead_s_is_validated():
    for bad in (-0.5, float("inf"), float("nan")):
        with pytest.raises(ParameterError, match="assign_lead_s"):
            TrackingParams(assign_lead_s=bad)
    assert TrackingParams(assign_lead_s=0.0).assign_lead_s == 0.0


# ---------------------------------------------------------------- hand-offs by K-means' assignment


def test_assigned_group_is_this_robots_share_of_the_known_targets_near_their_centroid():
    from cekm_swarm.controller.tracking import assigned_group

    p = TrackingParams(assign_radius=0.8, assign_min=1)
    team = {"q": TeammateShare(0.0, (3.0, 1.0, 0.0), {})}
    known = {"a": (1.2, 1.0), "b": (1.4, 1.2), "c": (2.9, 1.0)}  # c is nearer q
    centroid, mine = assigned_group("r1", (1.0, 1.0, 0.0), known, team, R, p)
    assert mine == ("a", "b") and centroid == pytest.approx((1.3, 1.1))  # sorted: one order for every sum
    # parted further than 0.8 R from their centroid: no group (each keeps its own field)
    assert assigned_group("r1", (1.0, 1.0, 0.0), {"a": (1.0, 1.5), "b": (1.0, 0.5)}, team, R, p) is None
    # fewer than assign_min, or the rule off
    assert assigned_group("r1", (1.0, 1.0, 0.0), {"a": (1.2, 1.0)}, team, R, TrackingParams(assign_min=2)) is None
    assert assigned_group("r1", (1.0, 1.0, 0.0), known, team, R, TrackingParams(assign_radius=0.0)) is None


def test_assign_speed_s_tightens_the_reach_of_a_fast_share():
    """Two targets 0.6 R apart (each 0.3 R from their centroid) fit within 0.8 R; moving at
    0.1 m/s with assign_speed_s = 3 the reach is 0.8 R - 0.3 m = 0.2 R (R = 0.5 m): no
    group. Without tracks, or off, they fit."""
    from cekm_swarm.controller.tracking import assigned_group

    team = {"q": TeammateShare(0.0, (3.0, 1.0, 0.0), {})}
    pose, known = (1.0, 1.0, 0.0), {"a": (1.2, 1.0), "b": (1.2, 1.0 + 0.6 * R)}
    fast = {"a": 0.1, "b": 0.1}
    p = TrackingParams(assign_radius=0.8, assign_speed_s=3.0)
    assert assigned_group("r1", pose, known, team, R, p, fast) is None
    assert assigned_group("r1", pose, known, team, R, p, {})[1] == ("a", "b")
    assert assigned_group("r1", pose, known, team, R, TrackingParams(assign_radius=0.8), fast)[1] == ("a", "b")
    for bad in (-1.0, float("inf"), float("nan")):
        with pytest.raises(ParameterError, match="assign_speed_s"):
            TrackingParams(assign_speed_s=bad)


def test_assign_subset_holds_the_largest_part_of_a_share_that_fits_nearest_first():
    """A share of four that does not fit within 0.5 R: off, no group; on, the two of it that
    fit (of the two pairs that fit, the one whose centroid is nearer the robot)."""
    from cekm_swarm.controller.tracking import assigned_group

    team = {"q": TeammateShare(0.0, (3.0, 1.0, 0.0), {})}
    pose = (1.0, 1.0, 0.0)

    def sub(n: int) -> TrackingParams:
        return TrackingParams(assign_radius=0.5, assign_subset=n)

    known = {"a": (1.2, 1.0), "b": (1.2, 1.2), "c": (1.2, 0.1), "d": (1.4, 0.1)}  # {a, b} and {c, d} fit, not all
    assert assigned_group("r1", pose, known, team, R, sub(0)) is None
    centroid, mine = assigned_group("r1", pose, known, team, R, sub(6))
    assert mine == ("a", "b") and centroid == pytest.approx((1.2, 1.1))
    # three of the four fit once d leaves: the largest part wins over a nearer pair
    three = {"a": (1.1, 1.0), "b": (1.1, 1.2), "c": (1.1, 1.1), "d": (1.1, 2.2)}
    assert assigned_group("r1", pose, three, team, R, sub(6))[1] == ("a", "b", "c")
    # only the assign_subset nearest count; no two fit: none
    assert assigned_group("r1", pose, three, team, R, sub(2))[1] == ("a", "c")
    apart = {"a": (1.0, 2.0), "b": (2.0, 1.0), "c": (1.0, 0.0)}
    assert assigned_group("r1", pose, apart, team, R, sub(6)) is None
    with pytest.raises(ParameterError, match="assign_subset"):
        sub(-1)


def test_a_target_a_teammate_sees_but_this_robot_is_nearer_to_is_driven_to(model):
    """A teammate's share reports a target this robot does not sense but is the nearer
    robot to: the robot localizes it (no search); a target nearer the teammate is left."""
    pose = (1.0, 1.0, 0.0)
    far_teammate = TeammateShare(0.0, (2.5, 1.0, 0.0), {"a": (1.4, 1.0)})
    view = TeamView("r1")
    view.receive("q", far_teammate)
    act = TrackingEKM("r1", model, R).localize(0.256, pose, {}, view)
    assert not act.searching and len(act.inputs) == 1
    s, la, u_d, wt = act.inputs[0]
    assert (la, u_d, wt) == pytest.approx((0.0, 0.4, 1.0))  # straight ahead, 0.4 m: the target itself
    near_teammate = TeammateShare(0.0, (1.5, 1.0, 0.0), {"a": (1.4, 1.0)})
    view = TeamView("r1")
    view.receive("q", near_teammate)
    act = TrackingEKM("r1", model, R).localize(0.256, pose, {}, view)
    assert act.searching  # the teammate holds it: this robot searches


def test_teammate_hold_gain_weakens_the_teammate_fields_only_while_holding_a_target(model):
    """teammate_hold_gain scales b_team when the robot holds a target (here a lone sensed
    one, assigned to it) and leaves it alone while the robot searches (nothing sensed)."""
    pose = (1.0, 1.0, 0.0)

    def b_team(gain: float, sensed: dict, seen: int = 0) -> np.ndarray:
        ctl = TrackingEKM("r1", model, R, TrackingParams(teammate_hold_gain=gain, teammate_hold_seen=seen))
        view = TeamView("r1")
        view.receive("q", TeammateShare(0.0, (1.0, 1.15, 0.0), {}))  # 0.15 m to the left
        act = ctl.localize(0.256, pose, sensed, view)
        assert act.searching == (not sensed)
        return act.b_team

    holding = {"a": (0.0, 0.3)}
    full = b_team(1.0, holding)
    assert full.max() > 0.5  # a near teammate: its field is there at full weight
    np.testing.assert_allclose(b_team(0.4, holding), 0.4 * full, rtol=0, atol=1e-15)
    assert not b_team(0.0, holding).any()
    np.testing.assert_array_equal(b_team(0.4, {}), b_team(1.0, {}))  # searching: unchanged
    # teammate_hold_seen: only while the robot senses at least that many targets
    np.testing.assert_array_equal(b_team(0.0, holding, seen=2), full)
    two = {"a": (0.0, 0.3), "b": (0.2, 0.32)}
    np.testing.assert_allclose(b_team(0.4, two, seen=2), 0.4 * b_team(1.0, two), rtol=0, atol=1e-15)


def test_teammate_hold_gain_is_validated():
    for bad in (-0.1, 1.5, math.nan):
        with pytest.raises(ParameterError, match="teammate_hold_gain"):
            TrackingParams(teammate_hold_gain=bad)
    assert TrackingParams().teammate_hold_gain == 1.0
    with pytest.raises(ParameterError, match="teammate_hold_seen"):
        TrackingParams(teammate_hold_seen=-1)


def test_face_turn_gain_off_is_eq_11_as_it_is(model):
    """face_turn_gain 1 (off): every command is Eq. 11's, bit for bit, beside or ahead."""
    from cekm_swarm.controller.cooperative import motor_command
    pose = (1.0, 1.0, 0.0)
    for alpha in (2.6, -2.6, 1.2, -1.5, 0.5, -0.2):
        ctl = TrackingEKM("r1", model, R, TrackingParams(assign_radius=0.0, face_turn_gain=1.0))
        act = ctl.localize(0.0, pose, {"a": (alpha, 0.9 * R)}, TeamView("r1"))
        out = ctl.integrate(act, [])
        (s, la, u_d, _), = act.inputs
        ekm = ctl.ekm
        assert out.k == s
        assert (out.v_l, out.v_r) == motor_command(ekm._M, ekm.w, la, u_d, s, s, model.v_max, model.learn_p.d_scale)


def test_face_turn_gain_executes_the_turn_in_place_faster_in_its_direction(model):
    """face_turn_gain g: a target beside or behind (the face_angle rule's input (+-face_angle,
    0) winning) gets Eq. 11's command scaled by min(g, c* / max |c|): the same direction, no
    wheel beyond c*, a faster turn toward its side; a target ahead gets Eq. 11's command as it is."""
    pose = (1.0, 1.0, 0.0)
    c_star = model.v_max
    for alpha in (2.6, -2.6, 1.6, -1.5):
        def command(g, alpha=alpha):
            ctl = TrackingEKM("r1", model, R, TrackingParams(assign_radius=0.0, face_turn_gain=g, face_turn_only=False))
            return ctl.integrate(ctl.localize(0.0, pose, {"a": (alpha, 0.8 * R)}, TeamView("r1")), [])
        base = command(1.0)
        top = max(abs(base.v_l), abs(base.v_r))
        for g in (2.0, math.inf):
            out = command(g)
            f = min(g, c_star / top)
            assert f > 1.5  # the map's turn in place is slow: there is room to scale it
            assert (out.k, out.s) == (base.k, base.s)
            assert out.v_l == pytest.approx(f * base.v_l) and out.v_r == pytest.approx(f * base.v_r)
            assert max(abs(out.v_l), abs(out.v_r)) <= c_star * (1 + 1e-12)
            assert math.copysign(1.0, out.v_r - out.v_l) == math.copysign(1.0, alpha)
            assert abs(out.v_r - out.v_l) > abs(base.v_r - base.v_l)
        assert max(abs(command(math.inf).v_l), abs(command(math.inf).v_r)) == pytest.approx(c_star)
        ctl = TrackingEKM("r1", model, R, TrackingParams(assign_radius=0.0))  # the default: turn part to c*
        out = ctl.integrate(ctl.localize(0.0, pose, {"a": (alpha, 0.8 * R)}, TeamView("r1")), [])
        assert (out.k, out.s) == (base.k, base.s)
        assert out.v_l + out.v_r == pytest.approx(base.v_l + base.v_r)  # the map's mean speed kept
        assert max(abs(out.v_l), abs(out.v_r)) == pytest.approx(c_star)
        assert math.copysign(1.0, out.v_r - out.v_l) == math.copysign(1.0, alpha)
    for alpha in (0.5, -0.9, 0.0):  # ahead (within face_angle): untouched
        outs = []
        for g, only in ((1.0, False), (math.inf, False), (math.inf, True)):
            ctl = TrackingEKM("r1", model, R, TrackingParams(assign_radius=0.0, face_turn_gain=g, face_turn_only=only))
            outs.append(ctl.integrate(ctl.localize(0.0, pose, {"a": (alpha, 0.9 * R)}, TeamView("r1")), []))
        assert outs[0] == outs[1] == outs[2]


def test_face_turn_scales_up_to_the_wheels_limit_only():
    from cekm_swarm.controller.tracking import face_turn
    assert face_turn(0.0, 0.0, 4.0, 0.15) == (0.0, 0.0)
    assert face_turn(-0.01, 0.02, 2.0, 0.15) == (-0.02, 0.04)
    assert face_turn(-0.01, 0.02, math.inf, 0.15) == pytest.approx((-0.075, 0.15))
    assert face_turn(-0.1, 0.15, 3.0, 0.15) == (-0.1, 0.15)  # already at c*
    # turn_only: the turn part scaled, the mean speed kept
    assert face_turn(-0.01, 0.02, 2.0, 0.15, turn_only=True) == pytest.approx((-0.025, 0.035))
    assert face_turn(-0.01, 0.02, math.inf, 0.15, turn_only=True) == pytest.approx((-0.14, 0.15))
    assert face_turn(0.02, 0.02, math.inf, 0.15, turn_only=True) == (0.02, 0.02)  # no turn to scale


def test_face_turn_gain_reaches_the_motor_module_and_is_validated():
    """The motor module executes Eq. 11, so it takes TrackingParams (a graph's or --param's)."""
    from cekm_swarm.experiments.graph_run import with_params
    from cekm_swarm.graph.spec import graph_for
    from cekm_swarm.node.graph_check import check_graph
    checked = with_params(check_graph(str(graph_for("cekm", "tracking"))), {"face_turn_gain": 3.0})
    assert checked.make_params("motor").face_turn_gain == 3.0
    assert TrackingParams(face_turn_gain=math.inf).face_turn_gain == math.inf
    for bad in (0.5, 0.0, -1.0, float("nan")):
        with pytest.raises(ParameterError, match="face_turn_gain"):
            TrackingParams(face_turn_gain=bad)
