"""The tracking grid: its design covers every level pair, its scenarios are valid and the
same for the same seed, and `cekm experiment tracking --grid --quick` writes every output."""

import itertools
import json
import math

import pytest
from click.testing import CliRunner

from cekm_swarm.cli import main
from cekm_swarm.experiments.grid_design import AXES, LEVELS, QUICK, Cell, arena_side, design, grid_raw, grid_scenario
from cekm_swarm.robot import KHEPERA


def test_the_default_design_has_every_team_size_and_density_and_every_level_pair():
    cells = design()
    assert design() == cells  # the same cells every time
    assert {(c.robots, c.targets_per_robot) for c in cells} == set(itertools.product(LEVELS["robots"],
                                                                                      LEVELS["targets_per_robot"]))
    for a, b in itertools.combinations(AXES, 2):
        seen = {(getattr(c, a), getattr(c, b)) for c in cells}
        assert seen == set(itertools.product(LEVELS[a], LEVELS[b])), (a, b)


def test_a_generated_scenario_is_valid_for_its_seed_and_the_same_every_time():
    cell = Cell(6, 1.5, "fast", 0.35, True)
    raw = grid_raw(cell, 7)
    assert grid_raw(cell, 7) == raw and grid_raw(cell, 8) != raw
    sc = grid_scenario(cell, 7)  # the scenario parser's checks pass
    side = arena_side(6)
    assert sc.bounds == (0.0, 0.0, round(side, 4), round(side, 4)) and sc.target_range == 0.35
    assert len(sc.robots) == 6 and len(sc.targets) == 9 and len(sc.obstacles) == 3
    speed = {t["motion"]["speed"] for t in raw["targets"]}
    assert speed == {round(0.7 * KHEPERA.v_max, 5)}
    starts = [r["start"][:2] for r in raw["robots"]]
    for p, q in itertools.combinations(starts, 2):
        assert math.dist(p, q) >= 2 * KHEPERA.body_radius + 0.12
    for o in raw["obstacles"]:
        for p in starts:
            assert math.dist(p, o["center"]) > KHEPERA.body_radius
    assert not grid_raw(Cell(6, 1.5, "fast", 0.35, False), 7)["obstacles"]


def test_the_arena_grows_so_the_robot_density_is_the_same():
    def area(n: int) -> float:
        return arena_side(n) ** 2

    assert math.isclose(area(16) / 16, area(2) / 2) and arena_side(2) == 2.0


@pytest.mark.slow  # it asks git for the commit (a process) and runs the quick grid
def test_cekm_experiment_tracking_grid_quick_writes_every_cell_and_the_heatmaps(tmp_path):
    out = tmp_path / "grid"
    r = CliRunner().invoke(main, ["experiment", "tracking", "--grid", "--quick", "--seeds", "2", "--duration", "3",
                                  "--workers", "1", "--quiet", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "results.json").read_text())
    assert len(doc["cells"]) == len(design(QUICK)) and doc["seeds"] == [1, 2]
    assert doc["commit"] is None or len(doc["commit"]) == 40
    for c in doc["cells"]:
        assert set(c["controllers"]) == {"cekm", "acmommt", "kmeans", "kmeans-global"}
        for v in c["controllers"].values():
            assert len(v["per_seed"]) == 2 and all(0.0 <= a <= 1.0 for a in v["per_seed"])
        best = c["cekm_vs_best"]
        means = {k: c["controllers"][k]["A"]["mean"] for k in ("acmommt", "kmeans")}
        assert best["best_baseline"] == max(means, key=means.get)
        assert math.isclose(best["diff"], c["controllers"]["cekm"]["A"]["mean"] - max(means.values()))
        assert set(best["p_paired_each"]) == {"acmommt", "kmeans"}
        oracle = c["global_vs_best"]  # the same bar for global K-means
        assert math.isclose(oracle["diff"], c["controllers"]["kmeans-global"]["A"]["mean"] - max(means.values()))
        assert oracle["above_all"] == (oracle["diff"] > 0)
    assert len(doc["by_pair"]) == 10 and set(doc["by_axis"]) == set(AXES)
    assert (out / "grid.png").read_bytes()[:4] == b"\x89PNG" and "| robots |" in (out / "tables.md").read_text()
    # A over the run: six parts of 0.5 s, each controller's pooled over every cell and seed
    parts = doc["by_part"]
    assert parts["parts"][0] == [0.0, 0.5] and parts["parts"][-1] == [2.5, 3.0]
    assert set(parts["controllers"]) == {"cekm", "acmommt", "kmeans", "kmeans-global"}
    assert all(v[k]["n"] == 2 * len(doc["cells"]) for v in parts["controllers"].values() for k in range(6))
    assert (out / "parts.png").read_bytes()[:4] == b"\x89PNG" and "| part (s) |" in (out / "tables.md").read_text()
    # the seed-count bootstrap reads the grid's own results.json
    power = CliRunner().invoke(main, ["experiment", "tracking-power", str(out / "results.json"), "--seeds", "2,4",
                                      "--reps", "20"])
    assert power.exit_code == 0, power.output
    assert "| cekm | 4 |" in power.output and "| kmeans-global | 2 |" in power.output
    bad = CliRunner().invoke(main, ["experiment", "tracking", "--quick", "--out", str(tmp_path / "x")])
    assert bad.exit_code == 2 and "--grid" in bad.output
    assert doc["cekm_params"] == {}
    # --param: cekm's TrackingParams for this run, recorded; the baselines' runs are the same
    out2 = tmp_path / "grid2"
    r = CliRunner().invoke(main, ["experiment", "tracking", "--grid", "--quick", "--seeds", "2", "--duration", "3",
                                  "--workers", "1", "--quiet", "--param", "assign_radius=0", "--param",
                                  "search_weight=2", "--out", str(out2)])
    assert r.exit_code == 0, r.output
    doc2 = json.loads((out2 / "results.json").read_text())
    assert doc2["cekm_params"] == {"assign_radius": 0.0, "search_weight": 2.0}
    pairs = list(zip(doc["cells"], doc2["cells"], strict=True))
    assert any(a["controllers"]["cekm"]["per_seed"] != b["controllers"]["cekm"]["per_seed"] for a, b in pairs)
    assert all(a["controllers"][k]["per_seed"] == b["controllers"][k]["per_seed"]
               for a, b in pairs for k in ("acmommt", "kmeans", "kmeans-global"))


