"""The tracking grid's statistics: per cell, per level of an axis and per level pair of
two axes, each controller's mean A with a 95 % t interval (clipped to [0, 1]:
:func:`.tracking_stats.mean_ci95`), and cekm's A minus the best baseline's (the
baseline with the higher mean there) with Welch's p (the acceptance's test) and, since
every controller runs on the same scenarios and seeds, a paired t-test's p as well."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from .grid_design import AXES, Cell
from .grid_run import BASELINES, PARTS
from .metrics import paired_p, welch_p
from .tracking_stats import mean_ci95


def _versus(cekm: list[float], base: dict[str, list[float]], above: str = "cekm_above_all") -> dict[str, Any]:
    """``cekm`` (or another controller's A per seed) against the baselines: the best one, the
    difference, Welch's p against it; whether it is above all of them (key ``above``); Welch's
    and the paired test's p against each."""
    best = max(base, key=lambda c: np.mean(base[c]))
    return {"best_baseline": best, "diff": float(np.mean(cekm) - np.mean(base[best])),
            "p": welch_p(cekm, base[best]), above: bool(all(np.mean(cekm) > np.mean(v) for v in base.values())),
            "p_each": {c: welch_p(cekm, v) for c, v in base.items()},
            "p_paired_each": {c: paired_p(cekm, v) for c, v in base.items()}}


def cell_stats(rows: list[dict[str, Any]], cells: list[Cell], controllers: tuple[str, ...]) -> list[dict[str, Any]]:
    """Every cell: its levels, per controller the A of every seed and their mean and
    interval, cekm against the best baseline and against global K-means."""
    out = []
    for cell in cells:
        sub = sorted((r for r in rows if r["cell"] == cell.label), key=lambda r: r["seed"])  # paired by seed
        per = {c: [r["A"] for r in sub if r["controller"] == c] for c in controllers}
        doc = {**cell.as_dict(), "controllers": {c: {"A": mean_ci95(v), "per_seed": v} for c, v in per.items()},
               "collisions": {c: sum(r["collisions"] for r in sub if r["controller"] == c) for c in controllers}}
        if "cekm" in per and all(b in per for b in BASELINES):
            doc["cekm_vs_best"] = _versus(per["cekm"], {b: per[b] for b in BASELINES})
            if "kmeans-global" in per:
                g = per["kmeans-global"]
                doc["cekm_vs_global"] = {"diff": float(np.mean(per["cekm"]) - np.mean(g)), "p": welch_p(per["cekm"], g)}
                # the same bar for the centralized upper baseline: what this cell lets any controller show
                doc["global_vs_best"] = _versus(g, {b: per[b] for b in BASELINES}, "above_all")
        out.append(doc)
    return out


def _pooled(cells: list[dict[str, Any]], controllers) -> dict[str, list[float]]:
    return {c: [a for d in cells for a in d["controllers"][c]["per_seed"]] for c in controllers}


def by_axis(cells: list[dict[str, Any]], controllers: tuple[str, ...]) -> dict[str, list[dict[str, Any]]]:
    """Per axis, per level: every controller's A pooled over the cells at that level (every
    seed of every such cell), and cekm against the best baseline there."""
    out = {}
    for axis in AXES:
        levels = sorted({d[axis] for d in cells}, key=lambda v: (str(type(v)), v))
        if axis == "speed":
            levels = [s for s in ("slow", "medium", "fast") if s in levels]
        rows = []
        for lv in levels:
            sub = [d for d in cells if d[axis] == lv]
            pooled = _pooled(sub, controllers)
            row = {"level": lv, "cells": len(sub), "controllers": {c: mean_ci95(v) for c, v in pooled.items()}}
            if "cekm" in pooled and all(b in pooled for b in BASELINES):
                row["cekm_vs_best"] = _versus(pooled["cekm"], {b: pooled[b] for b in BASELINES})
            rows.append(row)
        out[axis] = rows
    return out


def _levels(axis: str, cells: list[dict[str, Any]]) -> list[Any]:
    """The levels of ``axis`` that occur in ``cells``, in order (speeds slow to fast)."""
    known = ("slow", "medium", "fast") if axis == "speed" else sorted({d[axis] for d in cells})
    return [v for v in known if any(d[axis] == v for d in cells)]


def by_pair(cells: list[dict[str, Any]], controllers: tuple[str, ...]) -> list[dict[str, Any]]:
    """Per pair of axes, per level pair that occurs: cekm's A minus the best baseline's,
    pooled over the cells there, with Welch's p (the heatmaps)."""
    out = []
    for a, b in itertools.combinations(AXES, 2):
        la = _levels(a, cells)
        lb = _levels(b, cells)
        grid = []
        for va, vb in itertools.product(la, lb):
            sub = [d for d in cells if d[a] == va and d[b] == vb]
            if not sub:
                continue
            pooled = _pooled(sub, controllers)
            grid.append({a: va, b: vb, "cells": len(sub), **_versus(pooled["cekm"], {k: pooled[k] for k in BASELINES})})
        out.append({"axes": [a, b], "levels": [la, lb], "cells": grid})
    return out


def by_part(rows: list[dict[str, Any]], controllers: tuple[str, ...], duration: float) -> dict[str, Any]:
    """A over the run: per controller, per part of the run (:data:`.grid_run.PARTS` equal
    parts of its ticks), A pooled over every cell and seed with its interval, and cekm's
    minus each other controller's with Welch's p. So one sees where a controller gains: the
    first part is mostly finding the targets, the later ones holding them."""
    have = [r for r in rows if r.get("A_parts") is not None]
    if not have:
        return {"parts": [], "controllers": {}, "cekm_minus": {}}
    span = duration / PARTS
    per = {c: [[r["A_parts"][k] for r in have if r["controller"] == c] for k in range(PARTS)] for c in controllers}
    out: dict[str, Any] = {"parts": [[round(k * span, 3), round((k + 1) * span, 3)] for k in range(PARTS)],
                           "controllers": {c: [mean_ci95(v) for v in per[c]] for c in controllers if per[c][0]}}
    if "cekm" in out["controllers"]:
        out["cekm_minus"] = {c: [{"diff": float(np.mean(per["cekm"][k]) - np.mean(per[c][k])),
                                  "p": welch_p(per["cekm"][k], per[c][k])} for k in range(PARTS)]
                             for c in out["controllers"] if c != "cekm"}
    return out
