"""Fig. 9: the widest concave obstacle the cooperative EKM negotiates, for each depth and
sensing range.

For every (sensing range, depth) the sweep tries the widths in ascending order on several
seeds; a width is negotiated when the robot reaches the goal behind the U on at least
``need`` of the seeds. The cell's answer is the largest negotiated width (the paper's
"maximum obstacle width ... can overcome"); every single run is kept in the JSON.
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
    from .navigation import run_scenario

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
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    with ProcessPoolExecutor(max_workers=workers) as ex:
        runs = list(tqdm(ex.map(_one, jobs), total=len(jobs), disable=not progress, desc="concave sweep", unit="run"))
    grid = []
    for r in config.ranges:
        for d in config.depths:
            ok = []
            for w in config.widths:
                wins = sum(x["reached"] for x in runs if x["range"] == r and x["depth"] == d and x["width"] == w)
                if wins >= config.need:
                    ok.append(w)
            grid.append({"range": r, "depth": d, "max_width": max(ok) if ok else None, "negotiated_widths": ok})
    return {"experiment": "concave-sweep", "paper_figure": 9, "settings": asdict(config), "grid": grid, "runs": runs}


def plot_sweep(doc: dict, path: Path) -> Path:
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


def write_sweep(doc: dict, out_dir: Path) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "fig9.json").write_text(json.dumps(doc, indent=1))
    return [out_dir / "fig9.json", plot_sweep(doc, out_dir / "fig9.png")]


def parse_floats(text: str, name: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ParameterError(f"--{name}: expected comma-separated numbers in metres, got {text!r}") from None
    if not values:
        raise ParameterError(f"--{name}: give at least one value")
    return values


def seeds_of(text: str) -> Sequence[int]:
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ParameterError(f"--seeds: expected comma-separated integers, got {text!r}") from None
