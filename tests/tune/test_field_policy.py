"""The field policy: its mapping, its file, the features it reads, and that the motor node uses it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.field_widths import policy_graph
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.models.params import FieldParams
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.tune.features import (
    FEATURES,
    FIELD_FEATURES,
    ClosingSpeeds,
    closing_speed,
    field_features,
    obstacle_features,
)
from cekm_swarm.tune.graphs import with_fields
from cekm_swarm.tune.motor import PAPER, PLAIN
from cekm_swarm.tune.policy import FieldPolicy, shipped_policy
from helpers.pair import pair_toml
from world import load_scenario


def test_zero_weights_are_todays_constants_exactly():
    nav = FieldPolicy("navigation").choose(np.ones(len(FEATURES)))
    assert nav.fields == FieldParams() and nav.teammate_gain == 1.0
    trk = FieldPolicy("tracking").choose(np.ones(len(FEATURES)))
    assert trk.fields == FieldParams.paper() and trk.teammate_gain == 1.0


def test_the_action_is_bounded_by_the_span():
    W = np.zeros((5, len(FEATURES)))
    W[0, 0], W[1, 0] = 100.0, -100.0
    v = FieldPolicy("navigation", W).choose(np.eye(len(FEATURES))[0]).fields
    assert v.sigma_b_alpha == pytest.approx(2 * 0.6) and v.sigma_b_d_beyond == pytest.approx(2.475 / 4)


def test_save_load_round_trip_and_bad_files(tmp_path):
    p = FieldPolicy("tracking", np.arange(4 * len(FEATURES)) / 100.0, {"seed": 3})
    p.save(tmp_path / "p.json")
    q = FieldPolicy.load(tmp_path / "p.json")
    assert q.task == "tracking" and np.array_equal(q.W, p.W) and q.meta == {"seed": 3}
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(ParameterError, match="bad.json: not a readable field policy"):
        FieldPolicy.load(bad)
    doc = p.to_dict()
    doc["weights"] = [[0.0]]
    bad.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match=r"bad.json: weights must be 4 x 11"):
        FieldPolicy.load(bad)
    doc["task"] = "juggling"
    bad.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match="task must be one of"):
        FieldPolicy.load(bad)


def test_without_v_every_field_gets_the_ticks_widths_bit_for_bit():
    """V = 0 (or no V) is the tick's policy exactly; W = V = 0 today's constants."""
    rng = np.random.default_rng(4)
    f, g = rng.uniform(0, 1, len(FEATURES)), rng.uniform(0, 1, (12, len(FIELD_FEATURES)))
    no_v = FieldPolicy("navigation", field_weights=np.zeros((3, len(FIELD_FEATURES))))
    assert no_v.field_params(f, g) == [FieldParams()] * 12
    for task in ("navigation", "tracking"):
        W = rng.normal(0, 1, (len(FieldPolicy(task).outputs), len(FEATURES)))
        tick = FieldPolicy(task, W).choose(f).fields
        zero_v = FieldPolicy(task, W, field_weights=np.zeros((3, len(FIELD_FEATURES))))
        assert not zero_v.per_field and FieldPolicy(task, W).field_params(f, g) == [tick] * 12
        assert zero_v.field_params(f, g) == [tick] * 12  # the per-field formula with V = 0, to the bit


def test_v_gives_each_field_its_own_widths_within_the_span():
    V = np.zeros((3, len(FIELD_FEATURES)))
    V[0, FIELD_FEATURES.index("near")] = 100.0  # sigma_b_alpha at its widest for a near field only
    p = FieldPolicy("navigation", field_weights=V)
    g = np.zeros((2, len(FIELD_FEATURES)))
    g[0, 0] = 0.9
    near, far = p.field_params(np.ones(len(FEATURES)), g)
    assert p.per_field and near.sigma_b_alpha == pytest.approx(2 * 0.6) and far == FieldParams()
    assert near.sigma_b_d_beyond == far.sigma_b_d_beyond and near.sigma_a_alpha == far.sigma_a_alpha


def test_flat_weights_and_their_lengths():
    p = FieldPolicy.from_flat("navigation", tuple(range(73)))
    assert p.W[4, 10] == 54 and p.V is not None and p.V[2, 5] == 72 and p.flat() == tuple(float(x) for x in range(73))
    assert FieldPolicy.from_flat("navigation", (0.0,) * 55).V is None
    assert FieldPolicy.size("tracking", per_field=True) == 44 + 18
    with pytest.raises(ParameterError, match=r"takes 55 \(W\) or 73 \(W and V\) numbers, got 30"):
        FieldPolicy.from_flat("navigation", (0.0,) * 30)


def test_a_v_policy_file_round_trips_and_old_files_load(tmp_path):
    W1 = np.random.default_rng(7).normal(0, 1, (3, 9))
    v1 = {"format": "cekm-field-policy", "version": 1, "task": "navigation", "features": list(FEATURES[:9]),
          "outputs": ["sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near"], "base": [0.6, 2.475, 0.02475],
          "span": [0.693, 1.386, 0.693], "weights": W1.tolist()}
    (tmp_path / "v1.json").write_text(json.dumps(v1))
    old = FieldPolicy.load(tmp_path / "v1.json")  # version 1: no V, no sigma_a_d, no pocket (their weights 0)
    assert old.V is None and not old.per_field and old.to_dict()["version"] == 1 and not old.W[3:].any()
    assert np.array_equal(old.W[:3, :9], W1) and not old.W[:, 9].any()
    shipped = FieldPolicy.load(shipped_policy("navigation"))  # --fields learned: a policy with its training command
    assert shipped.task == "navigation" and shipped.per_field and shipped.meta["command"].startswith("cekm tune fields")
    assert old.choose(np.ones(len(FEATURES))).fields.sigma_a_d == FieldParams().sigma_a_d
    W = old.W.copy()
    W[3, 0] = 0.5  # sigma_a_d moves: a version-1 file cannot say it
    FieldPolicy("navigation", W).save(tmp_path / "w.json")
    assert FieldPolicy.load(tmp_path / "w.json").to_dict()["version"] == 6
    assert np.array_equal(FieldPolicy.load(tmp_path / "w.json").W, W)
    W1 = old.W.copy()
    W1[0, 9] = -1.0  # the pocket feature is read: a version-1 file cannot say it either
    FieldPolicy("navigation", W1).save(tmp_path / "w1.json")
    assert FieldPolicy.load(tmp_path / "w1.json").to_dict()["version"] == 6
    p = FieldPolicy("navigation", old.W, {"seed": 5}, np.arange(18.0).reshape(3, 6) / 10)
    p.save(tmp_path / "v.json")
    q = FieldPolicy.load(tmp_path / "v.json")
    assert q.to_dict()["version"] == 6 and np.array_equal(q.V, p.V) and np.array_equal(q.W, p.W) and q.meta == p.meta
    doc = p.to_dict()
    w9 = [row[:9] for row in doc["weights"]]
    v3 = {**doc, "version": 3, "features": list(FEATURES[:9]), "outputs": doc["outputs"][:4], "base": doc["base"][:4],
          "span": doc["span"][:4], "weights": w9[:4]}
    (tmp_path / "v3.json").write_text(json.dumps(v3))
    r3 = FieldPolicy.load(tmp_path / "v3.json")  # nine features and four outputs: the rest at weight 0
    assert np.array_equal(r3.W, p.W) and not r3.W[:, 9].any() and not r3.W[4].any() and np.array_equal(r3.V, p.V)
    v4 = {**v3, "version": 4, "features": list(FEATURES[:10]), "weights": [row[:10] for row in doc["weights"][:4]]}
    (tmp_path / "v4.json").write_text(json.dumps(v4))
    assert np.array_equal(FieldPolicy.load(tmp_path / "v4.json").W, p.W)  # four outputs: sigma_a_alpha's row 0
    v5 = {**doc, "version": 5, "features": list(FEATURES[:10]), "weights": [row[:10] for row in doc["weights"]]}
    (tmp_path / "v5.json").write_text(json.dumps(v5))
    r5 = FieldPolicy.load(tmp_path / "v5.json")  # ten features: stalled's column at weight 0
    assert np.array_equal(r5.W, p.W) and not r5.W[:, 10].any()
    v2 = {**doc, "version": 2, "features": list(FEATURES[:9]), "outputs": doc["outputs"][:3], "base": doc["base"][:3],
          "span": doc["span"][:3], "weights": w9[:3], "field_features": list(FIELD_FEATURES[:5]),
          "field_weights": (p.V[:, :5]).tolist()}
    (tmp_path / "v2.json").write_text(json.dumps(v2))
    r = FieldPolicy.load(tmp_path / "v2.json")  # five features, closing's column 0, sigma_a_d's row 0
    assert r.V is not None and np.array_equal(r.V[:, :5], p.V[:, :5]) and not r.V[:, 5].any()
    assert np.array_equal(r.W, p.W) and not r.W[3].any()
    g = np.random.default_rng(1).uniform(0, 1, (12, len(FIELD_FEATURES)))
    g5 = g.copy()
    g5[:, 5] = 0.0
    f = np.ones(len(FEATURES))
    assert np.array_equal(r.field_widths(f, g), FieldPolicy("navigation", old.W, field_weights=r.V).field_widths(f, g5))
    bad = tmp_path / "bad.json"
    for key, value, message in (("field_features", ["near"], "field_features/field_outputs are not version 6's"),
                                ("field_weights", [[0.0]], "field_weights must be 3 x 6, got shape \\(1, 1\\)"),
                                ("field_weights", "many", "weights must be arrays of numbers"),
                                ("features", list(FEATURES[:9]), "features/outputs are not version 6's"),
                                ("version", 7, "format version 7; this code reads versions 1 to 6")):
        bad.write_text(json.dumps({**doc, key: value}))
        with pytest.raises(ParameterError, match=message):
            FieldPolicy.load(bad)
    bad.write_text(json.dumps({**v2, "outputs": doc["outputs"]}))  # version 2 with version 6's outputs
    with pytest.raises(ParameterError, match="features/outputs are not version 2's"):
        FieldPolicy.load(bad)


def test_each_field_sees_its_own_situation():
    """near, off_heading, toward_target, nearest, lone: a wall end (one neighbour blind), a
    ray inside a wall (both neighbours see), a lone post; a sensor that sees nothing is 0."""
    w = np.array([[0.0, 0.02], [0.0, 0.16], [math.pi / 2, 0.08], [-math.pi / 2, 0.04], [math.pi, 0.16]])
    winners = [0, 2, 2, None, 3, None]  # sensors 0..5 around a ring of six
    g = obstacle_features(w, winners, list(range(6)), (math.pi / 2, 0.1))
    row = [dict(zip(FIELD_FEATURES, r, strict=True)) for r in g]
    assert row[0]["near"] == pytest.approx(1 - 0.02 / 0.16) and row[0]["off_heading"] == 0.0
    assert row[0]["toward_target"] == pytest.approx(0.5) and row[1]["toward_target"] == 1.0
    assert row[1]["off_heading"] == pytest.approx(0.5) and row[4]["toward_target"] == 0.0
    assert [r["nearest"] for r in row] == [1, 0, 0, 0, 0, 0]
    assert row[0]["lone"] == 0.5 and row[1]["lone"] == 0.0 and row[2]["lone"] == 0.5 and row[4]["lone"] == 1.0
    assert not g[3].any() and not g[5].any()
    assert obstacle_features(w, [None, 1, None], [0, 1, 2], None)[1].tolist() == [0.0, 0.0, 0.0, 1.0, 1.0, 0.0]
    assert obstacle_features(w, [0, 1], [0, 1], None, [0.15, 9.0])[:, 5].tolist() == [0.5, 1.0]


def test_closing_tells_a_mover_from_the_robots_own_approach():
    """A wall ahead closing at the robot's own speed gives 0; the same closing beside the
    robot (nothing it drives at) is a mover's; an old or missing reading gives 0."""
    assert closing_speed((0.0, 0.10), (0.5, 0.05), 0.0, 0.1) == pytest.approx(0.0)
    assert closing_speed((0.0, 0.10), (0.5, 0.05), math.pi / 2, 0.1) == pytest.approx(0.1)
    assert closing_speed((0.0, 0.05), (0.5, 0.10), math.pi / 2, 0.0) == 0.0  # receding
    assert closing_speed(None, (0.5, 0.05), 0.0, 0.0) == 0.0
    assert closing_speed((0.0, 0.10), (2.0, 0.05), 0.0, 0.0) == 0.0
    w = np.array([[math.pi / 2, 0.10], [math.pi / 2, 0.07], [0.0, 0.10]])
    c = ClosingSpeeds()
    assert c.update(w, [(0.0, 3, 0), (0.0, 4, 2)], 0.0) == [0.0, 0.0]
    assert c.update(w, [(0.25, 3, 1), (0.25, 4, None)], 0.0) == [pytest.approx(0.12), 0.0]
    assert c.update(w, [(0.5, 3, 1), (0.5, 4, 2)], 0.0) == [0.0, 0.0]  # sensor 4 was blind: no difference


