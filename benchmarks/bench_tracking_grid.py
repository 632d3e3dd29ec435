"""Tracking grid speed: the default `cekm experiment tracking --grid` (28 cells, seeds 1-10,
60 s of sim time per run, cekm, A-CMOMMT, K-means and global K-means; one worker per core).

Goal (issue 19): under 15 minutes on 2 cores. Baseline, measured in the same run: one
60-s run of the grid's largest cell (16 robots, 48 targets) with A-CMOMMT, so the ratio
says how many such runs the grid costs; the host's load moves both.

Run: python benchmarks/bench_tracking_grid.py [--seeds N] [--workers W]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

GOAL_S = 900.0


def main() -> None:
    ap = argparse.ArgumentParser()
    from cekm_swarm.experiments.grid_report import DEFAULT_SEEDS

    ap.add_argument("--seeds", type=int, default=DEFAULT_SEEDS[1] - DEFAULT_SEEDS[0] + 1)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.grid_design import Cell, grid_scenario
    from cekm_swarm.experiments.tracking_run import run_tracking

    default_model()
    sc = grid_scenario(Cell(16, 3.0, "fast", 0.5, False), 1)
    run_tracking(sc, "acmommt", None, 1, 2.0)  # warm
    t0 = time.perf_counter()
    run_tracking(sc, "acmommt", None, 1, 60.0)
    base = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "cekm_swarm", "experiment", "tracking", "--grid", "--out", out,
                        "--overwrite", "--seeds", str(args.seeds), "--workers", str(args.workers), "--quiet"],
                       check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
    print(f"baseline: one 60-s run of the 16-robot, 48-target cell with A-CMOMMT: {base:.2f} s")
    print(f"cekm experiment tracking --grid ({args.seeds} seeds, {args.workers} workers): {wall:.1f} s "
          f"= {wall / base:.0f}x the baseline run; goal < {GOAL_S:.0f} s: {'met' if wall < GOAL_S else 'NOT met'}")


if __name__ == "__main__":
    main()
