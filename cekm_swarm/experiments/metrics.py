"""Performance indices of section 4.1 (Eqs. 18-20) and their epsilon versions.

E (Eq. 18): mean distance from the robot's centre to the target after the robot stops
(:mod:`.stopping`) or its step budget runs out; how many targets ended by the budget, and how
many by a stop at the goal state (the sensed distance 0), are counted. T (Eq. 19): time to target over straight-line
distance, s/m. D (Eq. 20): |path length - straight distance| / straight distance.
P(eps), T(eps), D(eps): "reached" means first coming within eps, with or without stopping;
T(eps) and D(eps) average over the targets reached.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .trial import TestOutcome


@dataclass(frozen=True)
class TestScore:
    """One test's indices (means over its targets)."""

    E_mm: float
    T_s_per_m: float
    D: float
    ended_by_budget: int
    P: np.ndarray  # per eps
    T_eps: np.ndarray  # s/m per eps (NaN where none reached)
    D_eps: np.ndarray
    goal_stops: int = 0  # targets ended by a stop with the sensed distance 0 (the goal state)


def _mean_or_nan(x: np.ndarray) -> float:
    return float(np.mean(x)) if x.size else math.nan


def score(o: TestOutcome, step_s: float) -> TestScore:
    """The indices of one test from its per-target outcomes."""
    t = o.steps * step_s
    n_eps = o.t_eps.shape[1]
    reached = ~np.isnan(o.t_eps)
    T_eps = np.array([_mean_or_nan(o.t_eps[reached[:, e], e] / o.straight[reached[:, e]]) for e in range(n_eps)])
    D_eps = np.array([_mean_or_nan(np.abs(o.path_eps[reached[:, e], e] - o.straight[reached[:, e]])
                                   / o.straight[reached[:, e]]) for e in range(n_eps)])
    return TestScore(
        E_mm=float(np.mean(o.final_dist) * 1000.0),
        T_s_per_m=float(np.mean(t / o.straight)),
        D=float(np.mean(np.abs(o.path - o.straight) / o.straight)),
        ended_by_budget=int(np.sum(~o.stopped)),
        P=reached.mean(axis=0),
        T_eps=T_eps,
        D_eps=D_eps,
        goal_stops=int(np.sum(o.at_goal)) if o.at_goal is not None else 0,
    )


def mean_std(values) -> dict:
    """{"mean", "std"} over trials (sample std, ddof = 1, as the paper's +-), NaNs ignored."""
    a = np.asarray(values, dtype=np.float64)
    a = a[~np.isnan(a)]
    if a.size == 0:
        return {"mean": None, "std": None}
    return {"mean": float(a.mean()), "std": float(a.std(ddof=1)) if a.size > 1 else 0.0}


def welch_p(a, b) -> float | None:
    """Two-sided Welch t-test p-value between two sets of trial means; None when undefined."""
    from scipy import stats

    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a, b = a[~np.isnan(a)], b[~np.isnan(b)]
    if a.size < 2 or b.size < 2:
        return None
    if np.ptp(a) == 0 and np.ptp(b) == 0:
        return 1.0 if a[0] == b[0] else 0.0

    with warnings.catch_warnings():  # near-identical samples: scipy warns, the p-value is still right
        warnings.simplefilter("ignore", RuntimeWarning)
        p = stats.ttest_ind(a, b, equal_var=False).pvalue
    return None if not np.isfinite(p) else float(p)


def paired_p(a, b) -> float | None:
    """Two-sided paired t-test p-value between two controllers' results on the same trials
    (a[i] and b[i] on the same scenario and seed); None when undefined."""
    from scipy import stats

    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    d = d[~np.isnan(d)]
    if d.size < 2:
        return None
    if np.ptp(d) == 0:
        return 1.0 if d[0] == 0 else 0.0
    p = stats.ttest_1samp(d, 0.0).pvalue
    return None if not np.isfinite(p) else float(p)
