"""The seed-count bootstrap of a tracking grid (`cekm experiment tracking-power`): its
vectorized Welch test equals the one the grid reports, it finds a large effect at few
seeds and none where there is none, it is seeded, and a bad results file is refused
with its name and the field."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from cekm_swarm.cli import main
from cekm_swarm.cli_support import run_cli
from cekm_swarm.errors import ResultsFileError
from cekm_swarm.experiments.grid_power import per_seed_table, seeds_power, welch_p_rows
from cekm_swarm.experiments.metrics import welch_p


def grid_doc(cekm_shift: float, cells: int = 6, seeds: int = 10, seed: int = 0) -> dict:
    """A results document: every controller's A per seed around 0.5, cekm's shifted."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(cells):
        base = rng.uniform(0.45, 0.55, seeds)  # what a scenario does to every controller alike
        ctl = {c: {"per_seed": list(np.clip(base + rng.normal(0.0, 0.05, seeds) + shift, 0.0, 1.0))}
               for c, shift in (("cekm", cekm_shift), ("acmommt", 0.0), ("kmeans", -0.02), ("kmeans-global", 0.1))}
        out.append({"label": f"cell{i}", "controllers": ctl})
    return {"cells": out}


def test_the_rowwise_welch_test_equals_the_grids():
    rng = np.random.default_rng(3)
    a, b = rng.normal(0.5, 0.1, (40, 7)), rng.normal(0.55, 0.2, (40, 7))
    a[0] = 0.4  # a row that does not vary against one that does
    a[1], b[1] = 0.4, 0.4  # neither varies, equal
    a[2], b[2] = 0.4, 0.6  # neither varies, apart
    got = welch_p_rows(a, b)
    want = np.array([welch_p(x, y) for x, y in zip(a, b, strict=True)])
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12)
    assert got[1] == 1.0 and got[2] == 0.0


def test_a_large_effect_is_significant_in_every_cell_and_none_is_not():
    big = seeds_power(grid_doc(0.2), seeds=(10,), reps=50)
    row = next(r for r in big if r["controller"] == "cekm")
    assert row["cells"] == 6 and row["above_mean"] == 6 and row["significant_mean"] == 6
    assert row["all_above"] == 1.0 and row["most_significant"] == 1.0
    same = grid_doc(0.0)
    for cell in same["cells"]:  # cekm exactly A-CMOMMT: never above it, so never significant
        cell["controllers"]["cekm"] = dict(cell["controllers"]["acmommt"])
    none = next(r for r in seeds_power(same, seeds=(10, 40), reps=50) if r["controller"] == "cekm")
    assert none["above_mean"] == 0 and none["significant_mean"] == 0 and none["most_significant"] == 0.0


def test_more_seeds_find_a_small_effect_more_often():
    rows = seeds_power(grid_doc(0.04, cells=10), seeds=(4, 40), reps=200)
    few, many = [r for r in rows if r["controller"] == "cekm"]
    assert few["seeds"] == 4 and many["seeds"] == 40
    assert many["significant_mean"] > few["significant_mean"] + 2
    assert {r["controller"] for r in rows} == {"cekm", "kmeans-global"}


def test_the_bootstrap_is_seeded():
    doc = grid_doc(0.03)
    assert seeds_power(doc, seeds=(8,), reps=30) == seeds_power(doc, seeds=(8,), reps=30)
    assert seeds_power(doc, seeds=(8,), reps=30) != seeds_power(doc, seeds=(8,), reps=30, rng_seed=1)


@pytest.mark.parametrize(
    "doc, words",
    [
        ({}, ["grid.json", "'cells'"]),
        ({"cells": [{"label": "n2", "controllers": {"cekm": {"per_seed": [0.5]}}}]}, ["cell n2", "cekm.per_seed"]),
        (
            {
                "cells": [
                    {
                        "label": "n3",
                        "controllers": {
                            "cekm": {"per_seed": [0.5, 0.6]},
                            "acmommt": {"per_seed": [0.5, 0.6, 0.7]},
                            "kmeans": {"per_seed": [0.5, 0.6]},
                        },
                    }
                ]
            },
            ["cell n3", "numbers of seeds"],
        ),
        ({"cells": [{"label": "n4"}]}, ["cell n4", "'controllers'"]),
        (
            {"cells": [{"label": "n5", "controllers": {"cekm": {"per_seed": [0.5, "x"]}}}]},
            ["cell n5", "finite numbers"],
        ),
        (
            {"cells": [{"label": "n6", "controllers": {"cekm": {"per_seed": [0.5, None]}}}]},
            ["cell n6", "cekm.per_seed"],
        ),
    ],
)
def test_a_results_file_without_what_the_bootstrap_needs_is_refused_by_name(doc, words):
    with pytest.raises(ResultsFileError) as e:
        per_seed_table(doc, "grid.json")
    assert all(w in str(e.value) for w in words), str(e.value)


def test_the_command_prints_the_table_and_refuses_a_file_that_is_not_json(tmp_path, capsys):
    good = tmp_path / "results.json"
    good.write_text(json.dumps(grid_doc(0.2)))
    r = CliRunner().invoke(main, ["experiment", "tracking-power", str(good), "--seeds", "5,10", "--reps", "20"])
    assert r.exit_code == 0, r.output
    assert "| cekm | 10 | 6.0 | 6.0 (6-6) | 1.00 | 1.00 |" in r.output
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert run_cli(main, ["experiment", "tracking-power", str(bad)]) == 2  # as the cekm command runs it
    err = capsys.readouterr().err
    assert "bad.json" in err and "JSON" in err
    r = CliRunner().invoke(main, ["experiment", "tracking-power", str(good), "--seeds", "1,x"])
    assert r.exit_code == 2 and "--seeds" in r.output
