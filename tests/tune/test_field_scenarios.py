"""Generated scenarios: every kind parses, a seed gives one scenario, and the purposes' seeds never meet."""

from __future__ import annotations

import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.tune.rollout import scenario_of
from cekm_swarm.tune.scenarios import (
    KINDS,
    SEED_BASE,
    WIDE_KINDS,
    navigation_raw,
    navigation_scenario,
    seed_of,
    tracking_scenario,
)


def test_every_kind_parses_over_many_seeds():
    seen = set()
    for i in range(40):
        sc = navigation_scenario(seed_of("train", i))
        seen.add(sc.name.split("-")[1])
        assert sc.robots[0].goal == "goal"
    assert seen == set(KINDS)
    for kind in KINDS:
        assert navigation_scenario(5, kind).name.startswith(f"gen-{kind}")


def test_the_wide_mix_draws_its_own_kinds_too_and_they_are_what_they_say():
    seen = set()
    for i in range(60):
        sc = navigation_scenario(seed_of("train", i), mix="wide")
        seen.add(sc.name.split("-")[1])  # a narrow deep U is named as every U
    assert seen == set(KINDS) | {"gaps", "wall"} and set(WIDE_KINDS) == seen | {"u-narrow"}
    gaps = navigation_raw(9, "gaps")["obstacles"]
    ys = sorted(o["center"][1] for o in gaps)
    assert 3 <= len(gaps) <= 4 and all(0.085 <= b - a - 0.1 <= 0.13 + 1e-3 for a, b in zip(ys, ys[1:], strict=False))
    u = navigation_raw(9, "u-narrow")["obstacles"][0]
    assert 0.15 <= u["width"] <= 0.4 and 0.12 <= u["depth"] <= 0.3
    wall = navigation_raw(9, "wall")
    (gx, gy), (_, ay), (bx, by) = wall["targets"][0]["position"], wall["walls"][0]["a"], wall["walls"][0]["b"]
    assert gx > bx and gy < ay == by < wall["robots"][0]["start"][1]  # the goal beyond the wall's end, behind it
    alcove = navigation_raw(9, "alcove")
    (x, _), (_, d), (gx, gy) = alcove["walls"][0]["a"], alcove["walls"][0]["b"], alcove["targets"][0]["position"]
    assert 0.12 <= 3.0 - x <= 0.2 and x < gx < 3.0 and gy < d  # the goal inside the corner's alcove
    assert {navigation_raw(i, mix="route")["name"].split("-")[1] for i in range(60)} == set(KINDS) | {
        "gaps", "wall", "alcove"}
    kinds = [navigation_raw(i, mix="movers")["name"].split("-")[1] for i in range(300)]
    assert set(kinds) == set(KINDS) | {"gaps", "wall"} and 0.25 < kinds.count("movers") / 300 < 0.42  # a third
    facings = [navigation_raw(i, "u-turned")["obstacles"][0]["facing"] for i in range(60)]
    for i in range(300):  # the robot and the goal clear of the U whichever way it is turned: every one parses
        navigation_scenario(1_000_000 + i, "u-turned")
    assert min(facings) < -2.0 and max(facings) > 2.0 and any(abs(f) < 1.0 for f in facings)  # every way
    assert scenario_of("navigation", ("mix", "wide", 9))[0].name == navigation_scenario(9, mix="wide").name
    with pytest.raises(ParameterError, match="unknown geometry mix"):
        navigation_raw(9, mix="maze")


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