def test_features_see_an_obstacle_ahead_and_the_target():
    w = np.array([[0.0, 0.02], [0.0, 0.16], [math.pi / 2, 0.08], [-math.pi / 2, 0.08], [math.pi, 0.16]])
    f = dict(zip(FEATURES, field_features(w, [0, None, 2, None], (0.0, 0.16)), strict=True))
    assert f["bias"] == 1.0 and f["front"] == pytest.approx(1 - 0.02 / 0.16) and f["left"] == pytest.approx(0.5)
    assert f["right"] == 0.0 and f["seen"] == 0.5 and f["toward_target"] == f["front"]
    assert f["target_angle"] == 0.0 and f["target_near"] == 0.0 and f["teammates"] == 0.0
    assert f["pocket"] == 0.0  # ahead and on the left, nothing on the right: a corner, not a pocket
    pocket = dict(zip(FEATURES, field_features(w, [0, None, 2, 3], (0.0, 0.16)), strict=True))
    assert pocket["pocket"] == pytest.approx(0.5)  # ahead (0.875), left and right (0.5 each): the least
    corridor = dict(zip(FEATURES, field_features(w, [None, None, 2, 3], (0.0, 0.16)), strict=True))
    assert corridor["left"] == corridor["right"] == pytest.approx(0.5) and corridor["pocket"] == 0.0
    empty = field_features(w, [None] * 12, None)
    assert empty.tolist() == [1.0] + [0.0] * (len(FEATURES) - 1)


