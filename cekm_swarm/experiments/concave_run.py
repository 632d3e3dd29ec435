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

import math
from dataclasses import asdict, dataclass
from pathlib import Path

from ..errors import ParameterError
from .concave_stats import cells_of, grid_of


@dataclass(frozen=True)
class SweepConfig:
    depths: tuple[float, ...] = (0.06, 0.12, 0.18, 0.24, 0.30)
    widths: tuple[float, ...] = (0.10, 0.20, 0.34, 0.50, 0.70, 1.00, 1.40, 2.00)
    ranges: tuple[float, ...] = (0.12, 0.17, 0.25)
    seeds: tuple[int, ...] = (1, 2, 3)
    need: int = 2  # successes out of len(seeds) for a width to count as negotiated
    max_time: float = 300.0
    scenario: str = "concave"

    def __post_init__(self) -> None:
        for name in ("depths", "widths", "ranges"):
            values = getattr(self, name)
            if not values or not all(math.isfinite(v) and v > 0 for v in values):
                raise ParameterError(f"--{name}: sweep {name} must be positive numbers, got {list(values)}")
        if not self.seeds:
            raise ParameterError("--seeds: give at least one seed")
        if not 1 <= self.need <= len(self.seeds):
            raise ParameterError(f"--need: must be between 1 and the number of --seeds ({len(self.seeds)}), "
                                 f"got {self.need}")

    def check_scenarios(self) -> None:
        """Load the scenario with every (width, depth, range) the sweep will run, so that a
        value the scenario refuses is a :class:`ParameterError` naming its option before any
        worker starts (it was a ScenarioError traceback from a worker)."""
        from world import ScenarioError, load_scenario

        options = {"obstacles[0].width": "--widths", "obstacles[0].depth": "--depths", "sensors.range": "--ranges"}
        for r in self.ranges:
            for d in self.depths:
                for w in self.widths:
                    try:
                        load_scenario(self.scenario, overrides={"obstacles[0].width": w, "obstacles[0].depth": d,
                                                                "sensors.range": r})
                    except ScenarioError as exc:
                        text = str(exc)
                        named = [o for field, o in options.items() if f"{field}:" in text]
                        where = named[0] if len(named) == 1 else "--depths/--widths/--ranges"
                        raise ParameterError(f"{where}: depth {d}, width {w}, range {r}: {text}") from None


def _one(args) -> dict:
    """One run (in a worker process): does the cooperative EKM reach the goal?"""
    scenario, width, depth, rng, seed, max_time, model_path = args
    from world import load_scenario

    from ..models.io import load_model
    from .navigation_run import run_scenario

    sc = load_scenario(scenario, overrides={"obstacles[0].width": width, "obstacles[0].depth": depth,
                                            "sensors.range": rng})
    run = run_scenario(sc, "cekm", load_model(model_path), seed, max_time)
    o = next(iter(run.outcome.values()))
    return {"width": width, "depth": depth, "range": rng, "seed": seed, "reached": o["reached"],
            "time_s": o["time_s"], "collisions": o["collisions"]}


def run_sweep(config: SweepConfig, model_path: Path, workers: int | None = None, progress: bool = True) -> dict:
    """All runs of the sweep, in parallel (on Dask: :mod:`.engine`); returns the fig9.json document."""
    from .engine import default_workers, run_jobs

    jobs = [(config.scenario, w, d, r, s, config.max_time, str(model_path))
            for r in config.ranges for d in config.depths for w in config.widths for s in config.seeds]
    runs = run_jobs(_one, jobs, workers or default_workers(len(jobs), cap=2), desc="concave sweep",
                    progress=progress)
    return {"experiment": "concave-sweep", "paper_figure": 9, "settings": asdict(config),
            "cells": cells_of(config, runs), "grid": grid_of(config, runs), "runs": runs}
