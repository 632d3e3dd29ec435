"""`cekm experiment learning`'s runs (cekm_swarm.experiments.learning_experiment): a short
team run through the learning graph, scored as it learns (docs/learning.md)."""

from __future__ import annotations

import tomllib

import pytest

from cekm_swarm.experiments.learning_experiment import LearningConfig, results_doc, run_one, scenario_text
from world.scenario import parse_scenario

pytestmark = pytest.mark.slow  # runs an experiment (tests/process_guard.py)


def test_team_scenarios_are_valid():
    for n in (1, 2, 4, 8):
        sc = parse_scenario(tomllib.loads(scenario_text(n)))
        assert len(sc.robots) == n and sc.bounds == (-2.5, -2.5, 2.5, 2.5)


def test_a_short_shared_run_learns_and_is_scored(tmp_path):
    config = LearningConfig(teams=(2,), seeds=(1,), ticks=24, evals=(0, 24))
    c = run_one(2, True, 1, config, tmp_path)
    assert c.steps[0] == 0 and c.updates[0] == 0
    assert c.E_mm[0] > 1000.0  # the untrained map: every test target ends by the budget
    assert 0 < c.steps[-1] <= 24 and c.updates[-1] > c.steps[-1]  # the teammate's pairs too
    assert c.E_mm[-1] < c.E_mm[0]
    doc = results_doc(config, [c])
    assert doc["summary"]["2-shared"]["final_E_mm"] == [c.E_mm[-1]]