def test_the_motor_node_uses_the_policys_widths():
    """Zero weights give the shipped run; a policy that widens the obstacle fields ahead
    changes it (the widths really come from the policy)."""
    sc = load_scenario("concave")
    checked = check_graph(policy_graph("navigation"))
    base = run_graph(sc, "cekm-tuned").episode.outcome()
    plain = PLAIN  # Eq. 11's command as the plain motor executes it, no trail field
    zero = run_graph(sc, graph=checked, params={"weights": (0.0,) * 55, **plain}).episode.outcome()
    zero_v = run_graph(sc, graph=checked, params={"weights": (0.0,) * 73, **plain}).episode.outcome()
    W = np.zeros((5, len(FEATURES)))
    W[0, 1] = 3.0  # sigma_b_alpha up with an obstacle ahead
    wide = run_graph(sc, graph=checked, params={"weights": tuple(W.ravel().tolist())}).episode.outcome()
    V = np.zeros((3, len(FIELD_FEATURES)))
    V[0, 0] = 3.0  # sigma_b_alpha up for the near fields only
    near = run_graph(sc, graph=checked, params={"weights": (0.0,) * 55 + tuple(V.ravel().tolist())},
                     max_time=60.0).episode.outcome()
    assert zero == base and zero_v == base and wide != base and near != base


