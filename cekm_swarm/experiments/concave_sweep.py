"""Fig. 9: the widest concave obstacle the cooperative EKM negotiates, for each depth and
sensing range, and the success rate of every (range, depth, width) cell.

For every (sensing range, depth) the sweep tries every width on several seeds; a width
is negotiated when the robot reaches the goal behind the U on at least ``need`` of the
seeds. fig9.json holds ``cells`` (every cell's successes out of its runs), ``grid`` (per
range and depth: the largest negotiated width, the paper's "maximum obstacle width ...
can overcome", and the largest width with no failing narrower width below it) and every
single run. fig9.png draws the paper's curves, fig9_grid.png every cell.
"""

from __future__ import annotations

import json
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

from ..errors import ParameterError


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
            if not values or any(v <= 0 for v in values):
                raise ParameterError(f"sweep {name} must be positive numbers, got {list(values)}")
        if not 1 <= self.need <= len(self.seeds):
            raise ParameterError(f"need must be between 1 and the number of seeds ({len(self.seeds)}), got {self.need}")


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
    """All runs of the sweep, in parallel processes; returns the fig9.json document."""
    from tqdm import tqdm

    jobs = [(config.scenario, w, d, r, s, config.max_time, str(model_path))
            for r in config.ranges for d in config.depths for w in config.widths for s in config.seeds]
    workers = workers or min(len(jobs), os.cpu_count() or 1, 2)
    with ProcessPoolExecutor(max_workers=workers) as ex:
        runs = list(tqdm(ex.map(_one, jobs), total=len(jobs), disable=not progress, desc="concave sweep", unit="run"))
    return {"experiment": "concave-sweep", "paper_figure": 9, "settings": asdict(config),
            "cells": cells_of(config, runs), "grid": grid_of(config, runs), "runs": runs}


def cells_of(config: SweepConfig, runs: list[dict]) -> list[dict]:
    """The success rate of every (range, depth, width) cell over the seeds."""
    cells = []
    for r in config.ranges:
        for d in config.depths:
            for w in config.widths:
                mine = [x for x in runs if x["range"] == r and x["depth"] == d and x["width"] == w]
                k = sum(x["reached"] for x in mine)
                cells.append({"range": r, "depth": d, "width": w, "reached": k, "of": len(mine),
                              "rate": k / len(mine) if mine else None})
    return cells


def grid_of(config: SweepConfig, runs: list[dict]) -> list[dict]:
    """Per (range, depth): the widths negotiated (>= ``need`` seeds), the widest of them
    (``max_width``, the paper's reading) and the widest below which every width tried is
    negotiated too (``max_width_no_hole``: a narrower U that traps the robot is a hole)."""
    grid = []
    for r in config.ranges:
        for d in config.depths:
            ok, solid = [], None
            broken = False
            for w in config.widths:
                wins = sum(x["reached"] for x in runs if x["range"] == r and x["depth"] == d and x["width"] == w)
                if wins >= config.need:
                    ok.append(w)
                    if not broken:
                        solid = w
                else:
                    broken = True
            grid.append({"range": r, "depth": d, "max_width": max(ok) if ok else None, "negotiated_widths": ok,
                         "max_width_no_hole": solid})
    return grid


def plot_sweep(doc: dict, path: Path) -> Path:
    """The paper's Fig. 9: the widest negotiated width against depth, one curve per range."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for r in doc["settings"]["ranges"]:
        cells = [c for c in doc["grid"] if c["range"] == r]
        ax.plot([c["depth"] * 100 for c in cells], [(c["max_width"] or 0.0) * 100 for c in cells], "-o",
                label=f"sensing range {r * 100:.0f} cm")
    ax.set_xlabel("obstacle depth (cm)")
    ax.set_ylabel("maximum negotiable width (cm)")
    ax.set_title(f"Fig. 9: widest concave obstacle overcome (>= {doc['settings']['need']} of "
                 f"{len(doc['settings']['seeds'])} seeds; 0 = none)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def plot_grid(doc: dict, path: Path) -> Path:
    """Every cell's success rate: one panel per sensing range, width across, depth down."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    st = doc["settings"]
    widths, depths, ranges = st["widths"], st["depths"], st["ranges"]
    fig, axes = plt.subplots(1, len(ranges), figsize=(4.2 * len(ranges) + 1.0, 3.6), squeeze=False)
    for ax, r in zip(axes[0], ranges):
        z = np.full((len(depths), len(widths)), np.nan)
        for c in doc["cells"]:
            if c["range"] == r and c["rate"] is not None:
                z[depths.index(c["depth"]), widths.index(c["width"])] = c["rate"]
        im = ax.imshow(z, origin="lower", cmap="RdYlGn", vmin=0.0, vmax=1.0, aspect="auto")
        for i in range(len(depths)):
            for j in range(len(widths)):
                cell = next((c for c in doc["cells"] if c["range"] == r and c["depth"] == depths[i]
                             and c["width"] == widths[j]), None)
                if cell is not None:
                    ax.text(j, i, f"{cell['reached']}/{cell['of']}", ha="center", va="center", fontsize=7)
        ax.set_xticks(range(len(widths)), [f"{w * 100:.0f}" for w in widths], fontsize=7)
        ax.set_yticks(range(len(depths)), [f"{d * 100:.0f}" for d in depths], fontsize=7)
        ax.set_xlabel("width (cm)")
        ax.set_ylabel("depth (cm)")
        ax.set_title(f"sensing range {r * 100:.0f} cm", fontsize=9)
    fig.colorbar(im, ax=axes[0].tolist(), fraction=0.03, label="success rate")
    fig.suptitle("Fig. 9 as a grid: runs that reached the goal behind the U, per cell", fontsize=10)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)
    return path


def write_sweep(doc: dict, out_dir: Path) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "fig9.json").write_text(json.dumps(doc, indent=1))
    return [out_dir / "fig9.json", plot_sweep(doc, out_dir / "fig9.png"), plot_grid(doc, out_dir / "fig9_grid.png")]


def parse_floats(text: str, name: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ParameterError(f"--{name}: expected comma-separated numbers in metres, got {text!r}") from None
    if not values:
        raise ParameterError(f"--{name}: give at least one value")
    return values


def seeds_of(text: str) -> Sequence[int]:
    """Seeds from "1,2,5" or ranges "1-20" (inclusive), mixed: "1-5,9"."""
    out: list[int] = []
    for part in (v.strip() for v in text.split(",")):
        if not part:
            continue
        a, _, b = part.partition("-")
        try:
            lo, hi = int(a), int(b if b else a)
        except ValueError:
            raise ParameterError(f"--seeds: expected comma-separated integers or ranges like 1-20, got {text!r}") from None
        if hi < lo:
            raise ParameterError(f"--seeds: range {part!r} runs backwards")
        out.extend(range(lo, hi + 1))
    return tuple(out)
