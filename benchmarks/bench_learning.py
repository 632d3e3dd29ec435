"""Training throughput of the section 4.1 learning loop and the full default experiment.

Measures, in one run:
* the baseline: the readable reference implementation (numpy networks, Python loop),
  robot-steps per second of training for R15;
* the fast path (numba), one thread and all threads, robot-steps per second of training
  only, for every network of the paper, batch of 5 trials;
* the full default run (`cekm experiment target-reaching`: 6 networks x 5 trials x
  100,000 steps plus all test phases under the paper's stop rule, where a network that does
  not stop uses each test target's whole 500-step budget) as a separate process: wall time
  and peak resident memory, once with numba's cache cold (first run after install) and once
  warm.

Goals (issue 2): full default run under 60 s, training at >= 500,000 robot-steps/s,
peak memory under 2 GB; with --master-seeds 5 (issue 12), the five-seed run under 5 minutes.
Run: python benchmarks/bench_learning.py [--skip-full] [--master-seeds K]
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

GOAL_FULL_S, GOAL_RATE, GOAL_MEM_GB = 60.0, 500_000, 2.0


def _batch(name: str, trials: int, steps: int, seed: int = 1):
    from cekm_swarm.experiments import trial
    from cekm_swarm.experiments.arena import Arena
    from cekm_swarm.experiments.streams import Schedule, TrialStreams
    from cekm_swarm.models import fast
    from cekm_swarm.models.networks import BFN_WIDTH_FLOOR, make_network

    arena = Arena()
    streams = [TrialStreams(seed, t, arena, Schedule(steps=steps, test_interval=steps)) for t in range(trials)]
    nets = [make_network(name, s.init_rng(), bfn_rule="paper") for s in streams]  # the default run's B15
    arrays = [fast.network_arrays(n) for n in nets]
    batch = trial.NetworkBatch(
        nets[0].kind,
        nets[0].lattice.size,
        *(np.stack([a[q] for a in arrays]) for q in range(3)),
        fast.pack_params(nets[0].comp, nets[0].learn_p, arena.v_max, BFN_WIDTH_FLOOR, "paper"),
    )
    return batch, streams, nets


def train_rate_fast(name: str, trials: int = 5, steps: int = 20_000) -> float:
    """Robot-steps of training per second (noise generation included, tests excluded)."""
    from cekm_swarm.experiments import trial
    from cekm_swarm.experiments.stopping import GOAL_STOP
    from cekm_swarm.experiments.streams import batch_train_chunk

    batch, streams, _ = _batch(name, trials, steps)
    arena = streams[0].arena
    poses = np.tile(np.array([*arena.centre, 0.0]), (trials, 1))
    cursors = np.zeros((trials, 4), dtype=np.int64)
    targets = np.stack([s.train_targets for s in streams])
    t0 = time.perf_counter()
    wheel, sense, explore = batch_train_chunk(streams, 0, steps)
    trial._train_batch(batch.code, batch.size, batch.W, batch.P, batch.R, batch.params, arena.vector(), poses, cursors,
                       targets, 0, wheel, sense, explore, streams[0].schedule.train_budget, GOAL_STOP.code)
    return trials * steps / (time.perf_counter() - t0)


def train_rate_reference(name: str = "R15", steps: int = 1_500) -> float:
    from cekm_swarm.experiments import trial

    _, streams, nets = _batch(name, 1, steps)
    pose = np.array([*streams[0].arena.centre, 0.0])
    t0 = time.perf_counter()
    trial.train_reference(nets[0], pose, [0, 0], streams[0], 0, 0, steps)
    return steps / (time.perf_counter() - t0)


def full_run(out: Path, master_seeds: int = 1) -> tuple[float, float]:
    """Wall seconds and peak RSS (GB) of the default experiment in a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "cekm_swarm", "experiment", "target-reaching", "--out", str(out), "--quiet",
                    "--master-seeds", str(master_seeds)], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    peak_kb = max(before, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    return wall, peak_kb / 1024 / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-full", action="store_true", help="skip the two full default runs (about 1-2 min)")
    ap.add_argument("--master-seeds", type=int, default=1, help="full runs over K master seeds (goal: K x 60 s, "
                                                                  "5 minutes for 5)")
    args = ap.parse_args()
    import numba

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, numba {numba.__version__}, "
          f"{numba.get_num_threads()} threads")
    train_rate_fast("G9", trials=2, steps=200)  # compile (or load the cache) before timing
    for n in ("B15", "D15", "R15"):
        train_rate_fast(n, trials=2, steps=200)
    ref = train_rate_reference()
    print(f"\nbaseline: reference numpy R15, 1 robot: {ref:,.0f} robot-steps/s of training")
    print(f"\n{'network':8} {'1 thread':>14} {'all threads':>14} {'x baseline':>11}")
    rates = {}
    for name in ("B15", "D15", "G9", "G12", "G15", "R15"):
        numba.set_num_threads(1)
        one = train_rate_fast(name)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        rates[name] = train_rate_fast(name)
        print(f"{name:8} {one:>14,.0f} {rates[name]:>14,.0f} {rates[name] / ref:>10.0f}x")
    ekm = np.mean([rates[n] for n in ("G9", "G12", "G15", "R15")])
    print(f"indirect EKMs, mean: {ekm:,.0f} robot-steps/s (goal {GOAL_RATE:,}: "
          f"{'met' if ekm >= GOAL_RATE else 'NOT met'})")
    if args.skip_full:
        return
    cache = Path(__import__("cekm_swarm").__file__).parent
    with tempfile.TemporaryDirectory() as tmp:
        for label, cold in (("cold numba cache", True), ("warm numba cache", False)):
            if cold:
                for p in list(cache.rglob("*.nbi")) + list(cache.rglob("*.nbc")):
                    p.unlink()
            wall, mem = full_run(Path(tmp) / label.replace(" ", "-"), args.master_seeds)
            goal = GOAL_FULL_S * args.master_seeds
            ok = wall < goal and mem < GOAL_MEM_GB
            print(f"full default run, {args.master_seeds} master seed(s) ({label}): {wall:.1f} s, peak RSS {mem:.2f} "
                  "GB "
                  f"(goals < {goal:.0f} s, < {GOAL_MEM_GB:.0f} GB: {'met' if ok else 'NOT met'}); "
                  f"x baseline: the reference would need ~{3.0e6 / ref / 3600:.1f} h for the training alone")
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
