"""Section 4.2 over several seeds: Figs. 8, 10, 11 and 12 for the cooperative EKM and the
command-fusion baseline, with every per-seed outcome and the pictures side by side.

Success is judged per scenario as the paper's figures show it:

* ``concave``, ``doorway``, ``lone_obstacle``: the robot reaches (stops at) the goal;
* ``rooms``: reaches the goal without touching the moving obstacles;
* ``checkpoints``: passes every checkpoint, then stops at the goal.

A run is *collision-free* when it also never touched a wall or an obstacle. Each
(scenario, controller) is summarized over the seeds by its success rate and its
collision-free success rate, each with a 95 % Wilson score interval, and the number of
contacts (new contacts with a wall or obstacle, summed over the runs).
"""

from __future__ import annotations

import json
import math
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

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


def wilson_interval(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The 95 % Wilson score interval of a success rate k/n (sound at k = 0 or k = n,
    unlike the normal approximation)."""
    if n <= 0:
        return (0.0, 1.0)
    p = k / n
    den = 1.0 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def _one(args):
    scenario, controller, seed, max_time, model_path, keep, speed_unit = args
    from world import load_scenario

    from ..models.io import load_model
    from .navigation_run import run_scenario

    overrides = None if speed_unit is None else {"plant.speed_unit": speed_unit}
    run = run_scenario(load_scenario(scenario, overrides=overrides), controller, load_model(model_path), seed,
                       max_time)
    o = next(iter(run.outcome.values()))
    ok = success(scenario, o, run.geometry)
    row = {"scenario": scenario, "controller": controller, "seed": seed, "success": ok,
           "collision_free": ok and o["collisions"] == 0,
           **{k: o[k] for k in ("reached", "time_s", "path_length_m", "collisions", "collisions_with",
                                "min_clearance_m", "checkpoints_reached")},
           "checkpoints": len(o["checkpoints"])}
    return row, (run if keep else None)


def summarize(rows: list[dict], scenarios: dict[str, tuple[str, ...]]) -> dict:
    """Per scenario and controller: successes, collision-free successes (each with its 95 %
    Wilson interval), contacts summed over the runs, runs with a contact, the smallest
    clearance."""
    summary: dict = {}
    for s, cs in scenarios.items():
        summary[s] = {}
        for c in cs:
            mine = [r for r in rows if r["scenario"] == s and r["controller"] == c]
            n = len(mine)
            k = sum(r["success"] for r in mine)
            k_free = sum(r["collision_free"] for r in mine)
            summary[s][c] = {"success": k, "of": n, "success_ci95": list(wilson_interval(k, n)),
                             "collision_free": k_free, "collision_free_ci95": list(wilson_interval(k_free, n)),
                             "contacts": sum(r["collisions"] for r in mine),
                             "runs_with_contact": sum(r["collisions"] > 0 for r in mine),
                             "min_clearance_m": min((r["min_clearance_m"] for r in mine), default=math.inf)}
    return summary


def run_suite(seeds: tuple[int, ...], model_path: Path, max_time: float = 300.0, workers: int | None = None,
              scenarios: dict[str, tuple[str, ...]] | None = None, progress: bool = True,
              speed_unit: float | None = None):
    """Every (scenario, controller, seed); returns (document, the runs of the first seed for pictures).

    ``speed_unit``: the plant's wheel speed unit for every run (``[plant] speed_unit``;
    0 = continuous speeds); None keeps each scenario's own."""
    from tqdm import tqdm

    scenarios = scenarios or SUITE
    jobs = [(s, c, seed, max_time, str(model_path), seed == seeds[0], speed_unit) for s, cs in scenarios.items()
            for c in cs for seed in seeds]
    with ProcessPoolExecutor(max_workers=workers or min(len(jobs), os.cpu_count() or 1, 2)) as ex:
        results = list(tqdm(ex.map(_one, jobs), total=len(jobs), disable=not progress, desc="obstacle runs",
                            unit="run"))
    rows = [r for r, _ in results]
    pictures = {(r["scenario"], r["controller"]): run for r, run in results if run is not None}
    doc = {"experiment": "obstacles", "paper_section": "4.2", "seeds": list(seeds), "max_time_s": max_time,
           "speed_unit": speed_unit, "model": str(model_path), "summary": summarize(rows, scenarios), "runs": rows}
    return doc, pictures


