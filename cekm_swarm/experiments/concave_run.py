"""Fig. 9: the widest concave obstacle the cooperative EKM negotiates, for each depth and
sensing range -- the sweep's settings and its runs.

For every (sensing range, depth) the sweep tries every width on several seeds; a width
is negotiated when the robot reaches the goal behind the U on at least ``need`` of the
seeds. fig9.json holds ``cells`` (every cell's successes out of its runs), ``grid`` (per
range and depth: the largest negotiated width, the paper's "maximum obstacle width ...
can overcome", and the largest width with no failing narrower width below it; both
:mod:`.concave_stats`') and every single run. fig9.png draws the paper's curves,
fig9_grid.png every cell (:mod:`.concave_figures`); :mod:`.concave_report` writes them.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from world import load_scenario

from ..models.io import load_model
from .concave_config import SweepConfig
from .concave_stats import cells_of, grid_of
from .engine import default_workers, run_jobs
from .navigation_run import run_scenario


def _one(args) -> dict:
    """One run (in a worker process): does the cooperative EKM reach the goal?"""
    scenario, width, depth, rng, seed, max_time, model_path, fields = args

    sc = load_scenario(scenario, overrides={"obstacles[0].width": width, "obstacles[0].depth": depth,
                                            "sensors.range": rng})
    run = run_scenario(sc, "cekm", load_model(model_path), seed, max_time, fields=fields)
    o = next(iter(run.outcome.values()))
    return {"width": width, "depth": depth, "range": rng, "seed": seed, "reached": o["reached"],
            "time_s": o["time_s"], "collisions": o["collisions"]}


def run_sweep(config: SweepConfig, model_path: Path, workers: int | None = None, progress: bool = True) -> dict:
    """All runs of the sweep, in parallel (on Dask: :mod:`.engine`); returns the fig9.json document."""
    jobs = [(config.scenario, w, d, r, s, config.max_time, str(model_path), config.fields)
            for r in config.ranges for d in config.depths for w in config.widths for s in config.seeds]
    runs = run_jobs(_one, jobs, workers or default_workers(len(jobs), cap=2), desc="concave sweep",
                    progress=progress)
    return {"experiment": "concave-sweep", "paper_figure": 9, "settings": asdict(config),
            "cells": cells_of(config, runs), "grid": grid_of(config, runs), "runs": runs}
