"""The learning graphs' plans (docs/learning.md): the EKM nodes' readings are still held
(a delayed map input does not count), the world sends every reading as a version starts,
and the learner's odometry is a world key of its own period."""

from __future__ import annotations

import pytest

from cekm_swarm.experiments.graph_run import resolve_graph


@pytest.mark.parametrize("controller", ["cekm-learning", "cekm-learning-team"])
def test_learning_graph_plans_hold_readings_and_name_the_map_period(controller):
    plan = resolve_graph(controller, None, "navigation").plan(("r1", "r2"), "navigation")
    plain = resolve_graph("cekm-tuned", None, "navigation").plan(("r1", "r2"), "navigation")
    assert plan.held_readings("r1") == plain.held_readings("r1")  # every range and the target reading
    assert plan.map_period("r1") == 8 and plain.map_period("r1") is None
    assert "cekm/r1/sense/odometry" in plan.world_keys("r1")
    assert "cekm/r1/sense/odometry" not in plain.world_keys("r1")
    learner = next(n for n in plan.nodes["r1"] if n.decl.name == "learner")
    assert plan.holding_reader(learner) is None  # not a pure node
    obstacle = next(n for n in plan.nodes["r1"] if n.decl.name == "obstacle")
    assert plan.holding_reader(obstacle) == "cekm/r1/sense/range/0"
