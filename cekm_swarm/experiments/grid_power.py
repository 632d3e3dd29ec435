"""How many seeds a tracking grid needs (``cekm experiment tracking-power``): from a
grid's ``results.json``, a bootstrap of what the same grid with N seeds a cell would show.

Each replicate draws N seeds a cell, with replacement, from the seeds the grid ran, the
same seeds for every controller (so a scenario's effect on all of them stays paired, as
in the grid), and counts the cells where a controller's mean A is above both baselines
and where it is also Welch-significant (p < 0.05) against each: the acceptance's bar.
It answers whether a result is short of seeds or short of effect: a cell whose effect is
nil stays unsignificant at any N. Resampling a few observed seeds understates the tails;
the counts are an estimate, not a promise.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ParameterError, ResultsFileError
from .grid_run import BASELINES


def per_seed_table(doc: dict[str, Any], source: str = "results.json") -> tuple[list[str], list[dict[str, np.ndarray]]]:
    """The cells' labels and, per cell, {controller: A per seed} (seed-aligned arrays) of a
    grid's results document; a missing field or unequal seed counts name the cell."""
    cells = doc.get("cells")
    if not isinstance(cells, list) or not cells:
        raise ResultsFileError(f"{source}: no 'cells' list (is this a tracking grid's results.json?)")
    labels, table = [], []
    for i, cell in enumerate(cells):
        label = cell.get("label", f"cells[{i}]") if isinstance(cell, dict) else f"cells[{i}]"
        ctl = cell.get("controllers") if isinstance(cell, dict) else None
        if not isinstance(ctl, dict):
            raise ResultsFileError(f"{source}: cell {label}: no 'controllers'")
        per = {}
        for c in ("cekm", *BASELINES, "kmeans-global"):
            seeds = ctl[c].get("per_seed") if isinstance(ctl.get(c), dict) else None
            if seeds is None and c == "kmeans-global":
                continue
            try:
                values = np.asarray(seeds, dtype=np.float64) if isinstance(seeds, list) else None
            except (TypeError, ValueError):
                values = None
            if values is None or values.ndim != 1 or len(values) < 2 or not np.isfinite(values).all():
                raise ResultsFileError(f"{source}: cell {label}: controllers.{c}.per_seed must be a list of at least "
                                       f"2 finite numbers, got {seeds!r:.60}")
            per[c] = values
        if len({len(v) for v in per.values()}) != 1:
            raise ResultsFileError(f"{source}: cell {label}: the controllers ran different numbers of seeds "
                                   f"({ {c: len(v) for c, v in per.items()} })")
        labels.append(label)
        table.append(per)
    return labels, table


def welch_p_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Two-sided Welch p of every row of a against the same row of b (as :func:`.metrics.welch_p`
    for one pair: 1 or 0 where neither row varies)."""
    from scipy import stats

    na, nb = a.shape[1], b.shape[1]
    va, vb = a.var(axis=1, ddof=1) / na, b.var(axis=1, ddof=1) / nb
    diff = a.mean(axis=1) - b.mean(axis=1)
    se2 = va + vb
    flat = (np.ptp(a, axis=1) == 0.0) & (np.ptp(b, axis=1) == 0.0)
    se2 = np.where(flat, 1.0, se2)
    df = se2 ** 2 / np.where(flat, 1.0, va ** 2 / (na - 1) + vb ** 2 / (nb - 1))
    p = 2.0 * stats.t.sf(np.abs(diff) / np.sqrt(se2), df)
    return np.where(flat, np.where(diff == 0.0, 1.0, 0.0), p)


def _counts(table: list[dict[str, np.ndarray]], who: str, n: int, reps: int,
            rng: np.random.Generator) -> np.ndarray:
    """``reps`` replicates with n seeds a cell: per replicate (cells above both baselines,
    cells also significant against each)."""
    out = np.zeros((reps, 2), dtype=int)
    for per in table:
        idx = rng.integers(0, len(per[who]), (reps, n))
        a = per[who][idx]
        up = np.ones(reps, dtype=bool)
        sig = np.ones(reps, dtype=bool)
        for b in BASELINES:
            bb = per[b][idx]
            up &= a.mean(axis=1) > bb.mean(axis=1)
            sig &= welch_p_rows(a, bb) < 0.05
        out[:, 0] += up
        out[:, 1] += up & sig
    return out


def seeds_power(doc: dict[str, Any], seeds: tuple[int, ...] = (10, 15, 20, 30, 40, 60), reps: int = 1000,
                rng_seed: int = 0, source: str = "results.json") -> list[dict[str, Any]]:
    """Per N in ``seeds`` and per controller held to the bar (cekm, and global K-means when
    the grid ran it): the mean and 5-95 % range over ``reps`` replicates of the cells above
    both baselines and of those also significant. Seeded: the same input, the same answer."""
    if reps < 1 or any(n < 2 for n in seeds):
        raise ParameterError("tracking-power: reps must be >= 1 and every N of seeds >= 2")
    labels, table = per_seed_table(doc, source)
    who = ["cekm"] + (["kmeans-global"] if all("kmeans-global" in per for per in table) else [])
    out = []
    observed = len(table[0]["cekm"])
    for i, c in enumerate(who):
        for n in seeds:
            runs = _counts(table, c, n, reps, np.random.default_rng([rng_seed, n, i]))
            out.append({"controller": c, "seeds": n, "cells": len(labels), "observed_seeds": observed,
                        "above_mean": float(runs[:, 0].mean()), "significant_mean": float(runs[:, 1].mean()),
                        "significant_5": float(np.percentile(runs[:, 1], 5)),
                        "significant_95": float(np.percentile(runs[:, 1], 95)),
                        "all_above": float(np.mean(runs[:, 0] == len(labels))),
                        "most_significant": float(np.mean(runs[:, 1] > len(labels) / 2))})
    return out


def power_markdown(rows: list[dict[str, Any]], source: str) -> str:
    """The bootstrap as a table."""
    lines = [f"Bootstrap of {source} ({rows[0]['observed_seeds']} seeds a cell resampled; {rows[0]['cells']} cells): "
             "what the grid with N seeds a cell would show by the acceptance's bar (mean A above both baselines; "
             "and Welch p < 0.05 against each).", "",
             "| controller | N seeds | cells above both | cells significant (5-95 %) | P(every cell above) | "
             "P(most cells significant) |", "|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['controller']} | {r['seeds']} | {r['above_mean']:.1f} | {r['significant_mean']:.1f} "
                     f"({r['significant_5']:.0f}-{r['significant_95']:.0f}) | {r['all_above']:.2f} | "
                     f"{r['most_significant']:.2f} |")
    return "\n".join(lines)
