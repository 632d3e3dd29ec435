"""The tracking grid's files: ``results.json`` (every cell, every seed, the
summaries, the commit), ``tables.md`` and ``grid.png`` (:mod:`.grid_figures`). The command that runs and writes
them is :func:`.commands.run_grid_cmd`."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path
from typing import Any

from .. import jsonfile
from .grid_design import LEVELS, QUICK, design
from .grid_figures import heatmaps, over_the_run
from .grid_run import BASELINES, GRID_CONTROLLERS, run_grid
from .grid_stats import by_axis, by_pair, by_part, cell_stats

DEFAULT_SEEDS = (1, 10)  # held-out seeds 1..10 (docs/tracking.md: why 10); tuning used 1001-1099
DEFAULT_DURATION = 60.0
REFERENCE_SEEDS = 40  # the reference grid (--reference): 40 held-out seeds a cell ...
REFERENCE_DURATION = 120.0  # ... of 120 s each (docs/tracking.md); the default is the quick look
QUICK_SEEDS, QUICK_DURATION = 2, 8.0  # --quick: a small grid (CI)


def grid_size(quick: bool, reference: bool, seeds: int | None, duration: float | None) -> tuple[int, float]:
    """Seeds a cell and sim seconds a run of the tracking grid: the quick look (10 x 60 s) by
    default, the reference grid (40 x 120 s) with ``reference``, a small one with ``quick``;
    ``seeds`` and ``duration`` override either, except the reference, which is what it says."""
    if quick and reference:
        raise ValueError("--quick and --reference: choose one")
    if reference and (seeds is not None or duration is not None):
        raise ValueError("--reference is 40 seeds x 120 s: leave out --seeds and --duration")
    if reference:
        return REFERENCE_SEEDS, REFERENCE_DURATION
    n = seeds if seeds is not None else (QUICK_SEEDS if quick else DEFAULT_SEEDS[1])
    return n, duration if duration is not None else (QUICK_DURATION if quick else DEFAULT_DURATION)


def git_commit(ignore: Path | None = None, where: Path | None = None) -> dict[str, Any]:
    """The checkout's commit and whether it had changes to tracked files (None outside a
    git checkout). Changes under ``ignore`` (the run's own output directory, which a rerun
    over the committed results rewrites) do not count. ``where``: a directory of the
    checkout (default: this package's)."""
    here = where if where is not None else Path(__file__).resolve().parent
    try:
        def git(*args: str) -> str:
            return subprocess.run(["git", *args], cwd=here, capture_output=True, text=True, check=True).stdout

        sha = git("rev-parse", "HEAD").strip()
        top = Path(git("rev-parse", "--show-toplevel").strip())
        status = git("status", "--porcelain", "--untracked-files=no")
        changed = [line[3:].split(" -> ")[-1] for line in status.splitlines()]
    except (OSError, subprocess.CalledProcessError):
        return {"commit": None, "dirty": None}
    if ignore is not None:
        out = Path(ignore).resolve()
        changed = [c for c in changed if not (top / c).resolve().is_relative_to(out)]
    return {"commit": sha, "dirty": bool(changed)}


def grid_doc(quick: bool, seeds: list[int], duration: float, model_path, workers, progress: bool,
             tparams=None, out_dir: Path | None = None) -> dict[str, Any]:
    """Run the grid and summarize it."""
    cells = design(QUICK) if quick else design()
    checkout = git_commit(ignore=out_dir)  # the code that runs: taken before, not after
    t0 = time.perf_counter()
    rows = run_grid(cells, seeds, duration, model_path, workers, progress, GRID_CONTROLLERS, tparams)
    wall = time.perf_counter() - t0
    per_cell = cell_stats(rows, cells, GRID_CONTROLLERS)
    levels = QUICK if quick else LEVELS
    return {"design": "quick" if quick else "default", "levels": {k: list(v) for k, v in levels.items()},
            "seeds": seeds, "duration_s": duration, "controllers": list(GRID_CONTROLLERS), "baselines": list(BASELINES),
            "scenario_rule": "square walled arena of side 2 m * sqrt(n / 2); round(m/n * n) random-walk targets "
                             "(speed a fraction of v* = 0.15625 m/s, turn noise 1 rad/sqrt(s)) and n robots at uniform "
                             "starts; with obstacles round(n / 2) discs and boxes "
                             "(cekm_swarm/experiments/grid_design.py)",
            "wall_seconds": round(wall, 1), "workers": workers, **checkout,
            "cells": per_cell, "by_axis": by_axis(per_cell, GRID_CONTROLLERS),
            "by_pair": by_pair(per_cell, GRID_CONTROLLERS), "by_part": by_part(rows, GRID_CONTROLLERS, duration)}


def cells_above(doc: dict[str, Any], key: str = "cekm_vs_best", test: str | None = None) -> list[str]:
    """The cells where ``key``'s controller (cekm; global K-means for "global_vs_best") is
    above both baselines, and with ``test`` ("p_each": Welch, "p_paired_each": paired)
    significantly (p < 0.05) against each."""
    above = "cekm_above_all" if key == "cekm_vs_best" else "above_all"
    return [d["label"] for d in doc["cells"] if key in d and d[key][above]
            and (test is None or all(p is not None and p < 0.05 for p in d[key][test].values()))]


def summary(doc: dict[str, Any]) -> str:
    """The acceptance's count (above both baselines; significantly, Welch p < 0.05 against
    each), the paired test's, and the same bar for global K-means: what the cells and seeds
    let even a controller that sees every target show."""
    n = len(doc["cells"])
    return (f"cekm above both baselines in {len(cells_above(doc))} of {n} cells, significantly (Welch p < 0.05 "
            f"against each) in {len(cells_above(doc, test='p_each'))}, by a paired test in "
            f"{len(cells_above(doc, test='p_paired_each'))}; by the same bar global K-means is above both in "
            f"{len(cells_above(doc, 'global_vs_best'))}, "
            f"significantly in {len(cells_above(doc, 'global_vs_best', 'p_each'))}")


def _ci(a: dict[str, Any]) -> str:
    return f"{a['mean']:.3f} [{a['ci95'][0]:.3f}, {a['ci95'][1]:.3f}]"


def tables_markdown(doc: dict[str, Any]) -> str:
    """The summary, by every axis (every controller, 95 % intervals), A over the run, then every cell."""
    ctl = doc["controllers"]
    lines = [summary(doc) + ".", ""] if doc["cells"] and "cekm_vs_best" in doc["cells"][0] else []
    for axis, name in (("robots", "robots"), ("speed", "target speed"), ("targets_per_robot", "m/n"),
                       ("target_range", "R (m)"), ("obstacles", "obstacles")):
        lines += [f"| {name} | cells | " + " | ".join(f"A {c}" for c in ctl) + " | cekm - best baseline (Welch p) |",
                  "|---|---:|" + "---:|" * len(ctl) + "---|"]
        for row in doc["by_axis"][axis]:
            v = row.get("cekm_vs_best")
            vs = f"{v['diff']:+.3f} vs {v['best_baseline']} (p = {v['p']:.2g})" if v else ""
            lines.append(f"| {row['level']} | {row['cells']} | " + " | ".join(_ci(row["controllers"][c]) for c in ctl)
                         + f" | {vs} |")
        lines.append("")
    parts = doc.get("by_part", {})
    if parts.get("parts"):
        lines += ["A over the run: every cell and seed pooled, per part of the run's ticks (s of sim time).", "",
                  "| part (s) | " + " | ".join(f"A {c}" for c in parts["controllers"])
                  + " | " + " | ".join(f"cekm - {c}" for c in parts["cekm_minus"]) + " |",
                  "|---|" + "---:|" * (len(parts["controllers"]) + len(parts["cekm_minus"]))]
        for k, (lo, hi) in enumerate(parts["parts"]):
            diffs = (f"{v[k]['diff']:+.3f} (p = {v[k]['p']:.2g})" for v in parts["cekm_minus"].values())
            lines.append(f"| {lo:g}-{hi:g} | " + " | ".join(_ci(v[k]) for v in parts["controllers"].values()) + " | "
                         + " | ".join(diffs) + " |")
        lines.append("")
    lines += ["| cell | " + " | ".join(f"A {c}" for c in ctl)
              + " | cekm - best baseline (Welch p; paired p) | cekm - kmeans-global (p) |",
              "|---|" + "---:|" * len(ctl) + "---|---|"]
    for d in doc["cells"]:
        v, g = d.get("cekm_vs_best"), d.get("cekm_vs_global")
        vs = (f"{v['diff']:+.3f} vs {v['best_baseline']} (p = {v['p']:.2g}; "
              f"{v['p_paired_each'][v['best_baseline']]:.2g})") if v else ""
        gs = f"{g['diff']:+.3f} (p = {g['p']:.2g})" if g else ""
        lines.append(f"| {d['label']} | " + " | ".join(f"{d['controllers'][c]['A']['mean']:.3f}" for c in ctl)
                     + f" | {vs} | {gs} |")
    return "\n".join(lines) + "\n"


def write_grid(doc: dict[str, Any], out_dir) -> list[Path]:
    """results.json, tables.md, grid.png and parts.png (A over the run)."""

    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(jsonfile.dumps(doc))
    (out / "tables.md").write_text(tables_markdown(doc))
    n = len(doc["seeds"])
    fig = heatmaps(doc["by_pair"], f"cekm's A minus the best of A-CMOMMT and local K-means, pooled over the cells "
                                   f"at each level pair ({n} seeds per cell; * Welch p < 0.05)")
    fig.savefig(out / "grid.png", dpi=110)
    plt.close(fig)
    paths = [out / "results.json", out / "tables.md", out / "grid.png"]
    if doc.get("by_part", {}).get("parts"):
        fig = over_the_run(doc["by_part"], f"A over the run: every cell and seed pooled ({len(doc['cells'])} cells, "
                                           f"{n} seeds), 95 % intervals")
        fig.savefig(out / "parts.png", dpi=110)
        plt.close(fig)
        paths.append(out / "parts.png")
    return paths
