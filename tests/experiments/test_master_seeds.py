"""Section 4.1 over several master seeds: intervals, ordering counts, the CLI."""

import json

import pytest
from click.testing import CliRunner

from cekm_swarm.cli import main
from cekm_swarm.experiments.reaching_run import seeds_from
from cekm_swarm.experiments.reaching_stats import budget_ended_trials, interval95, summarize_seeds


def test_interval95_is_the_student_t_interval():
    iv = interval95([1.0, 2.0, 3.0])
    # mean 2, s = 1, t(0.975, 2) = 4.302653, half = 4.302653 / sqrt(3) = 2.484138
    assert iv["mean"] == pytest.approx(2.0)
    assert iv["lo"] == pytest.approx(2.0 - 2.484138, abs=1e-6) and iv["hi"] == pytest.approx(2.0 + 2.484138, abs=1e-6)
    assert interval95([5.0]) == {"mean": 5.0, "lo": 5.0, "hi": 5.0, "n": 1}
    assert interval95([None, float("nan")])["mean"] is None


def _doc(seed, e_r15, e_d15, budget_r15=(0, 0)):
    def net(e, budget):
        entry = {k: {"mean": e, "std": 0.0} for k in ("E_mm", "T_s_per_m", "D", "P5", "T5_s_per_m", "D5")}
        entry["ended_by_budget"] = {"mean": sum(budget) / len(budget), "std": 0.0}
        entry["per_trial"] = {"E_mm": [e] * len(budget), "ended_by_budget": list(budget)}
        return entry

    return {"settings": {"seed": seed, "trials": 2, "schedule": {}, "arena": {}},
            "networks": {"D15": net(e_d15, (0, 0)), "R15": net(e_r15, budget_r15)}, "wall_seconds": 1.0}


def test_orderings_are_counted_per_seed_and_budget_trials_listed():
    per_seed = {1: _doc(1, 1.0, 2.0), 2: _doc(2, 3.0, 2.0, budget_r15=(0, 4)), 3: _doc(3, 1.0, 2.0)}
    s = summarize_seeds(per_seed)
    assert s["orderings"]["R15 lowest E_mm"] == {"holds": 2, "seeds": 3, "fails_in": [2]}
    assert s["networks"]["R15"]["E_mm"]["per_seed"] == [1.0, 3.0, 1.0]
    assert s["budget_ended"]["2"] == [{"network": "R15", "trial": 2, "targets": 4, "E_mm": 3.0}]
    assert budget_ended_trials(per_seed[1]) == []
    assert s["settings"]["master_seeds"] == [1, 2, 3]
    assert seeds_from(2005, 3) == [2005, 2006, 2007]


@pytest.mark.slow
def test_cli_master_seeds_writes_each_seed_and_the_summary(tmp_path):
    out = tmp_path / "ms"
    r = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(out), "--networks", "R9,D9",
                                  "--trials", "2", "--steps", "400", "--test-interval", "200", "--targets", "3",
                                  "--master-seeds", "2", "--seed", "11", "--quiet"])
    assert r.exit_code == 0, r.output
    for seed in (11, 12):
        assert (out / f"seed-{seed}" / "results.json").is_file() and (out / f"seed-{seed}" / "tables.md").is_file()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["settings"]["master_seeds"] == [11, 12]
    assert summary["settings"]["arena"]["speed_unit"] == 0.0  # continuous by default
    per_seed = [json.loads((out / f"seed-{s}" / "results.json").read_text())["networks"]["R9"]["E_mm"]["mean"]
                for s in (11, 12)]
    assert summary["networks"]["R9"]["E_mm"]["per_seed"] == per_seed
    assert "95 % interval" in (out / "summary.md").read_text()


def test_cli_refuses_a_bad_speed_unit(tmp_path):
    r = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(tmp_path), "--speed-unit", "0.5"])
    assert r.exit_code == 2 and "speed_unit" in r.output
