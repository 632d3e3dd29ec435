"""Multi-robot tracking end to end in one process: the Fig. 13 behaviour over 10 seeds,
`cekm run` on a tracking scenario and `cekm experiment tracking`."""

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import stats

from cekm_swarm.cli import main
from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.experiments.tracking_run import run_tracking, team_scenario
from world import load_scenario


@pytest.fixture(scope="module")
def model():
    return default_model()


@pytest.mark.slow
def test_fig13_cekm_observes_more_than_static_robots_and_the_robots_part(model):
    """10 seeds of tracking.toml, 40 s each: cekm's A above stay's (Welch p < 0.05), and
    the robots move apart as the targets do."""
    sc = load_scenario("tracking")
    a = {"cekm": [], "stay": []}
    apart = []
    for seed in range(1, 11):
        for c in a:
            run = run_tracking(sc, c, model, seed, 40.0)
            a[c].append(run.tracking["A"])
            if c == "cekm":
                sp = run.tracking["spread"]
                assert sp["targets_moved_apart_m"] > 0.3  # the scenario does what it says
                apart.append(sp["robots_moved_apart_m"])
    t, p = stats.ttest_ind(a["cekm"], a["stay"], equal_var=False)
    assert np.mean(a["cekm"]) > np.mean(a["stay"]) and p < 0.05, (a, p)
    assert np.mean(apart) > 0.3 and sum(x > 0 for x in apart) >= 8, apart


def test_same_seed_same_run(model):
    sc = load_scenario("tracking-crowd")
    r1, r2 = (run_tracking(sc, "cekm", model, 4, 3.0) for _ in range(2))
    assert r1.tracking == r2.tracking and r1.paths == r2.paths


def test_team_scenarios_grow_with_the_team():
    s2, s8 = team_scenario(2, 1), team_scenario(8, 1)
    assert (len(s2.robots), len(s2.targets)) == (2, 3) and (len(s8.robots), len(s8.targets)) == (8, 12)
    def area(s) -> float:
        return (s.bounds[2] - s.bounds[0]) * (s.bounds[3] - s.bounds[1])

    assert area(s8) / 8 == pytest.approx(area(s2) / 2)


@pytest.mark.slow
@pytest.mark.parametrize("controller", ["cekm", "acmommt", "kmeans", "kmeans-global", "stay"])
def test_cekm_run_tracking_writes_the_tracking_outcome(tmp_path, controller):
    out = tmp_path / controller
    r = CliRunner().invoke(main, ["run", "tracking", "--controller", controller, "--seed", "2", "--max-time", "3",
                                  "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "outcome.json").read_text())
    tr = doc["tracking"]
    assert 0.0 <= tr["A"] <= 1.0 and tr["robots"] == 2 and tr["targets"] == 3
    assert set(tr["A_per_target"]) == {"t1", "t2", "t3"}
    assert len(tr["series"]["A"]) == tr["ticks"] and tr["A"] == pytest.approx(np.mean(tr["series"]["A"]))
    assert {"robots_start", "robots_end", "targets_start", "targets_end"} <= set(tr["spread"])
    assert (out / "trajectory.png").read_bytes()[:4] == b"\x89PNG"


def test_cekm_run_refuses_a_navigation_controller_on_tracking():
    r = CliRunner().invoke(main, ["run", "tracking", "--controller", "fusion", "--out", "/nonexistent/x"])
    assert r.exit_code == 2 and "tracking scenario" in r.output


@pytest.mark.slow
def test_cekm_experiment_tracking_writes_results(tmp_path):
    out = tmp_path / "exp"
    r = CliRunner().invoke(main, ["experiment", "tracking", "--out", str(out), "--seeds", "2", "--robots", "2,3",
                                  "--duration", "4", "--workers", "1", "--quiet"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "results.json").read_text())
    assert [c["robots"] for c in doc["configs"]] == [2, 3]
    for c in doc["configs"]:
        assert set(c["controllers"]) == {"cekm", "acmommt", "kmeans", "kmeans-global", "stay"}
        for v in c["controllers"].values():
            lo, hi = v["A"]["ci95"]
            assert lo <= v["A"]["mean"] <= hi and len(v["per_seed"]) == 2
    for f in ("tables.md", "tracking.png", "fig13_cekm.png", "fig13_acmommt.png", "fig13_kmeans.png",
              "fig13_kmeans-global.png", "fig13_stay.png"):
        assert (out / f).exists(), f
    bad = CliRunner().invoke(main, ["experiment", "tracking", "--out", str(out), "--robots", "two"])
    assert bad.exit_code == 2 and "--robots" in bad.output


def test_cekm_experiment_tracking_honours_first_seed(tmp_path):
    """--first-seed without --grid: the runs are of seeds 7 and 8, and results.json says so."""
    out = tmp_path / "exp"
    r = CliRunner().invoke(main, ["experiment", "tracking", "--out", str(out), "--seeds", "2", "--robots", "2",
                                  "--duration", "1", "--first-seed", "7", "--workers", "1", "--quiet"])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "results.json").read_text())
    assert doc["seeds"] == [7, 8]
    stay = doc["configs"][0]["controllers"]["stay"]["per_seed"]
    assert stay == [run_tracking(team_scenario(2, s), "stay", None, s, 1.0).tracking["A"] for s in (7, 8)]
    assert (out / "fig13_cekm.png").exists()


def test_intervals_of_a_stay_within_0_and_1():
    """Two seeds far apart: the t interval (t = 12.7) would be [-4.13, 4.87]; A is a fraction."""
    from cekm_swarm.experiments.tracking_stats import mean_ci95

    s = mean_ci95([0.0, 0.75])
    assert s["ci95"] == [0.0, 1.0] and s["mean"] == 0.375 and s["n"] == 2
    narrow = mean_ci95([0.5, 0.52, 0.48])  # inside [0, 1]: unchanged
    assert 0.0 < narrow["ci95"][0] < 0.5 < narrow["ci95"][1] < 1.0
    assert mean_ci95([0.98, 1.0, 1.0])["ci95"][1] == 1.0 and mean_ci95([0.0, 0.0, 0.02])["ci95"][0] == 0.0


def test_tables_compare_cekm_with_each_baseline_by_welch_p_and_seeds():
    """The p-values and seed counts the docs quote come from the command's tables.md."""
    from cekm_swarm.experiments.tracking_report import table_markdown
    from cekm_swarm.experiments.tracking_run import CONTROLLERS

    def ctl(per_seed):
        return {"A": {"mean": sum(per_seed) / len(per_seed), "ci95": [0.0, 1.0], "n": len(per_seed)},
                "per_seed": per_seed}

    seeds = {c: [0.5, 0.6, 0.7] for c in CONTROLLERS}
    seeds["cekm"], seeds["acmommt"] = [0.9, 0.8, 0.95], [0.2, 0.3, 0.85]
    doc = {"configs": [{"robots": 2, "targets": 3, "controllers": {c: ctl(v) for c, v in seeds.items()}}]}
    header, _, row = table_markdown(doc).splitlines()
    assert "cekm vs acmommt (Welch p; seeds cekm higher)" in header
    cells = [c.strip() for c in row.strip("|").split("|")]
    from scipy import stats

    p = stats.ttest_ind(seeds["cekm"], seeds["acmommt"], equal_var=False).pvalue
    assert cells[-3] == f"p = {p:.2g}; 3 of 3"  # acmommt
    assert cells[-2].endswith("; 3 of 3") and cells[-1].endswith("; 3 of 3")  # kmeans, kmeans-global
