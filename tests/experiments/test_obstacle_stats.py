"""The statistics of the section 4.2 experiments: Wilson intervals, per-cell success
rates of the Fig. 9 grid, holes below the widest negotiated width, seed lists."""

import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.commands import seeds_of
from cekm_swarm.experiments.concave_run import SweepConfig
from cekm_swarm.experiments.concave_stats import cells_of, grid_of
from cekm_swarm.experiments.obstacle_stats import summarize, wilson_interval


def test_wilson_interval():
    lo, hi = wilson_interval(20, 20)
    assert hi == 1.0 and lo == pytest.approx(0.8389, abs=1e-3)  # 20/20 does not prove 100 %
    lo, hi = wilson_interval(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-3)
    lo, hi = wilson_interval(10, 20)
    assert lo == pytest.approx(0.2993, abs=1e-3) and hi == pytest.approx(0.7007, abs=1e-3)


def test_seeds_accept_lists_and_ranges():
    assert seeds_of("1-5") == (1, 2, 3, 4, 5)
    assert seeds_of("1-3,9, 11") == (1, 2, 3, 9, 11)
    with pytest.raises(ParameterError, match="backwards"):
        seeds_of("5-1")
    for bad in ("a", "1-x", "-3"):
        with pytest.raises(ParameterError, match="--seeds"):
            seeds_of(bad)


def _run(r, d, w, s, ok):
    return {"range": r, "depth": d, "width": w, "seed": s, "reached": ok}


def test_grid_cells_and_holes():
    cfg = SweepConfig(depths=(0.18,), widths=(0.2, 0.5, 1.0), ranges=(0.17,), seeds=(1, 2), need=2)
    runs = [_run(0.17, 0.18, 0.2, 1, False), _run(0.17, 0.18, 0.2, 2, True),
            _run(0.17, 0.18, 0.5, 1, True), _run(0.17, 0.18, 0.5, 2, True),
            _run(0.17, 0.18, 1.0, 1, True), _run(0.17, 0.18, 1.0, 2, True)]
    cells = cells_of(cfg, runs)
    assert [(c["width"], c["reached"], c["of"], c["rate"]) for c in cells] == [(0.2, 1, 2, 0.5), (0.5, 2, 2, 1.0),
                                                                              (1.0, 2, 2, 1.0)]
    (g,) = grid_of(cfg, runs)
    assert g["max_width"] == 1.0 and g["negotiated_widths"] == [0.5, 1.0]
    assert g["max_width_no_hole"] is None  # the narrowest U already traps it: a hole below the widest


def test_summary_counts_contacts_and_collision_free_successes():
    rows = [{"scenario": "rooms", "controller": "cekm", "success": True, "collision_free": True, "collisions": 0,
             "min_clearance_m": 0.01},
            {"scenario": "rooms", "controller": "cekm", "success": True, "collision_free": False, "collisions": 3,
             "min_clearance_m": -0.0004},
            {"scenario": "rooms", "controller": "cekm", "success": False, "collision_free": False, "collisions": 1,
             "min_clearance_m": 0.002}]
    t = summarize(rows, {"rooms": ("cekm",)})["rooms"]["cekm"]
    assert (t["success"], t["collision_free"], t["of"], t["contacts"], t["runs_with_contact"]) == (2, 1, 3, 4, 2)
    assert t["min_clearance_m"] == -0.0004
    assert t["success_ci95"] == list(wilson_interval(2, 3))


def test_summary_clearance_skips_runs_with_nothing_in_range():
    row = {"scenario": "rooms", "controller": "cekm", "success": True, "collision_free": True, "collisions": 0}
    both = [row | {"min_clearance_m": None}, row | {"min_clearance_m": 0.02}]
    assert summarize(both, {"rooms": ("cekm",)})["rooms"]["cekm"]["min_clearance_m"] == 0.02
    none = summarize([row | {"min_clearance_m": None}], {"rooms": ("cekm",)})["rooms"]["cekm"]
    assert none["min_clearance_m"] is None