def _pct(k: int, n: int, ci: list[float]) -> str:
    return f"{k}/{n} ({100 * ci[0]:.0f}-{100 * ci[1]:.0f} %)"


def summary_markdown(doc: dict) -> str:
    """One row per scenario and controller: success and collision-free success with their
    95 % intervals, contacts, runs with a contact, smallest clearance."""
    lines = ["| scenario | controller | success (95 % CI) | collision-free success (95 % CI) | contacts | "
             "runs with a contact | min clearance (mm) |", "|---|---|---|---|---:|---:|---:|"]
    for s, per in doc["summary"].items():
        fig = FIGURE.get(s)
        name = f"{s} (Fig. {fig})" if fig else s
        for c, t in per.items():
            lines.append(f"| {name} | {c} | {_pct(t['success'], t['of'], t['success_ci95'])} | "
                         f"{_pct(t['collision_free'], t['of'], t['collision_free_ci95'])} | {t['contacts']} | "
                         f"{t['runs_with_contact']} | {1000 * t['min_clearance_m']:.1f} |")
    return "\n".join(lines)


def table_markdown(doc: dict) -> str:
    """Per seed: success, sim time, contacts (and checkpoints passed)."""
    lines = ["| scenario | controller | " + " | ".join(f"seed {s}" for s in doc["seeds"]) + " | success |",
             "|---|---|" + "---|" * (len(doc["seeds"]) + 1)]
    for s, per in doc["summary"].items():
        for c, tally in per.items():
            cells = []
            for seed in doc["seeds"]:
                r = next(x for x in doc["runs"] if x["scenario"] == s and x["controller"] == c and x["seed"] == seed)
                mark = "yes" if r["success"] else "no"
                extra = f", {r['checkpoints_reached']}/{r['checkpoints']} cp" if s == "checkpoints" else ""
                cells.append(f"{mark} {r['time_s']:.0f} s, {r['collisions']} coll.{extra}")
            lines.append(f"| {s} | {c} | " + " | ".join(cells) + f" | {tally['success']}/{tally['of']} |")
    return "\n".join(lines)


def write_suite(doc: dict, pictures: dict, out_dir: Path) -> list[Path]:
    """outcomes.json, table.md and one picture per scenario (controllers side by side)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .navigation_figures import plot_run

    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "outcomes.json", out_dir / "table.md"]
    written[0].write_text(json.dumps(doc, indent=1))
    written[1].write_text(summary_markdown(doc) + "\n\nPer seed:\n\n" + table_markdown(doc) + "\n")
    for s in doc["summary"]:
        runs = [pictures[(s, c)] for c in ("fusion", "cekm") if (s, c) in pictures]
        if not runs:
            continue
        xmin, ymin, xmax, ymax = runs[0].geometry["bounds"]
        aspect = (ymax - ymin) / (xmax - xmin)
        fig, axes = plt.subplots(1, len(runs), figsize=(6.5 * len(runs), max(3.0, 6.5 * aspect) + 0.6), squeeze=False)
        for ax, run, letter in zip(axes[0], runs, "AB"):
            name = "command fusion" if run.controller == "fusion" else "cooperative EKMs"
            plot_run(run, ax=ax, title=f"({letter}) {name}, seed {run.seed}")
        fig_no = FIGURE[s]
        fig.suptitle(f"Fig. {fig_no}: {s}" if fig_no else s)
        fig.tight_layout()
        path = out_dir / (f"fig{fig_no}_{s}.png" if fig_no else f"{s}.png")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
