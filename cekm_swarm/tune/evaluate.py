"""``cekm tune evaluate``: the field policy against the paper's and today's constants on
held-out scenarios (docs/fields.md).

Held out: generated scenarios with :data:`~.scenarios.SEED_BASE` ``["test"]`` seeds, which
neither training nor validation draws; ``--concave``: Fig. 9's sweep cells (concave.toml
with the sweep's widths, depths, ranges and world seeds, as ``cekm sweep concave`` runs
them); ``--suite``: section 4.2's table (``cekm experiment obstacles``' five scenarios and
success rule, seeds 1-20). None of these geometries or seeds is trained or selected on.
Navigation reports goal-reached and contact-free rates with Wilson 95 % intervals, overall
and per geometry kind, and the paired wins/losses of learned against tuned;
tracking reports Parker's A with t intervals and Welch p against every other controller.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from tqdm import tqdm

from world import load_scenario

from ..errors import ParameterError
from ..experiments.concave_config import SweepConfig
from ..experiments.concave_stats import cells_of, grid_of
from ..experiments.field_widths import fields_graph
from ..experiments.graph_run import with_params
from ..experiments.metrics import welch_p
from ..experiments.navigation_run import run_scenario
from ..experiments.obstacle_run import SUITE, success
from ..experiments.obstacle_stats import wilson_interval
from ..experiments.tracking_stats import mean_ci95
from .rollout import _model, run_many
from .scenarios import seed_of

BASELINES = ("acmommt", "kmeans", "kmeans-global")


def variants(task: str, policy: Path | None) -> dict[str, tuple]:
    """What runs: the three ``--fields`` (and, for tracking, the baselines' graphs)."""
    out: dict[str, tuple] = {"paper": ("fields", "paper"), "tuned": ("fields", "tuned"),
                             "learned": ("fields", "learned", str(policy) if policy else None)}
    if task == "tracking":
        out.update({b: ("controller", b) for b in BASELINES})
    return out


def _rate(k: int, n: int) -> dict[str, Any]:
    lo, hi = wilson_interval(k, n)
    return {"k": k, "n": n, "rate": k / n if n else None, "wilson95": [lo, hi]}


def _kind(name: str) -> str:
    return name.split("-")[1] if name.startswith("gen-") else name


def navigation_summary(rows: dict[str, list[dict]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for v, rs in rows.items():
        kinds = sorted({_kind(r["scenario"]) for r in rs})
        out[v] = {"reached": _rate(sum(r["reached"] for r in rs), len(rs)),
                  "contact_free": _rate(sum(r["contact_free"] for r in rs), len(rs)),
                  "by_kind": {k: _rate(sum(r["contact_free"] for r in rs if _kind(r["scenario"]) == k),
                                       sum(_kind(r["scenario"]) == k for r in rs)) for k in kinds}}
    if "learned" in rows and "tuned" in rows:
        pairs = list(zip(rows["learned"], rows["tuned"], strict=True))
        out["learned_vs_tuned"] = {"contact_free_wins": sum(a["contact_free"] and not b["contact_free"]
                                                            for a, b in pairs),
                                   "contact_free_losses": sum(b["contact_free"] and not a["contact_free"]
                                                              for a, b in pairs)}
    return out


def tracking_summary(rows: dict[str, list[dict]]) -> dict[str, Any]:
    out: dict[str, Any] = {v: mean_ci95([r["A"] for r in rs]) for v, rs in rows.items()}
    if "learned" in rows:
        out["learned_welch_p"] = {v: welch_p([r["A"] for r in rows["learned"]], [r["A"] for r in rs])
                                  for v, rs in rows.items() if v != "learned"}
    return out


def evaluate(task: str, tests: int, policy: Path | None = None, max_time: float | None = None,
             model_path: str | None = None, workers: int = 2, progress: bool = True,
             only: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Every variant on the ``tests`` held-out generated scenarios; the results document."""
    max_time = max_time or (300.0 if task == "navigation" else 120.0)
    vs = {k: v for k, v in variants(task, policy).items() if only is None or k in only}
    wheres = [seed_of("test", i) for i in range(tests)]
    jobs = [(task, what, w, max_time, model_path) for what in vs.values() for w in wheres]
    with tqdm(total=len(jobs), disable=not progress, desc=f"evaluate {task}", unit="run") as bar:
        flat = run_many(jobs, workers, bar.update)
    rows = {v: flat[i * len(wheres):(i + 1) * len(wheres)] for i, v in enumerate(vs)}
    summary = navigation_summary(rows) if task == "navigation" else tracking_summary(rows)
    return {"experiment": "field-policy", "task": task, "held_out": "generated, test seeds",
            "seeds": [wheres[0], wheres[-1]] if wheres else [], "max_time_s": max_time,
            "policy": str(policy) if policy else "shipped", "summary": summary, "runs": rows}


def evaluate_concave(policy: Path | None = None, model_path: str | None = None, workers: int = 2,
                     progress: bool = True, config: SweepConfig | None = None,
                     only: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Fig. 9's sweep for every ``--fields``: the widest U negotiated per (range, depth)."""
    config = config or SweepConfig()
    vs = {k: v for k, v in variants("navigation", policy).items() if only is None or k in only}
    cells = [("concave", w, d, r, s) for r in config.ranges for d in config.depths for w in config.widths
             for s in config.seeds]
    jobs = [("navigation", what, c, config.max_time, model_path) for what in vs.values() for c in cells]
    with tqdm(total=len(jobs), disable=not progress, desc="evaluate concave", unit="run") as bar:
        flat = run_many(jobs, workers, bar.update)
    out: dict[str, Any] = {"experiment": "field-policy-concave", "policy": str(policy) if policy else "shipped",
                           "need": config.need}
    for i, v in enumerate(vs):
        mine = flat[i * len(cells):(i + 1) * len(cells)]
        runs = [{"width": c[1], "depth": c[2], "range": c[3], "seed": c[4], "reached": r["reached"],
                 "collisions": r["collisions"]} for c, r in zip(cells, mine, strict=True)]
        out[v] = {"cells": cells_of(config, runs), "grid": grid_of(config, runs),
                  "negotiated_cells": sum(c["reached"] >= config.need for c in cells_of(config, runs))}
    return out


def suite_one(job: tuple) -> dict:
    """One run of section 4.2's table (``cekm experiment obstacles``' scenarios, seeds and
    success rule) with ``--fields`` ``what``."""

    scenario, what, seed, max_time, model_path = job
    checked, params = fields_graph(what[1], "navigation", what[2] if len(what) > 2 else None)
    run = run_scenario(load_scenario(scenario), "cekm", _model(model_path), seed, max_time,
                       graph=with_params(checked, params))
    o = next(iter(run.outcome.values()))
    ok = success(scenario, o, run.geometry)
    return {"scenario": scenario, "seed": seed, "success": ok, "collision_free": ok and o["collisions"] == 0,
            "collisions": o["collisions"], "reached": o["reached"]}


def evaluate_suite(seeds: tuple[int, ...], policy: Path | None = None, model_path: str | None = None,
                   workers: int = 2, progress: bool = True, max_time: float = 300.0,
                   only: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Section 4.2's table (concave, doorway, rooms, checkpoints, lone obstacle) for every ``--fields``."""

    vs = {k: v for k, v in variants("navigation", policy).items() if only is None or k in only}
    cells = [(sc, s) for sc in SUITE for s in seeds]
    jobs = [(sc, what, s, max_time, model_path) for what in vs.values() for sc, s in cells]
    with tqdm(total=len(jobs), disable=not progress, desc="evaluate section 4.2", unit="run") as bar:
        flat = run_many(jobs, workers, bar.update, fn=suite_one)
    out: dict[str, Any] = {"experiment": "field-policy-4.2", "seeds": list(seeds), "max_time_s": max_time,
                           "policy": str(policy) if policy else "shipped"}
    for i, v in enumerate(vs):
        rows = flat[i * len(cells):(i + 1) * len(cells)]
        out[v] = {sc: {"success": _rate(sum(r["success"] for r in rows if r["scenario"] == sc), len(seeds)),
                       "collision_free": _rate(sum(r["collision_free"] for r in rows if r["scenario"] == sc),
                                               len(seeds)),
                       "contacts": sum(r["collisions"] for r in rows if r["scenario"] == sc)} for sc in SUITE}
        out[v]["runs"] = rows
    return out


def concave_rows(specs: list[str]) -> tuple[dict[str, list[dict]], int]:
    """The rows of :func:`~cekm_swarm.experiments.concave_figures.plot_grid_rows` from
    ``cekm tune evaluate --concave`` documents: each spec is ``FILE`` (every variant in it)
    or ``FILE:VARIANT`` or ``FILE:VARIANT=LABEL``; returns the rows and the cells' ``need``.
    A ParameterError names the spec and what is wrong."""
    rows: dict[str, list[dict]] = {}
    needs = set()
    for spec in specs:
        path, _, pick = spec.partition(":") if not Path(spec).exists() else (spec, "", "")
        variant, _, label = pick.partition("=")
        try:
            doc = json.loads(Path(path).read_text())
        except (OSError, ValueError) as exc:
            raise ParameterError(f"{path}: not a readable results.json: {exc}") from None
        if not isinstance(doc, dict) or doc.get("experiment") != "field-policy-concave":
            raise ParameterError(f"{path}: not the results of `cekm tune evaluate --concave`")
        found = [v for v in doc if isinstance(doc[v], dict) and "cells" in doc[v]]
        if variant and variant not in found:
            raise ParameterError(f"{spec}: no variant {variant!r} in {path} (it has {', '.join(found)})")
        for v in [variant] if variant else found:
            name = label or v
            if name in rows:
                raise ParameterError(f"{spec}: a second row named {name!r}; name it with {path}:{v}=LABEL")
            rows[name] = doc[v]["cells"]
        needs.add(int(doc.get("need", SweepConfig().need)))
    if len(needs) > 1:
        raise ParameterError(f"the documents count a cell negotiated at different numbers of runs: {sorted(needs)}")
    return rows, needs.pop() if needs else SweepConfig().need