@pytest.mark.parametrize("row,name,bias", [(3, "sigma_a_d", 0.7), (4, "sigma_a_alpha", -0.5)])
def test_the_policys_target_width_is_the_target_modules_own_exactly(row, name, bias):
    """A policy that sets sigma_a_d or sigma_a_alpha (Eq. 6) everywhere runs as the shipped
    graph whose target module computes with that width: the motor's recomputed target field
    is the module's."""
    sc = load_scenario("concave")
    W = np.zeros((5, len(FEATURES)))
    W[row, 0] = bias
    width = getattr(FieldPolicy("navigation", W).choose(np.ones(len(FEATURES))).fields, name)
    assert width != getattr(FieldParams(), name)
    policy = run_graph(sc, graph=check_graph(policy_graph("navigation")),
                       params={"weights": tuple(W.ravel().tolist()), **PLAIN}, max_time=40.0).episode.outcome()
    module = run_graph(sc, "cekm-tuned", params={name: width}, max_time=40.0).episode.outcome()
    assert policy == module and policy != run_graph(sc, "cekm-tuned", max_time=40.0).episode.outcome()


def test_the_tracking_policy_motor_takes_the_trackers_parameters():
    """The tracking field-policy motor with zero weights is the shipped tracking motor, with
    the default TrackingParams and with ``face_turn_gain=1`` (the previous turn) alike: the
    parameter reaches it, and changes the run."""
    sc = load_scenario("tracking")
    checked = check_graph(policy_graph("tracking"))
    zero = (0.0,) * FieldPolicy.size("tracking")
    runs = {}
    for gain in (math.inf, 1.0):
        shipped = run_graph(sc, "cekm", params={"face_turn_gain": gain}, max_time=30.0).episode.outcome()
        policy = run_graph(sc, graph=checked, params={"weights": zero, "face_turn_gain": gain},
                           max_time=30.0).episode.outcome()
        assert policy == shipped
        runs[gain] = policy
    assert runs[math.inf] != runs[1.0]


