"""Generated scenarios: every kind parses, a seed gives one scenario, and the purposes' seeds never meet."""

from __future__ import annotations

import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.tune.scenarios import KINDS, SEED_BASE, navigation_raw, navigation_scenario, seed_of, tracking_scenario


def test_every_kind_parses_over_many_seeds():
    seen = set()
    for i in range(40):
        sc = navigation_scenario(seed_of("train", i))
        seen.add(sc.name.split("-")[1])
        assert sc.robots[0].goal == "goal"
    assert seen == set(KINDS)
    for kind in KINDS:
        assert navigation_scenario(5, kind).name.startswith(f"gen-{kind}")


def test_a_seed_is_one_scenario_and_purposes_are_apart():
    assert navigation_raw(1_000_003) == navigation_raw(1_000_003) != navigation_raw(1_000_004)
    bases = sorted(SEED_BASE.values())
    assert (
        all(b - a >= 1_000_000 for a, b in zip(bases, bases[1:], strict=False)) and bases[0] > 139
    )  # no reported seed
    with pytest.raises(ParameterError, match="unknown seed purpose"):
        seed_of("holdout", 1)
    with pytest.raises(ParameterError, match="unknown geometry kind"):
        navigation_raw(1, "maze")


def test_tracking_scenarios_are_grid_cells():
    sc = tracking_scenario(seed_of("validation", 2))
    assert sc.name.startswith("grid-n") and all(r.goal is None for r in sc.robots)
