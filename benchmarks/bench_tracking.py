"""Tracking experiment speed: the default run of `cekm experiment tracking` (team sizes
2, 4, 8; seeds 1-10; 60 s of sim time per run; every controller; one worker per core).

Goal (issue 10): under 5 minutes on 2 cores. Baseline, measured in the same run: one
60-s run of tracking.toml with static robots (`stay`: the world, sensing, messages and
metric with no controller work), to show what the world itself costs; the ratio is the
whole experiment's wall time over that one run's.

Run: python benchmarks/bench_tracking.py [--seeds N]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time

GOAL_S = 300.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    args = ap.parse_args()
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.tracking_run import run_tracking
    from world import load_scenario

    model = default_model()
    sc = load_scenario("tracking")
    run_tracking(sc, "cekm", model, 1, 2.0)  # compile
    t0 = time.perf_counter()
    run_tracking(sc, "stay", model, 1, 60.0)
    base = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "cekm_swarm", "experiment", "tracking", "--out", out, "--seeds",
                        str(args.seeds), "--quiet"], check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
    print(f"baseline: one 60-s tracking.toml run with static robots: {base:.2f} s")
    print(f"cekm experiment tracking (sizes 2,4,8; {args.seeds} seeds; 60 s; 5 controllers): {wall:.1f} s "
          f"= {wall / base:.0f}x the baseline run; goal < {GOAL_S:.0f} s: {'met' if wall < GOAL_S else 'NOT met'}")


if __name__ == "__main__":
    main()
