"""Section 4.1 over several independent master seeds: each network's mean with a 95 %
interval, and how often each of the paper's headline orderings holds.

One master seed is one whole run of :func:`run_experiment` (its trials, targets, noise and
initial maps all derive from it), so K master seeds are K independent draws of the
experiment. Per seed and network the trial mean is taken; across seeds the mean of those
and a Student-t 95 % interval (K - 1 degrees of freedom). Targets ended by the step budget
are listed trial by trial, never averaged away.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable

import numpy as np

from .report import headline_orderings, write_seeds_report
from .target_reaching import INDICES, NetworkRun, TargetReachingConfig, run_experiment

SUMMARY_INDICES = INDICES + ("ended_by_budget", "goal_stops")


def seeds_from(first: int, count: int) -> list[int]:
    """The master seeds of a K-seed run: first, first + 1, ..., first + count - 1."""
    return [first + i for i in range(count)]


def interval95(values) -> dict:
    """{"mean", "lo", "hi", "n"}: the mean of per-seed values and its two-sided Student-t 95 %
    interval (lo = hi = mean for a single seed; None where no value is finite)."""
    from scipy import stats

    a = np.asarray([v for v in values if v is not None], dtype=np.float64)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {"mean": None, "lo": None, "hi": None, "n": 0}
    m = float(a.mean())
    if a.size == 1:
        return {"mean": m, "lo": m, "hi": m, "n": 1}
    half = float(stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return {"mean": m, "lo": m - half, "hi": m + half, "n": int(a.size)}


def budget_ended_trials(results: dict) -> list[dict]:
    """Every (network, trial) whose final test had targets ended by the step budget."""
    out = []
    for name, e in results["networks"].items():
        for t, n in enumerate(e["per_trial"]["ended_by_budget"]):
            if n > 0:
                out.append({"network": name, "trial": t + 1, "targets": int(n),
                            "E_mm": e["per_trial"]["E_mm"][t]})
    return out


def summarize_seeds(per_seed: dict[int, dict]) -> dict:
    """The summary document over master seeds from each seed's results document."""
    seeds = sorted(per_seed)
    names = list(per_seed[seeds[0]]["networks"])
    networks = {}
    for name in names:
        entry = {}
        for key in SUMMARY_INDICES:
            vals = [per_seed[s]["networks"][name].get(key, {}).get("mean") for s in seeds]
            entry[key] = interval95(vals) | {"per_seed": vals}
        networks[name] = entry
    orderings: dict[str, dict] = {}
    for s in seeds:
        for claim, holds in headline_orderings(per_seed[s]).items():
            o = orderings.setdefault(claim, {"holds": 0, "seeds": len(seeds), "fails_in": []})
            if holds:
                o["holds"] += 1
            else:
                o["fails_in"].append(s)
    budget = {str(s): budget_ended_trials(per_seed[s]) for s in seeds}
    first = per_seed[seeds[0]]["settings"]
    settings = {k: v for k, v in first.items() if k != "seed"} | {"master_seeds": seeds}
    return {"experiment": "target-reaching", "paper_section": "4.1", "settings": settings, "networks": networks,
            "orderings": orderings, "budget_ended": budget,
            "wall_seconds": round(sum(per_seed[s].get("wall_seconds", 0.0) for s in seeds), 3)}


def run_master_seeds(config: TargetReachingConfig, count: int, progress: bool = True,
                     on_seed: Callable[[int, dict, list[NetworkRun]], None] | None = None) -> tuple[dict, dict[int, dict]]:
    """Run the experiment once per master seed (config.seed, config.seed + 1, ...).

    ``on_seed(seed, results, runs)`` is called after each seed (to write its report).
    Returns (summary document, results document per seed).
    """
    per_seed = {}
    for s in seeds_from(config.seed, count):
        results, runs = run_experiment(dataclasses.replace(config, seed=s), progress=progress)
        per_seed[s] = results
        if on_seed:
            on_seed(s, results, runs)
    return summarize_seeds(per_seed), per_seed


def _write_seed(config: TargetReachingConfig, results: dict, runs: list[NetworkRun], out_dir: Path,
                models: bool) -> list[Path]:
    """One seed's report: with models, also the trained models and the figures (a single-seed
    run); without (one seed of several), results.json and tables.md only."""
    import json

    from ..models.io import save_model
    from .report import tables_markdown, write_report

    if not models:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "results.json").write_text(json.dumps(results, indent=1))
        (out_dir / "tables.md").write_text(tables_markdown(results))
        return [out_dir / "results.json", out_dir / "tables.md"]
    if models:
        for r in runs:
            for t in range(config.trials):
                save_model(out_dir / "models" / f"{r.name}-trial{t + 1}.npz", r.trained(t, config),
                           {"network": r.name, "trial": t + 1, "steps": config.schedule.steps, "seed": config.seed,
                            "initial_M": "random", "experiment": "target-reaching"})
    return write_report(results, {r.name: r.trained(0, config) for r in runs}, out_dir)


def run_and_report(config: TargetReachingConfig, out_dir: Path, master_seeds: int = 1, progress: bool = True,
                   echo: Callable[[str], None] = print) -> None:
    """``cekm experiment target-reaching``: one master seed into out_dir (with the trained
    models), or several, each into out_dir/seed-S, and their summary into out_dir."""
    from .report import headline_orderings

    out_dir = Path(out_dir)
    if master_seeds == 1:
        results, runs = run_experiment(config, progress=progress)
        written = _write_seed(config, results, runs, out_dir, models=True)
        echo((out_dir / "tables.md").read_text().split("### Table 2")[0].rstrip())
        echo("")
        for claim, holds in headline_orderings(results).items():
            echo(f"  {'holds' if holds else 'DOES NOT HOLD'}: {claim}")
        echo(f"\n{results['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in written))
        return

    def on_seed(seed: int, results: dict, runs: list[NetworkRun]) -> None:
        _write_seed(dataclasses.replace(config, seed=seed), results, runs, out_dir / f"seed-{seed}", models=False)
        holds = sum(bool(v) for v in headline_orderings(results).values())
        echo(f"master seed {seed}: {results['wall_seconds']:.1f} s, {holds} of {len(headline_orderings(results))} "
             f"headline orderings hold; wrote {out_dir / f'seed-{seed}'}")

    summary, _ = run_master_seeds(config, master_seeds, progress, on_seed)
    written = write_seeds_report(summary, out_dir)
    echo("")
    echo(written[1].read_text().rstrip())
    echo(f"\n{summary['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in written))
