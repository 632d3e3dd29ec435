"""Running the tracking grid (``cekm experiment tracking --grid``): every controller on
every cell of the design for the same seeds, in parallel (on Dask: :mod:`.engine`), with a
progress bar. The statistics are :mod:`.grid_stats`'s, the pictures :mod:`.grid_figures`',
the files :mod:`.grid_report`'s and the command :mod:`.commands`'."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..models.io import load_model
from .engine import run_jobs
from .grid_design import Cell, grid_scenario
from .tracking_run import run_tracking

GRID_CONTROLLERS = ("cekm", "acmommt", "kmeans", "kmeans-global")
PARTS = 6
"""A run's ticks are cut into this many equal parts, and A is also kept per part
(``A_parts``): where in the run a controller gains or loses (the first part is mostly
finding the targets, the last ones holding them)."""
BASELINES = ("acmommt", "kmeans")
"""The baselines cekm must beat in every cell; ``kmeans-global`` (every target known) is the
centralized upper baseline, compared honestly but apart."""

_MODELS: dict[str, Any] = {}


def run_one(job: tuple) -> dict[str, Any]:
    """One run of the grid: (cell, seed, controller, duration, model path, params) -> its row."""
    cell, seed, controller, duration, model_path, tparams = job

    model = None
    if controller == "cekm":  # one load per process
        model = _MODELS.get(model_path) or _MODELS.setdefault(model_path, load_model(model_path))
    run = run_tracking(grid_scenario(cell, seed), controller, model, seed, duration,
                       tparams=tparams if controller == "cekm" else None)
    return {"cell": cell.label, "seed": seed, "controller": controller, "A": run.tracking["A"],
            "A_parts": a_parts(run.tracking["series"]["A"]), "collisions": int(sum(run.collisions.values()))}


def a_parts(per_tick: list[float], parts: int = PARTS) -> list[float] | None:
    """Parker's A over each of ``parts`` equal runs of consecutive ticks (the first parts
    one tick longer when the ticks do not divide evenly); None for a run of fewer ticks
    than parts."""
    if len(per_tick) < parts:
        return None
    return [float(np.mean(chunk)) for chunk in np.array_split(np.asarray(per_tick, dtype=float), parts)]


def run_grid(cells: list[Cell], seeds: list[int], duration: float, model_path, workers: int | None = None,
             progress: bool = True, controllers: tuple[str, ...] = GRID_CONTROLLERS,
             tparams=None) -> list[dict[str, Any]]:
    """Every controller on every cell for every seed; the rows in job order (the same for
    any number of workers). ``tparams``: cekm's TrackingParams (None: the defaults)."""
    # the largest teams first, so the workers do not end on one long run
    jobs = [(c, s, ctl, duration, str(model_path), tparams) for c in sorted(cells, key=lambda c: -c.robots * c.targets)
            for s in seeds for ctl in controllers]
    return run_jobs(run_one, jobs, workers, desc="tracking grid", progress=progress)