def test_fields_option_takes_only_a_cooperative_ekm_graph():
    fusion = check_graph("fusion-navigation")
    assert with_fields(fusion, None, "navigation") is fusion
    with pytest.raises(ParameterError, match="--fields goes with --controller cekm"):
        with_fields(fusion, "paper", "navigation")
    tuned = check_graph("cekm-tuned-navigation")
    assert with_fields(tuned, "learned", "navigation").graph.controller == "cekm"
    with pytest.raises(ParameterError, match="--policy p.json goes with --fields learned, not tuned"):
        with_fields(tuned, "tuned", "navigation", "p.json")


def test_a_bad_policy_file_stops_the_node_with_its_name(tmp_path):
    bad = tmp_path / "nav.json"
    bad.write_text("[]")
    from cekm_swarm.node import NodeError

    with pytest.raises(NodeError, match="nav.json: not a field policy"):
        run_graph(load_scenario("concave"), graph=check_graph(policy_graph("navigation")),
                  params={"policy": str(bad)}, max_time=1.0)


def _pair(tmp_path):
    path = tmp_path / "pair.toml"
    path.write_text(pair_toml((0.2, 0.355, -0.1)))  # a start where the learned widths leave only a turn in place
    return load_scenario(str(path))


def test_the_constant_widths_pass_a_small_disc_head_on(tmp_path):
    assert run_graph(_pair(tmp_path), "cekm-tuned", seed=1, max_time=60.0).episode.outcome()["r1"]["reached"]


def test_the_default_passes_a_small_disc_head_on_by_turning_at_speed(tmp_path):
    """The stall the realtime launch test met: the obstacle field widened for a wall ahead
    inhibits every forward neuron the map has, a turn-in-place neuron toward the rear wins,
    and executed as the map commands it (PLAIN: turn_gain 1, no trail) the robot turns so slowly that the
    next winner turns it back: it swings in front of the disc. Executed at speed (the
    default), it turns away and passes (docs/fields.md, the sixth round)."""
    sc = _pair(tmp_path)
    assert run_graph(sc, "cekm", seed=1, max_time=60.0).episode.outcome()["r1"]["reached"]
    slow = run_graph(sc, "cekm", seed=1, max_time=60.0, params=PLAIN).episode.outcome()["r1"]
    assert not slow["reached"]


def test_the_default_backs_out_of_a_narrow_u_it_entered():
    """Fig. 9's hole cell (0.1 m wide, 0.18 m deep, sensing range 0.12 m): the robot enters
    the slot, the arms and back wall inhibit every forward neuron, and only a turn in place
    toward the rear is left; executed at speed it turns round, drives out and goes round."""
    sc = load_scenario("concave", overrides={"obstacles[0].width": 0.1, "obstacles[0].depth": 0.18,
                                             "sensors.range": 0.12})
    assert run_graph(sc, "cekm", seed=3, max_time=40.0).episode.outcome()["r1"]["reached"]
    slow = run_graph(sc, "cekm", seed=3, max_time=40.0, params=PLAIN).episode.outcome()["r1"]
    assert not slow["reached"] and slow["collisions"] == 0  # stalled in the slot, not stuck on a wall


