"""The target-reaching experiment of section 4.1 (Tables 1-4, Figures 5-7): its settings
and running it, once or over several master seeds.

Each network is trained for ``steps`` steps in each of ``trials`` trials and tested every
``test_interval`` steps on the trial's fixed 50 targets. Trials run as one numba batch
per network. Every network of a trial sees the same targets and noise. Stop rules
(:mod:`.stopping`) end test targets (the paper's, by default) and training targets (the
goal state, by default, as before).

One master seed is one whole run of :func:`run_experiment` (its trials, targets, noise and
initial maps all derive from it), so K master seeds (:func:`run_master_seeds`) are K
independent draws of the experiment. The statistics are :mod:`.reaching_stats`', the
figures :mod:`.reaching_figures`', the tables and files :mod:`.reaching_report`'s.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np
from tqdm import tqdm

from ..models import fast
from ..models.networks import BFN_WIDTH_FLOOR, make_network, parse_network_name
from .engine import cluster_address, run_jobs
from .metrics import score
from .reaching_config import NetworkRun, TargetReachingConfig
from .reaching_stats import summarize, summarize_seeds
from .streams import TrialStreams
from .trial import NetworkBatch, run_batch


def run_network(name: str, config: TargetReachingConfig,
                on_progress: Callable[[int], None] | None = None) -> NetworkRun:
    """Train and test one network over all trials."""
    streams = [TrialStreams(config.seed, t, config.arena, config.schedule) for t in range(config.trials)]
    nets = [make_network(name, s.init_rng(), config.comp, config.learn_p, config.bfn_rule) for s in streams]
    arrays = [fast.network_arrays(n) for n in nets]
    kind, size = parse_network_name(name)
    params = fast.pack_params(config.comp, config.learn_p, config.arena.v_max, BFN_WIDTH_FLOOR, config.bfn_rule)
    W, P, R = (np.ascontiguousarray(np.stack([a[q] for a in arrays])) for q in range(3))
    batch = NetworkBatch(kind, size, W, P, R, params)
    eps = np.array(config.eps_mm) / 1000.0
    t0 = time.perf_counter()
    outcomes = run_batch(batch, streams, eps, on_progress, config.stop, config.train_stop)
    seconds = time.perf_counter() - t0
    scores = [[score(o, config.arena.step_s) for o in per_trial] for per_trial in outcomes]
    return NetworkRun(name, batch, scores, seconds)


def run_experiment(config: TargetReachingConfig, progress: bool = True) -> tuple[dict, list[NetworkRun]]:
    """Run every network; returns (results document, runs)."""
    total = len(config.networks) * config.trials * config.schedule.steps
    runs = []
    t0 = time.perf_counter()
    with tqdm(total=total, unit="step", unit_scale=True, disable=not progress, desc="training",
              bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} robot-steps [{elapsed}<{remaining}, {rate_fmt}]") as bar:
        for name in config.networks:
            bar.set_description(f"{name} ({config.trials} trials)")
            runs.append(run_network(name, config, lambda n: bar.update(n * config.trials)))
    results = summarize(runs, config)
    results["wall_seconds"] = round(time.perf_counter() - t0, 3)
    return results, runs


def seeds_from(first: int, count: int) -> list[int]:
    """The master seeds of a K-seed run: first, first + 1, ..., first + count - 1."""
    return [first + i for i in range(count)]


def _one_seed(config: TargetReachingConfig) -> tuple[dict, list[NetworkRun]]:
    """One master seed's experiment on an engine's worker (no progress bar of its own)."""
    return run_experiment(config, progress=False)


def run_master_seeds(config: TargetReachingConfig, count: int, progress: bool = True,
                     on_seed: Callable[[int, dict, list[NetworkRun]], None] | None = None,
                     workers: int | None = None) -> tuple[dict, dict[int, dict]]:
    """Run the experiment once per master seed (config.seed, config.seed + 1, ...).

    ``on_seed(seed, results, runs)`` is called after each seed (to write its report).
    Returns (summary document, results document per seed). In this process one seed after
    the other by default (each already trains its trials on every core); with ``workers``
    > 1 or a cluster (:mod:`.engine`) the seeds run side by side, then ``on_seed`` is
    called for each in seed order.
    """
    seeds = seeds_from(config.seed, count)
    per_seed = {}
    if (workers or 1) == 1 and cluster_address() is None:
        for s in seeds:
            results, runs = run_experiment(dataclasses.replace(config, seed=s), progress=progress)
            per_seed[s] = results
            if on_seed:
                on_seed(s, results, runs)
        return summarize_seeds(per_seed), per_seed
    done = run_jobs(_one_seed, [dataclasses.replace(config, seed=s) for s in seeds], workers, desc="master seeds",
                    progress=progress)
    for s, (results, runs) in zip(seeds, done, strict=True):
        per_seed[s] = results
        if on_seed:
            on_seed(s, results, runs)
    return summarize_seeds(per_seed), per_seed
