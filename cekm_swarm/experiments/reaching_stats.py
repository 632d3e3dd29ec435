"""Section 4.1's statistics: one run's results document (per network, every index's mean
± std over trials, learning and eps curves, Welch t-tests between networks), the paper's
headline orderings checked on it, and the summary over master seeds.

Over master seeds: per seed and network the trial mean is taken; across seeds the mean of
those and a Student-t 95 % interval (K - 1 degrees of freedom). Targets ended by the step
budget are listed trial by trial, never averaged away.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..models.networks import parameter_count, parse_network_name
from .metrics import mean_std, welch_p

if TYPE_CHECKING:
    from .reaching_config import NetworkRun, TargetReachingConfig

INDICES = ("E_mm", "T_s_per_m", "D", "P5", "T5_s_per_m", "D5")
SUMMARY_INDICES = INDICES + ("ended_by_budget", "goal_stops")


def _after_training(run: NetworkRun, i5: int) -> dict[str, list[float]]:
    """Per-trial values of every index at the last test point."""
    last = [s[-1] for s in run.scores]
    return {
        "E_mm": [s.E_mm for s in last],
        "T_s_per_m": [s.T_s_per_m for s in last],
        "D": [s.D for s in last],
        "P5": [float(s.P[i5]) for s in last],
        "T5_s_per_m": [float(s.T_eps[i5]) for s in last],
        "D5": [float(s.D_eps[i5]) for s in last],
        "ended_by_budget": [float(s.ended_by_budget) for s in last],
        "goal_stops": [float(s.goal_stops) for s in last],
    }


def summarize(runs: Sequence[NetworkRun], config: TargetReachingConfig) -> dict:
    """The results.json document."""
    i5 = list(config.eps_mm).index(5.0)
    per_trial = {r.name: _after_training(r, i5) for r in runs}
    networks = {}
    for r in runs:
        kind, size = parse_network_name(r.name)
        entry = {"kind": kind, "lattice": size, "parameters": parameter_count(kind, size)}
        entry.update({k: mean_std(v) for k, v in per_trial[r.name].items()})
        entry["per_trial"] = per_trial[r.name]
        curves: dict[str, Any] = {"steps": config.schedule.test_points}
        pick = {"E_mm": lambda s: s.E_mm, "T_s_per_m": lambda s: s.T_s_per_m, "D": lambda s: s.D,
                "P5": lambda s: float(s.P[i5]), "T5_s_per_m": lambda s: float(s.T_eps[i5])}
        for key, get in pick.items():
            m = np.array([[get(s) for s in trial] for trial in r.scores])
            with warnings.catch_warnings():  # T5 is NaN at a test point where no target was reached
                warnings.simplefilter("ignore", RuntimeWarning)
                curves[key] = {"mean": np.nanmean(m, axis=0).tolist(),
                               "std": np.nanstd(m, axis=0, ddof=1).tolist() if len(m) > 1 else [0.0] * m.shape[1],
                               "per_trial": m.tolist()}
        curves["ended_by_budget"] = [[s.ended_by_budget for s in trial] for trial in r.scores]
        entry["learning_curves"] = curves
        last = [s[-1] for s in r.scores]
        entry["eps_curves"] = {
            "eps_mm": list(config.eps_mm),
            "P": _stack_mean_std([s.P for s in last]),
            "T_s_per_m": _stack_mean_std([s.T_eps for s in last]),
            "D": _stack_mean_std([s.D_eps for s in last]),
        }
        entry["seconds"] = round(r.seconds, 3)
        networks[r.name] = entry
    t_tests = {}
    for key in INDICES:
        t_tests[key] = {f"{a}|{b}": welch_p(per_trial[a][key], per_trial[b][key])
                        for a, b in itertools.combinations([r.name for r in runs], 2)}
    return {"experiment": "target-reaching", "paper_section": "4.1", "settings": config.settings(),
            "networks": networks, "t_tests": t_tests}


def _stack_mean_std(rows: list[np.ndarray]) -> dict:
    m = np.array(rows, dtype=np.float64)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(m, axis=0)
        std = np.nanstd(m, axis=0, ddof=1) if len(m) > 1 else np.zeros(m.shape[1])
    return {"mean": [None if not np.isfinite(x) else float(x) for x in mean],
            "std": [None if not np.isfinite(x) else float(x) for x in std]}


def headline_orderings(results: dict) -> dict[str, bool | None]:
    """The paper's headline claims, checked on these results (None when a network is missing)."""
    n = results["networks"]

    def m(name, key):
        return n[name][key]["mean"] if name in n and n[name][key]["mean"] is not None else None

    out: dict[str, bool | None] = {}
    for key in ("E_mm", "D"):
        if "R15" in n:
            others = [m(k, key) for k in n if k != "R15"]
            out[f"R15 lowest {key}"] = all(m("R15", key) < o for o in others if o is not None)
    indirect = [k for k in n if k[0] in "GR"]
    for base in ("D15", "B15"):
        for key in ("E_mm", "T_s_per_m"):
            if base in n and indirect:
                out[f"every indirect EKM below {base} in {key}"] = all(m(k, key) < m(base, key) for k in indirect)
    if "D15" in n and indirect:
        out["D15's P5 below every indirect EKM's"] = all(m("D15", "P5") < m(k, "P5") for k in indirect)
    return out


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