def test_the_trail_field_leads_out_of_a_deep_u_the_robot_circles_in():
    """A generated U (0.71 m wide, 0.27 m deep, facing the start, the goal behind it, sensing
    range 0.15 m; validation seed 2,000,079): the robot drives in, and the target field pulls
    it back each time it reaches the mouth, so it circles inside until the run ends. With the
    trail field (docs/fields.md, the seventh round) the places it circled are inhibited once
    the goal has come no nearer for a while, and it leaves the U and reaches the goal."""
    from cekm_swarm.tune.scenarios import navigation_scenario

    sc = navigation_scenario(2_000_079)
    trapped = run_graph(sc, "cekm", max_time=200.0, params={"trail_gain": 0.0}).episode.outcome()["r1"]
    assert not trapped["reached"] and trapped["collisions"] == 0
    out = run_graph(sc, "cekm", max_time=200.0).episode.outcome()["r1"]  # the default: trail_gain TRAIL_GAIN
    assert out["reached"] and out["collisions"] == 0


def test_the_default_keeps_clear_of_a_disc_that_would_hit_it_side_on():
    """Rooms with movers (validation seed 2,000,067): a circling disc hits the robot from its
    front left while it drives through the middle room. The movers' detector finds it in the
    raw ranges (a hit in space a ray saw free a moment before) and the command that would
    bring the body within 1 cm of it is replaced: the run is contact-free (docs/fields.md)."""
    from cekm_swarm.tune.scenarios import navigation_scenario

    sc = navigation_scenario(2_000_067)
    hit = run_graph(sc, "cekm", max_time=120.0, params={"keep_clear": False}).episode.outcome()["r1"]
    assert hit["reached"] and hit["collisions"] >= 1
    out = run_graph(sc, "cekm", max_time=120.0).episode.outcome()["r1"]
    assert out["reached"] and out["collisions"] == 0


def test_the_default_keeps_off_a_doorway_jamb_end_that_falls_between_two_rays():
    """Section 4.2's rooms (validation seed 2,000,051): the robot passes the first doorway and
    its side closes on the upper jamb's end, seen by a ray a tick before and then between two
    rays. The guard remembers the hits of the last ticks, and the command that would bring the
    body within 1 cm of one is replaced by the nearest that does not (docs/fields.md, the ninth
    round)."""
    sc = load_scenario("rooms")
    hit = run_graph(sc, "cekm", max_time=30.0, seed=2_000_051, params={"guard": False}).episode.outcome()["r1"]
    assert "walls[1]" in hit["collisions_with"]
    guarded: list[bool] = []
    out = run_graph(sc, "cekm", max_time=30.0, seed=2_000_051,
                    observe=lambda ex, _: guarded.append(ex.node("r1", "motor").last_guarded)).episode.outcome()["r1"]
    assert out["collisions"] == 0 and out["path_length_m"] > 1.0
    assert 0 < sum(guarded) < len(guarded) / 10  # it replaced a few commands, not the run's


def test_the_papers_widths_in_their_turn_lead_round_a_long_shallow_u():
    """Fig. 9's cell that the paper's constants negotiate (a U 2 m wide and 0.12 m deep, sensing
    range 0.12 m; validation seed 2,000,014): the learned widths take the robot up to the back
    wall, it follows the wall to an arm's inside, turns back and circles. Once the trail has
    acted for 20 s the paper's widths take their turn: they hold the robot at the edge of its
    range and it slides along the mouth toward an arm's end, which it then goes round
    (docs/fields.md, the tenth round). In their turn every obstacle field has the paper's
    widths, not its own."""
    sc = load_scenario("concave", overrides={"obstacles[0].width": 2.0, "obstacles[0].depth": 0.12,
                                             "sensors.range": 0.12})
    circles = run_graph(sc, "cekm", seed=2_000_014, max_time=120.0, params={"alternate": 0.0}).episode.outcome()["r1"]
    assert not circles["reached"] and circles["collisions"] == 0
    ticks: list[tuple[bool, set]] = []

    def observe(ex, _):
        motor = ex.node("r1", "motor")
        ticks.append((motor.last_choice is PAPER, set(motor.last_widths)))

    out = run_graph(sc, "cekm", seed=2_000_014, max_time=120.0, observe=observe).episode.outcome()["r1"]
    assert out["reached"] and out["collisions"] == 0
    paper = FieldParams.paper()
    turns = [widths for in_turn, widths in ticks if in_turn]
    assert 0 < len(turns) < len(ticks) / 2
    assert all(w <= {(paper.sigma_b_alpha, paper.sigma_b_d_beyond, paper.sigma_b_d_near)} for w in turns)


