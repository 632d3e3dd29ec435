"""Section 4.2 over several seeds: Figs. 8, 10, 11 and 12 for the cooperative EKM and the
command-fusion baseline, with every per-seed outcome and the pictures side by side.

Success is judged per scenario as the paper's figures show it:

* ``concave``, ``doorway``, ``lone_obstacle``: the robot reaches (stops at) the goal;
* ``rooms``: reaches the goal without touching the moving obstacles;
* ``checkpoints``: passes every checkpoint, then stops at the goal.
"""

from __future__ import annotations

import json
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


def _one(args):
    scenario, controller, seed, max_time, model_path, keep = args
    from world import load_scenario

    from ..models.io import load_model
    from .navigation import run_scenario

    run = run_scenario(load_scenario(scenario), controller, load_model(model_path), seed, max_time)
    o = next(iter(run.outcome.values()))
    row = {"scenario": scenario, "controller": controller, "seed": seed, "success": success(scenario, o, run.geometry),
           **{k: o[k] for k in ("reached", "time_s", "path_length_m", "collisions", "collisions_with",
                                "min_clearance_m", "checkpoints_reached")},
           "checkpoints": len(o["checkpoints"])}
    return row, (run if keep else None)


def run_suite(seeds: tuple[int, ...], model_path: Path, max_time: float = 300.0, workers: int | None = None,
              scenarios: dict[str, tuple[str, ...]] | None = None, progress: bool = True):
    """Every (scenario, controller, seed); returns (document, the runs of the first seed for pictures)."""
    from tqdm import tqdm

    scenarios = scenarios or SUITE
    jobs = [(s, c, seed, max_time, str(model_path), seed == seeds[0]) for s, cs in scenarios.items() for c in cs
            for seed in seeds]
    with ProcessPoolExecutor(max_workers=workers or min(len(jobs), os.cpu_count() or 1)) as ex:
        results = list(tqdm(ex.map(_one, jobs), total=len(jobs), disable=not progress, desc="obstacle runs",
                            unit="run"))
    rows = [r for r, _ in results]
    pictures = {(r["scenario"], r["controller"]): run for r, run in results if run is not None}
    summary = {}
    for s, cs in scenarios.items():
        summary[s] = {c: {"success": sum(r["success"] for r in rows if r["scenario"] == s and r["controller"] == c),
                          "of": len(seeds)} for c in cs}
    doc = {"experiment": "obstacles", "paper_section": "4.2", "seeds": list(seeds), "max_time_s": max_time,
           "model": str(model_path), "summary": summary, "runs": rows}
    return doc, pictures


def table_markdown(doc: dict) -> str:
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

    from .navigation import plot_run

    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "outcomes.json", out_dir / "table.md"]
    written[0].write_text(json.dumps(doc, indent=1))
    written[1].write_text(table_markdown(doc) + "\n")
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
