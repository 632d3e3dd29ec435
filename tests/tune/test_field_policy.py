"""The field policy: its mapping, its file, the features it reads, and that the motor node uses it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.models.params import FieldParams
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.tune.features import FEATURES, field_features
from cekm_swarm.tune.graphs import fields_graph, policy_graph, with_fields
from cekm_swarm.tune.policy import FieldPolicy
from world import load_scenario


def test_zero_weights_are_todays_constants_exactly():
    nav = FieldPolicy("navigation").choose(np.ones(len(FEATURES)))
    assert nav.fields == FieldParams() and nav.teammate_gain == 1.0
    trk = FieldPolicy("tracking").choose(np.ones(len(FEATURES)))
    assert trk.fields == FieldParams.paper() and trk.teammate_gain == 1.0


def test_the_action_is_bounded_by_the_span():
    W = np.zeros((3, len(FEATURES)))
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
    with pytest.raises(ParameterError, match=r"bad.json: weights must be 4 x 9"):
        FieldPolicy.load(bad)
    doc["task"] = "juggling"
    bad.write_text(json.dumps(doc))
    with pytest.raises(ParameterError, match="task must be one of"):
        FieldPolicy.load(bad)


def test_features_see_an_obstacle_ahead_and_the_target():
    w = np.array([[0.0, 0.02], [0.0, 0.16], [math.pi / 2, 0.08], [-math.pi / 2, 0.08], [math.pi, 0.16]])
    f = dict(zip(FEATURES, field_features(w, [0, None, 2, None], (0.0, 0.16)), strict=True))
    assert f["bias"] == 1.0 and f["front"] == pytest.approx(1 - 0.02 / 0.16) and f["left"] == pytest.approx(0.5)
    assert f["right"] == 0.0 and f["seen"] == 0.5 and f["toward_target"] == f["front"]
    assert f["target_angle"] == 0.0 and f["target_near"] == 0.0 and f["teammates"] == 0.0
    empty = field_features(w, [None] * 12, None)
    assert empty.tolist() == [1.0] + [0.0] * (len(FEATURES) - 1)


def test_the_motor_node_uses_the_policys_widths():
    """Zero weights give the shipped run; a policy that widens the obstacle fields ahead
    changes it (the widths really come from the policy)."""
    sc = load_scenario("concave")
    checked = check_graph(policy_graph("navigation"))
    base = run_graph(sc, "cekm").episode.outcome()
    zero = run_graph(sc, graph=checked, params={"weights": (0.0,) * 27}).episode.outcome()
    W = np.zeros((3, len(FEATURES)))
    W[0, 1] = 3.0  # sigma_b_alpha up with an obstacle ahead
    wide = run_graph(sc, graph=checked, params={"weights": tuple(W.ravel().tolist())}).episode.outcome()
    assert zero == base and wide != base


def test_fields_option_graphs():
    checked, params = fields_graph("paper", "navigation")
    assert params == {"sigma_b_alpha": 0.495}
    assert fields_graph("tuned", "tracking")[1] == {}
    g, params = fields_graph("learned", "navigation", "p.json")
    assert g.graph.node("motor").program.endswith("FieldMotor") and params == {"policy": "p.json"}
    with pytest.raises(ParameterError, match="--fields must be one of"):
        fields_graph("clever", "navigation")
    fusion = check_graph("fusion-navigation")
    assert with_fields(fusion, None, "navigation") is fusion
    with pytest.raises(ParameterError, match="--fields goes with --controller cekm"):
        with_fields(fusion, "paper", "navigation")


def test_a_bad_policy_file_stops_the_node_with_its_name(tmp_path):
    bad = tmp_path / "nav.json"
    bad.write_text("[]")
    from cekm_swarm.node import NodeError

    with pytest.raises(NodeError, match="nav.json: not a field policy"):
        run_graph(load_scenario("concave"), graph=check_graph(policy_graph("navigation")),
                  params={"policy": str(bad)}, max_time=1.0)