def test_a_negative_alternate_is_refused_naming_the_node():
    from cekm_swarm.node.api import NodeError

    with pytest.raises(NodeError, match=r"r1/motor: alternate must be >= 0 s \(0: never\), got -1.0"):
        run_graph(load_scenario("concave"), "cekm", params={"alternate": -1.0}, max_time=1.0)


def test_a_negative_trail_gain_is_refused_naming_the_node():
    from cekm_swarm.node.api import NodeError

    with pytest.raises(NodeError, match=r"r1/motor: trail gain must be >= 0, got -0.5"):
        run_graph(load_scenario("concave"), "cekm", params={"trail_gain": -0.5}, max_time=1.0)


def test_a_turn_gain_below_one_is_refused_naming_the_node():
    from cekm_swarm.node.api import NodeError

    with pytest.raises(NodeError, match=r"r1/motor: turn_gain must be >= 1 \(inf: up to c\*\), got 0.5"):
        run_graph(load_scenario("concave"), "cekm", params={"turn_gain": 0.5}, max_time=1.0)


def test_stalled_is_how_little_the_robots_own_commands_moved_it():
    """``stalled`` over STALL_WINDOW s of sent commands: 0 until a window has passed, 0 at
    full pace, 1 turning in place or back and forth, linear in the net forward travel."""
    from cekm_swarm.ticks import TICK_S
    from cekm_swarm.tune.features import STALL_PACE, STALL_WINDOW, Stall

    v_max = 0.2

    def after(speeds) -> float:
        s = Stall()
        for k, v in enumerate(speeds):
            s.update(k * TICK_S, v)
        return s.value(len(speeds) * TICK_S, v_max)

    n = int(STALL_WINDOW / TICK_S) + 2
    assert after([0.0] * (n - 10)) == 0.0  # less than a window: not known
    assert after([0.0] * n) == 1.0 and after([v_max] * n) == 0.0
    assert after([0.05, -0.05] * n) == pytest.approx(1.0, abs=0.02)  # forward and back nets nothing
    assert after([STALL_PACE * v_max / 2] * n) == pytest.approx(0.5)
    assert after([0.0] * n + [v_max] * n) == 0.0  # only the last window counts
    feats = field_features(np.array([[0.0, 0.1], [1.0, 0.2]]), [None], None, stalled=0.75)
    assert feats[FEATURES.index("stalled")] == 0.75


def test_a_policy_set_while_the_motor_runs_takes_over_and_a_bad_one_is_refused(tmp_path, caplog):
    """``cekm param set r1/motor policy FILE`` replaces the node's params between steps: the
    field-policy motor follows from its next step; a file it cannot read is refused in its
    log, naming it, and the policy before it stays."""
    import dataclasses

    from cekm_swarm.experiments.graph_run import GraphSession

    FieldPolicy("navigation").save(tmp_path / "zero.json")
    (tmp_path / "bad.json").write_text("[]")
    s = GraphSession(load_scenario("concave"), "cekm", max_time=10.0)
    for _ in range(20):
        s.step()
    motor = s.executor.node("r1", "motor")
    shipped = motor.policy
    assert motor.last_choice.fields != FieldParams()  # the shipped policy moves the widths
    motor.params = dataclasses.replace(motor.params, policy=str(tmp_path / "bad.json"))
    s.step()
    assert motor.policy is shipped and "bad.json refused" in caplog.text and "not a field policy" in caplog.text
    motor.params = dataclasses.replace(motor.params, policy=str(tmp_path / "zero.json"))
    s.step()
    assert motor.policy is not shipped and motor.last_choice.fields == FieldParams()  # W = 0: the constants
