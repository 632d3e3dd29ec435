"""Section 4.2 over several seeds: running Figs. 8, 10, 11 and 12's scenarios for the
cooperative EKM and the command-fusion baseline, and judging each run.

Success is judged per scenario as the paper's figures show it:

* ``concave``, ``doorway``, ``lone_obstacle``: the robot reaches (stops at) the goal;
* ``rooms``: reaches the goal without touching the moving obstacles;
* ``checkpoints``: passes every checkpoint, then stops at the goal.

A run is *collision-free* when it also never touched a wall or an obstacle. The summary
over the seeds is :mod:`.obstacle_stats`', the pictures :mod:`.obstacle_figures`', the
files :mod:`.obstacle_report`'s.
"""

from __future__ import annotations

from pathlib import Path

from ..models.io import load_model
from .engine import default_workers, run_jobs
from .field_widths import REPRODUCTION
from .navigation_run import run_scenario
from .obstacle_stats import summarize

SUITE: dict[str, tuple[str, ...]] = {
    "concave": ("cekm", "fusion"),
    "doorway": ("cekm", "fusion"),
    "rooms": ("cekm", "fusion"),
    "checkpoints": ("cekm",),
    "lone_obstacle": ("cekm", "fusion"),
}
FIGURE = {"concave": 8, "doorway": 10, "rooms": 11, "checkpoints": 12, "lone_obstacle": None}


def success(scenario: str, outcome: dict, geometry: dict) -> bool:
    """Did this run do what the paper's figure shows?"""
    if not outcome["reached"]:
        return False
    if scenario == "rooms":
        moving = {m["id"] for m in geometry.get("moving_obstacles", [])}
        touched = outcome.get("collisions_with", {})
        return not any(any(f"({mid})" in item for mid in moving) for item in touched)
    if scenario == "checkpoints":
        return outcome["checkpoints_reached"] == len(outcome["checkpoints"])
    return True


def _one(args):
    scenario, controller, seed, max_time, model_path, keep, speed_unit, fields = args
    from world import load_scenario  # noqa: PLC0415 -- lazy: pymunk, world

    overrides = None if speed_unit is None else {"plant.speed_unit": speed_unit}
    run = run_scenario(load_scenario(scenario, overrides=overrides), controller, load_model(model_path), seed,
                       max_time, fields=fields if controller == "cekm" else None)
    o = next(iter(run.outcome.values()))
    ok = success(scenario, o, run.geometry)
    row = {"scenario": scenario, "controller": controller, "seed": seed, "success": ok,
           "collision_free": ok and o["collisions"] == 0,
           **{k: o[k] for k in ("reached", "time_s", "path_length_m", "collisions", "collisions_with",
                                "min_clearance_m", "checkpoints_reached")},
           "checkpoints": len(o["checkpoints"])}
    return row, (run if keep else None)


def run_suite(seeds: tuple[int, ...], model_path: Path, max_time: float = 300.0, workers: int | None = None,
              scenarios: dict[str, tuple[str, ...]] | None = None, progress: bool = True,
              speed_unit: float | None = None, fields: str = REPRODUCTION):
    """Every (scenario, controller, seed); returns (document, the runs of the first seed for pictures).

    ``speed_unit``: the plant's wheel speed unit for every run (``[plant] speed_unit``;
    0 = continuous speeds); None keeps each scenario's own. ``fields``: cekm's field
    widths (:mod:`.field_widths`; the paper's method, constant ones, unless told)."""
    scenarios = scenarios or SUITE
    jobs = [(s, c, seed, max_time, str(model_path), seed == seeds[0], speed_unit, fields)
            for s, cs in scenarios.items() for c in cs for seed in seeds]
    results = run_jobs(_one, jobs, workers or default_workers(len(jobs), cap=2), desc="obstacle runs",
                       progress=progress)
    rows = [r for r, _ in results]
    pictures = {(r["scenario"], r["controller"]): run for r, run in results if run is not None}
    doc = {"experiment": "obstacles", "paper_section": "4.2", "seeds": list(seeds), "max_time_s": max_time,
           "speed_unit": speed_unit, "fields": fields, "model": str(model_path), "summary": summarize(rows, scenarios),
           "runs": rows}
    return doc, pictures