def test_param_overrides_are_typed_by_the_field_and_refused_by_name():
    from cekm_swarm.errors import ParameterError
    from cekm_swarm.experiments.commands import parse_cekm_params

    assert parse_cekm_params(()) == {}
    assert parse_cekm_params(("assign_lead_s=0.5", "assign_min = 2")) == {"assign_lead_s": 0.5, "assign_min": 2}
    for bad, words in ((("nope=1",), "no such field"), (("assign_min=1.5",), "expected int"),
                       (("assign_lead_s",), "NAME=VALUE"), (("assign_lead_s=-1",), "assign_lead_s"),
                       (("standoff=0.5", "standoff=0.6"), "given twice"), (("standoff=x",), "expected float")):
        with pytest.raises(ParameterError, match=words):
            parse_cekm_params(bad)


@pytest.mark.slow  # runs git
def test_the_results_commit_is_dirty_for_changed_code_not_for_their_own_directory(tmp_path):
    import subprocess

    from cekm_swarm.experiments.grid_report import git_commit

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "results.json").write_text("{}")
    (tmp_path / "code.py").write_text("x = 1\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "c")
    assert git_commit(where=tmp_path)["dirty"] is False
    (tmp_path / "out" / "results.json").unlink()  # a rerun over the committed results
    assert git_commit(where=tmp_path)["dirty"] is True
    assert git_commit(ignore=tmp_path / "out", where=tmp_path)["dirty"] is False
    (tmp_path / "code.py").write_text("x = 2\n")
    assert git_commit(ignore=tmp_path / "out", where=tmp_path)["dirty"] is True


def test_a_over_the_run_is_split_into_equal_parts_whose_weighted_mean_is_a():
    from cekm_swarm.experiments.grid_run import a_parts

    ticks = [0.0, 0.0, 1.0, 1.0, 0.5, 0.5, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]  # 13 ticks: parts of 3, 2, 2, 2, 2, 2
    parts = a_parts(ticks)
    assert parts == [1 / 3, 0.75, 0.75, 0.0, 0.5, 1.0]
    assert math.isclose((3 * parts[0] + 2 * sum(parts[1:])) / 13, sum(ticks) / 13)
    assert a_parts(ticks[:5]) is None  # fewer ticks than parts


def test_a_over_the_run_pools_every_cell_and_seed_and_compares_cekm_with_each_controller():
    from cekm_swarm.experiments.grid_stats import by_part

    rows = [{"controller": c, "A_parts": [a + 0.01 * k for k in range(6)]}
            for c, values in (("cekm", (0.6, 0.62, 0.64)), ("acmommt", (0.4, 0.42, 0.44))) for a in values]
    doc = by_part(rows, ("cekm", "acmommt"), 60.0)
    assert doc["parts"] == [[0.0, 10.0], [10.0, 20.0], [20.0, 30.0], [30.0, 40.0], [40.0, 50.0], [50.0, 60.0]]
    assert math.isclose(doc["controllers"]["cekm"][2]["mean"], 0.64) and doc["controllers"]["acmommt"][0]["n"] == 3
    assert all(math.isclose(d["diff"], 0.2) for d in doc["cekm_minus"]["acmommt"])
    assert all(0.0 < d["p"] < 0.05 for d in doc["cekm_minus"]["acmommt"])
    assert by_part([{"controller": "cekm", "A_parts": None}], ("cekm",), 1.0)["parts"] == []


def test_the_paired_test_pairs_trials_and_is_stronger_when_scenarios_differ():
    from cekm_swarm.experiments.metrics import paired_p, welch_p

    hard_easy = [0.2, 0.8, 0.3, 0.9, 0.5]  # scenarios of very different difficulty
    better = [a + 0.03 + 0.002 * i for i, a in enumerate(hard_easy)]  # a little better on every one
    assert paired_p(better, hard_easy) < 0.001 < 0.5 < welch_p(better, hard_easy)
    assert paired_p([0.5, 0.5], [0.5, 0.5]) == 1.0 and paired_p([0.6, 0.6], [0.5, 0.5]) == 0.0
    assert paired_p([0.5], [0.4]) is None


def test_the_summary_counts_cells_above_both_baselines_and_holds_global_kmeans_to_the_same_bar():
    from cekm_swarm.experiments.grid_report import cells_above, summary

    def versus(above, p_a, p_k, key="cekm_above_all"):
        return {
            key: above,
            "p_each": {"acmommt": p_a, "kmeans": p_k},
            "p_paired_each": {"acmommt": p_a / 2, "kmeans": p_k / 2},
        }

    doc = {
        "cells": [
            {
                "label": "a",
                "cekm_vs_best": versus(True, 0.01, 0.02),
                "global_vs_best": versus(True, 0.2, 0.01, "above_all"),
            },
            {
                "label": "b",
                "cekm_vs_best": versus(True, 0.01, 0.08),
                "global_vs_best": versus(True, 0.01, 0.01, "above_all"),
            },
            {
                "label": "c",
                "cekm_vs_best": versus(False, 0.01, 0.01),
                "global_vs_best": versus(False, 0.01, 0.01, "above_all"),
            },
        ]
    }
    assert cells_above(doc) == ["a", "b"] and cells_above(doc, test="p_each") == ["a"]
    assert cells_above(doc, test="p_paired_each") == ["a", "b"]  # 0.04 paired in b
    assert cells_above(doc, "global_vs_best", "p_each") == ["b"]
    assert summary(doc) == ("cekm above both baselines in 2 of 3 cells, significantly (Welch p < 0.05 against each) in "
                            "1, "
                            "by a paired test in 2; by the same bar global K-means is above both in 2, significantly "
                            "in 1")


_HASH_PROBE = """
from cekm_swarm.experiments.grid_design import design, grid_scenario
from cekm_swarm.experiments.tracking_run import run_tracking
from cekm_swarm.experiments.default_model import default_model
cell = next(c for c in design() if c.label == "n12-m3-fast-R0.35-obst")
run = run_tracking(grid_scenario(cell, 8), "cekm", default_model(progress=False), 8, 12.0)
print(repr(sorted((r, p[-1]) for r, p in run.paths.items())))
"""


@pytest.mark.slow  # two processes, 12 s of a 12-robot run each
def test_a_run_does_not_depend_on_the_process_string_hashes():
    """The grid's workers are processes with their own PYTHONHASHSEED: a sum over a set of
    target ids (the assignment's led centroid summed a frozenset) took its order from the
    hashes, and this run's robot r12 got a command 1e-16 apart at tick 72 and a different A
    in one run of 1,120 from one grid to the next. Every pose must be equal bit for bit."""
    import os
    import subprocess
    import sys

    out = {}
    for h in ("0", "9"):  # 9 gave the other order before the fix
        env = dict(os.environ, PYTHONHASHSEED=h)
        out[h] = subprocess.run([sys.executable, "-c", _HASH_PROBE], env=env, capture_output=True, text=True,
                                check=True).stdout
    assert out["0"] and out["0"] == out["9"]


@pytest.mark.slow  # a pool of worker processes
def test_the_grid_gives_the_same_rows_with_one_worker_or_two():
    """Which worker runs a job, and what it ran before, must not change a row."""
    from cekm_swarm.experiments.default_model import default_model, default_model_path
    from cekm_swarm.experiments.grid_run import run_grid

    cells = design(QUICK)
    default_model(progress=False)  # trained and cached on first use
    path = default_model_path()
    one = run_grid(cells, [1, 2], 4.0, path, workers=1, progress=False)
    two = run_grid(cells, [1, 2], 4.0, path, workers=2, progress=False)
    assert len(one) == 4 * len(cells) * 2 and one == two


def test_the_grid_sizes_the_quick_look_the_reference_and_refuses_what_contradicts_them(tmp_path):
    from cekm_swarm.experiments.grid_report import grid_size

    assert grid_size(False, False, None, None) == (10, 60.0)  # the quick look
    assert grid_size(False, True, None, None) == (40, 120.0)  # the reference grid
    assert grid_size(True, False, None, None) == (2, 8.0)
    assert grid_size(False, False, 5, 30.0) == (5, 30.0)
    for contradiction in [(True, True, None, None), (False, True, 12, None), (False, True, None, 9.0)]:
        with pytest.raises(ValueError, match="--reference"):
            grid_size(*contradiction)
    out = CliRunner().invoke(main, ["experiment", "tracking", "--reference", "--out", str(tmp_path / "r")])
    assert out.exit_code == 2 and "--reference goes with --grid" in out.output
    out = CliRunner().invoke(main, ["experiment", "tracking", "--grid", "--reference", "--seeds", "12",
                                    "--out", str(tmp_path / "r")])
    assert out.exit_code == 2 and "leave out --seeds" in out.output and not (tmp_path / "r").exists()
