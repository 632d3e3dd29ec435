"""``cekm experiment learning`` (docs/learning.md): learning curves through the graph.

Teams of robots start from untrained maps (R15, ``--model untrained``) in the 5 m x 5 m
obstacle-free arena of section 4.1 and learn online while they reach targets drawn at
random (a new one when a robot stops at its target, or after 100 steps of 1.024 s:
:class:`world.training.TrainingEpisode`) with section 4.1's training exploration noise on
their executed wheel speeds (the scenario's ``explore``), every robot with the learning graph
(``cekm-learning``) or the team-learning graph (``cekm-learning-team``, each learner also
learns from its teammates' (v, c) pairs). At fixed ticks the first robot's map is
scored on the section 4.1 test (E, T: :func:`.learning_run.test_score`), against the
robot's own learning steps. Runs are seeded and independent, so the results are the same
with any number of workers.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from world import load_scenario

from ..modules.learner import copy_model
from .graph_run import resolve_graph, run_graph, with_params
from .learning_run import LEARNER, learning_params, test_score, untrained_model

ARENA = 2.5  # m: half the side of section 4.1's 5 m x 5 m arena


@dataclass(frozen=True)
class LearningConfig:
    """What ``cekm experiment learning`` runs: every team size with and without sharing, over seeds."""

    teams: tuple[int, ...] = (1, 2, 4, 8)
    seeds: tuple[int, ...] = (1, 2)
    ticks: int = 1600  # per run: 1600 ticks of 0.128 s, 205 s of sim time, about 1600 learning steps per robot
    evals: tuple[int, ...] = (0, 16, 32, 64, 128, 256, 512, 1024, 1600)  # ticks at which r1's map is scored
    threshold_mm: float = 5.0  # E below which a map counts as learned (steps to it, per robot)
    threshold_T: float = 50.0  # s/m: and T below which


def scenario_text(n: int) -> str:
    """A team of n robots in the arena, on a ring around its centre facing out, each with a
    target (section 4.1's training: new targets, exploration noise)."""
    lines = ['name = "learning"', 'description = "section 4.1 arena, a team learning online"', "seed = 1",
             "retarget = true", "explore = true", "",
             "[arena]", f"bounds = [{-ARENA}, {-ARENA}, {ARENA}, {ARENA}]", "boundary_walls = true",
             "wall_thickness = 0.02", ""]
    for i in range(n):
        a = 2.0 * math.pi * i / n
        r = 0.0 if n == 1 else 0.6
        lines += ["[[robots]]", f'id = "r{i + 1}"', f"start = [{r * math.cos(a):.6f}, {r * math.sin(a):.6f}, {a:.6f}]",
                  f'goal = "t{i + 1}"', "", "[[targets]]", f'id = "t{i + 1}"',
                  f"position = [{1.5 * math.cos(a + 0.7):.6f}, {1.5 * math.sin(a + 0.7):.6f}]", ""]
    return "\n".join(lines)


@dataclass
class Curve:
    """One run: the first robot's map scored at the ticks ``evals``."""

    team: int
    share: bool
    seed: int
    steps: list[int] = field(default_factory=list)  # the first robot's own learning steps
    updates: list[int] = field(default_factory=list)  # every update of its map (own and teammates')
    E_mm: list[float] = field(default_factory=list)
    T_s_per_m: list[float] = field(default_factory=list)
    D: list[float] = field(default_factory=list)
    targets_reached: int = 0
    collisions: int = 0


def run_one(team: int, share: bool, seed: int, config: LearningConfig, folder: Path) -> Curve:
    """One seeded run of a team, scored as it learns."""

    path = folder / f"learning-{team}.toml"
    if not path.exists():
        path.write_text(scenario_text(team))
    controller = "cekm-learning-team" if share else "cekm-learning"
    checked = with_params(resolve_graph(controller, None, "navigation"), learning_params("untrained"))
    curve = Curve(team, share, seed)

    def observe(executor, k: int) -> None:
        if k in config.evals:
            node = executor.node("r1", LEARNER)
            s = test_score(copy_model(node.net))
            curve.steps.append(node.counts.applied)
            curve.updates.append(node.counts.learned)
            curve.E_mm.append(s["E_mm"])
            curve.T_s_per_m.append(s["T_s_per_m"])
            curve.D.append(s["D"])

    run = run_graph(load_scenario(path), graph=checked, model=untrained_model(), seed=seed,
                    max_time=(config.ticks - 0.5) * 0.128, observe=observe)
    curve.targets_reached = sum(run.episode.reached_count.values())
    curve.collisions = sum(run.world.stats(r)["collisions"] for r in run.world.robot_ids)
    return curve


def steps_to(curve: Curve, threshold: float, index: str = "E_mm") -> int | None:
    """The first robot's own steps until its map's E (or T) fell below the threshold (None: never)."""
    return next((s for s, e in zip(curve.steps, getattr(curve, index), strict=True) if e < threshold), None)


def run_experiment(config: LearningConfig, out: Path, workers: int = 1,
                   done: Callable[[Curve], None] | None = None) -> list[Curve]:
    """Every (team, sharing, seed) run, in a fixed order (a pool of ``workers`` processes)."""
    jobs = [(n, share, seed) for n in config.teams for share in ((False, True) if n > 1 else (False,))
            for seed in config.seeds]
    curves: list[Curve] = []
    if workers <= 1:
        for n, share, seed in jobs:
            curves.append(run_one(n, share, seed, config, out))
            if done:
                done(curves[-1])
        return curves

    with ProcessPoolExecutor(workers) as pool:
        futures = [pool.submit(run_one, n, share, seed, config, out) for n, share, seed in jobs]
        for f in futures:
            curves.append(f.result())
            if done:
                done(curves[-1])
    return curves


def results_doc(config: LearningConfig, curves: list[Curve]) -> dict[str, Any]:
    """results.json: the config, every curve, and per (team, sharing) the steps to the threshold."""
    summary: dict[str, Any] = {}
    for c in curves:
        key = f"{c.team}{'-shared' if c.share else ''}"
        row = summary.setdefault(key, {"team": c.team, "shared": c.share, "steps_to_E": [], "steps_to_T": [],
                                       "final_E_mm": [], "final_T_s_per_m": [], "final_D": [], "targets_reached": [],
                                       "collisions": []})
        row["steps_to_E"].append(steps_to(c, config.threshold_mm))
        row["steps_to_T"].append(steps_to(c, config.threshold_T, "T_s_per_m"))
        row["targets_reached"].append(c.targets_reached)
        row["collisions"].append(c.collisions)
        row["final_E_mm"].append(c.E_mm[-1])
        row["final_T_s_per_m"].append(c.T_s_per_m[-1])
        row["final_D"].append(c.D[-1])
    for row in summary.values():
        row["stats"] = {k: seed_interval(row[k]) for k in STATS_OF}
    sharing = {str(n): {k: paired_difference(summary[str(n)][k], summary[f"{n}-shared"][k]) for k in STATS_OF}
               for n in config.teams if str(n) in summary and f"{n}-shared" in summary}
    return {"config": asdict(config), "summary": summary, "sharing": sharing, "curves": [asdict(c) for c in curves]}


STATS_OF = ("steps_to_E", "steps_to_T", "final_E_mm", "final_T_s_per_m", "final_D")  # summarized over seeds


def seed_interval(values: list[float | None]) -> dict[str, Any]:
    """{"mean", "lo", "hi", "n", "of"} over the seeds with a value (a None: the threshold never
    reached, counted in "of" but not in the mean): the mean and its Student-t 95 % interval
    (lo = hi = None with one seed)."""
    from .reaching_stats import interval95  # noqa: PLC0415 -- lazy: scipy

    out = interval95(values) | {"of": len(values)}
    if out["n"] < 2:
        out["lo"] = out["hi"] = None
    return out


def paired_difference(alone: list[float | None], shared: list[float | None]) -> dict[str, Any]:
    """Sharing minus not sharing on the same seeds (both lists in seed order; seeds where
    either is None are left out): the mean difference, its 95 % t interval, and the paired
    t-test's two-sided p (None with fewer than two pairs)."""
    from .metrics import paired_p  # noqa: PLC0415 -- lazy: scipy

    pairs = [(a, b) for a, b in zip(alone, shared, strict=True) if a is not None and b is not None]
    diff = seed_interval([b - a for a, b in pairs])
    return {"mean_diff": diff["mean"], "lo": diff["lo"], "hi": diff["hi"], "n": diff["n"],
            "p": paired_p([b for _, b in pairs], [a for a, _ in pairs]) if pairs else None}


def summary_table(doc: dict[str, Any]) -> list[str]:
    """The summary as text lines: per team and sharing, mean [95 % interval] over seeds; per
    team, sharing minus not sharing (paired on seeds) with its p."""

    def fmt(s: dict[str, Any], digits: int) -> str:
        if s["mean"] is None:
            return "never"
        ci = "" if s["lo"] is None else f" [{s['lo']:.{digits}f}, {s['hi']:.{digits}f}]"
        miss = "" if s["n"] == s["of"] else f" ({s['of'] - s['n']} of {s['of']} never)"
        return f"{s['mean']:.{digits}f}{ci}{miss}"

    c = doc["config"]
    lines = [f"mean [95 % interval] over {len(c['seeds'])} seeds; steps of r1 to E < {c['threshold_mm']} mm, "
             f"to T < {c['threshold_T']} s/m; final E (mm), T (s/m), D"]
    for key, row in doc["summary"].items():
        st = row["stats"]
        lines.append(f"{key:>10}: to E {fmt(st['steps_to_E'], 0)}; to T {fmt(st['steps_to_T'], 0)}; final E "
                     f"{fmt(st['final_E_mm'], 2)}, T {fmt(st['final_T_s_per_m'], 1)}, D {fmt(st['final_D'], 2)}")
    for n, d in doc.get("sharing", {}).items():
        parts = []
        for k, digits in (("steps_to_E", 0), ("steps_to_T", 0), ("final_E_mm", 2)):
            s = d[k]
            if s["mean_diff"] is None:
                parts.append(f"{k} n/a")
                continue
            ci = "" if s["lo"] is None else f" [{s['lo']:.{digits}f}, {s['hi']:.{digits}f}]"
            p = "" if s["p"] is None else f", p = {s['p']:.3f}"
            parts.append(f"{k} {s['mean_diff']:+.{digits}f}{ci} (n = {s['n']}{p})")
        lines.append(f"{n:>3} robots, sharing - not: " + "; ".join(parts))
    return lines


def plot_curves(config: LearningConfig, curves: list[Curve]):
    """E and T of the first robot's map against its own learning steps (Fig. 5's shape)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    groups: dict[tuple[int, bool], list[Curve]] = {}
    for c in curves:
        groups.setdefault((c.team, c.share), []).append(c)
    for (team, share), cs in sorted(groups.items()):
        label = f"{team} robot{'s' if team > 1 else ''}{', sharing' if share else ''}"
        steps = np.mean([c.steps for c in cs], axis=0)
        for ax, name in zip(axes, ("E_mm", "T_s_per_m"), strict=True):
            ax.plot(steps, np.mean([getattr(c, name) for c in cs], axis=0), "-" if share or team == 1 else "--",
                    marker="o", ms=3, label=label)
    axes[0].set_ylabel("E (mm)")
    axes[1].set_ylabel("T (s/m)")
    for ax in axes:
        ax.set_yscale("log")
        ax.set_xlabel("learning steps of robot r1")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"untrained R15 learning through the runtime (mean of {len(config.seeds)} seeds)")
    fig.tight_layout()
    return fig
