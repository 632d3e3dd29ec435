"""The tracking experiment's statistics over team sizes: per team size and controller,
Parker's A per seed and its mean with a 95 % t interval (clipped to [0, 1]). The runs are
:mod:`.tracking_run`'s."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def mean_ci95(xs: list[float]) -> dict[str, Any]:
    """Mean of Parker's A and its 95 % t interval, clipped to [0, 1]: A is a fraction, and
    with few seeds the t interval (mean +- t * s / sqrt(n)) reaches past 0 or 1 (two seeds:
    t = 12.7). The mean and the per-seed values are unclipped."""
    from scipy import stats

    a = np.asarray(xs, dtype=float)
    m = float(a.mean())
    if len(a) < 2:
        return {"mean": m, "ci95": [m, m], "n": len(a)}
    h = float(stats.t.ppf(0.975, len(a) - 1) * a.std(ddof=1) / math.sqrt(len(a)))
    return {"mean": m, "ci95": [max(0.0, m - h), min(1.0, m + h)], "n": len(a)}


def team_stats(rows: list[dict[str, Any]], sizes: tuple[int, ...],
               controllers: tuple[str, ...]) -> list[dict[str, Any]]:
    """Per team size (in ``sizes``' order): its targets and, per controller, A's mean and
    95 % interval over the seeds with the value of every seed."""
    configs = []
    for n in sizes:
        sub = [r for r in rows if r["robots"] == n]
        conf: dict[str, Any] = {"robots": n, "targets": sub[0]["targets"], "controllers": {}}
        for c in controllers:
            a = [r["A"] for r in sub if r["controller"] == c]
            conf["controllers"][c] = {"A": mean_ci95(a), "per_seed": a}
        configs.append(conf)
    return configs
