"""One policy on generated scenarios: the runs the training and the evaluation make
(docs/fields.md). A run is ``cekm run``'s (:func:`~cekm_swarm.experiments.graph_run.run_graph`)
with the field-policy graph, or with a shipped controller's graph for a comparison."""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from world import load_scenario

from ..experiments.field_widths import fields_graph, policy_graph
from ..experiments.graph_run import run_graph
from ..models.io import load_model
from ..node.graph_check import check_graph
from .scenarios import scenario as generated

_MODEL: dict[str | None, Any] = {}


def _model(path: str | None):
    if path not in _MODEL:
        if path is None:
            from ..experiments.default_model import default_model  # noqa: PLC0415 -- lazy: scipy

            _MODEL[path] = default_model(progress=False)
        else:
            _MODEL[path] = load_model(path)
    return _MODEL[path]


def navigation_score(o: dict) -> float:
    """The training objective of one navigation run: 1 for the goal reached without a
    contact; reached with contacts 0.5 less 0.05 per contact (down to 0.25); not reached
    0.4 times the fraction of the start's distance covered."""
    if o["reached"]:
        return 1.0 if o["collisions"] == 0 else 0.5 - 0.05 * min(o["collisions"], 5)
    start = o.get("start_distance_m") or 1.0
    return 0.4 * max(0.0, 1.0 - o["final_distance_m"] / start)


def scenario_of(task: str, where):
    """The scenario and world seed of a job: a generated scenario's seed (its own world
    seed), ("mix", mix, seed) the same from another geometry mix (:data:`.scenarios.MIXES`),
    or ("concave", width, depth, sensor range, world seed), Fig. 9's sweep cell
    (concave.toml with those overrides, as ``cekm sweep concave`` builds it)."""
    if isinstance(where, tuple) and where and where[0] == "mix":
        return generated(task, int(where[2]), mix=where[1]), None
    if isinstance(where, tuple) and where and where[0] == "concave":
        _, width, depth, rng, seed = where
        return load_scenario("concave", overrides={"obstacles[0].width": width, "obstacles[0].depth": depth,
                                                   "sensors.range": rng}), seed
    return generated(task, int(where)), None


def run_one(job: tuple) -> dict:
    """One run: (task, what, where, max_time, model path); ``where`` as :func:`scenario_of`
    takes it, ``what`` a weight
    tuple (the field-policy graph), ``("fields", name[, policy file])`` (--fields) or
    ``("controller", name)`` (a shipped controller's graph). Returns its row."""
    task, what, where, max_time, model_path = job
    sc, seed = scenario_of(task, where)
    model = _model(model_path)
    if isinstance(what, tuple) and what and what[0] == "fields":
        checked, params = fields_graph(what[1], task, what[2] if len(what) > 2 else None)
        run = run_graph(sc, graph=checked, params=params, model=model, max_time=max_time, seed=seed)
    elif isinstance(what, tuple) and what and what[0] == "controller":
        run = run_graph(sc, what[1], model=model, max_time=max_time, seed=seed)
    else:
        run = run_graph(sc, graph=check_graph(policy_graph(task)), params={"weights": tuple(what)}, model=model,
                        max_time=max_time, seed=seed)
    row: dict[str, Any] = {"where": list(where) if isinstance(where, tuple) else where, "scenario": sc.name}
    if task == "navigation":
        o = run.episode.outcome()["r1"]
        (sx, sy, _), (gx, gy) = sc.robots[0].start, run.world.goal_of("r1")
        o["start_distance_m"] = math.hypot(gx - sx, gy - sy)
        row.update({k: o[k] for k in ("reached", "collisions", "final_distance_m", "start_distance_m", "time_s")})
        row["contact_free"] = bool(o["reached"] and o["collisions"] == 0)
        row["score"] = navigation_score(o)
    else:
        row["A"] = run.episode.meter.A
        row["score"] = row["A"]
    run.executor.close()
    return row


def run_many(jobs: list[tuple], workers: int = 1, progress=None, fn=None) -> list[dict]:
    """``fn`` (default :func:`run_one`) of every job, in order (so the results do not
    depend on the workers); ``progress()`` after each."""
    fn = fn or run_one
    out = []
    if workers <= 1:
        for j in jobs:
            out.append(fn(j))
            if progress:
                progress()
        return out
    with ProcessPoolExecutor(max_workers=min(workers, os.cpu_count() or 1, len(jobs) or 1)) as ex:
        for row in ex.map(fn, jobs):
            out.append(row)
            if progress:
                progress()
    return out
