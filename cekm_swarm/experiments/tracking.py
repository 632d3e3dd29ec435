"""Multi-robot tracking (Fig. 13) in one process, and the experiment over team sizes.

A run is the controller's graph (cooperative EKMs, A-CMOMMT, or robots that stay) on a
tracking scenario, run by :func:`.graph_run.run_graph` with the world server's tracking
episode (:class:`world.tracking.TrackingEpisode`): at tick k each robot's nodes see the
world's readings of tick k and their teammates' shares of their previous run (the rule
of :mod:`cekm_swarm.graph.plan`). Parker's A is sampled at every tick before the readings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..models.params import ACMOMMTParams, TrackingParams

CONTROLLERS = ("cekm", "acmommt", "kmeans", "kmeans-global", "stay")
DEFAULT_DURATION = 120.0  # s of sim time of a tracking run


@dataclass
class TrackingRun:
    scenario: str
    controller: str
    seed: int
    paths: dict[str, list[tuple[float, float, float, float]]]  # robot: (t, x, y, theta) per tick
    target_paths: dict[str, list[tuple[float, float]]]
    tracking: dict[str, Any]
    geometry: dict
    final_state: dict
    target_range: float
    collisions: dict[str, int] = field(default_factory=dict)
    graph: str | None = None


def run_tracking(scenario, controller: str = "cekm", model=None, seed: int | None = None,
                 duration: float = DEFAULT_DURATION, tparams: TrackingParams | None = None,
                 aparams: ACMOMMTParams | None = None, graph=None) -> TrackingRun:
    """Run a tracking scenario for ``duration`` s of sim time with the controller's graph
    in one process (:func:`.graph_run.run_graph`; a distributed lockstep run computes the
    same, bit for bit). ``tparams``/``aparams``: the tracking controllers' parameters."""
    from dataclasses import asdict

    from world.tracking import is_tracking

    from .graph_run import run_graph

    if graph is None and controller not in CONTROLLERS:
        raise ParameterError(f"unknown tracking controller {controller!r}; expected one of {list(CONTROLLERS)}")
    if not is_tracking(scenario):
        raise ParameterError(f"scenario {scenario.name!r} is not a tracking scenario (it needs targets and robots "
                             "without a goal)")
    if not math.isfinite(scenario.target_range):
        raise ParameterError(f"scenario {scenario.name!r}: sensors.target_range must be finite for tracking")
    overrides: dict[str, Any] = {}
    for p in (tparams, aparams):
        if p is not None:
            overrides.update(asdict(p))
    if overrides:
        overrides["lenient"] = True
    run = run_graph(scenario, controller, graph=graph, model=model, seed=seed, max_time=duration,
                    params=overrides or None)
    world, episode = run.world, run.episode
    robots = list(world.robot_ids)
    paths = {r: list(episode.progress[r].path) for r in robots}
    collisions = {r: int(world.stats(r)["collisions"]) for r in robots}
    return TrackingRun(scenario.name, controller, int(seed if seed is not None else scenario.seed), paths,
                       run.target_paths, episode.meter.summary(), world.static_geometry(), world.state(),
                       world.target_range, collisions, run.plan.graph.name)


def outcome_doc(run: TrackingRun) -> dict[str, Any]:
    """``outcome.json`` of a tracking run."""
    robots = {}
    for r, p in run.paths.items():
        length = sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in zip(p, p[1:]))
        robots[r] = {"path_length_m": length, "collisions": run.collisions.get(r, 0),
                     "final_pose": list(p[-1][1:]) if p else None}
    return {"scenario": run.scenario, "controller": run.controller, "graph": run.graph, "seed": run.seed,
            "robots": robots, "tracking": run.tracking}


def run_tracking_cmd(scenario, controller: str, model_path, seed: int | None, duration: float | None, out_dir,
                     graph=None, model=None) -> None:
    """``cekm run`` on a tracking scenario: outcome.json (with ``tracking``) and trajectory.png."""
    import json
    import time
    from pathlib import Path

    import click

    if model is None and controller == "cekm" and graph is None:
        from ..models.io import load_model
        from .default_model import default_model

        model = load_model(model_path) if model_path else default_model()
    t0 = time.perf_counter()
    run = run_tracking(scenario, controller, model, seed, DEFAULT_DURATION if duration is None else duration,
                       graph=graph)
    out = Path(out_dir)
    doc = outcome_doc(run)
    doc["wall_seconds"] = round(time.perf_counter() - t0, 3)
    (out / "outcome.json").write_text(json.dumps(doc, indent=1))
    import matplotlib.pyplot as plt

    fig = plot_tracking(run)
    fig.savefig(out / "trajectory.png", dpi=130)
    plt.close(fig)
    tr = run.tracking
    per = ", ".join(f"{k} {v:.2f}" for k, v in tr["A_per_target"].items())
    sp = tr["spread"]
    click.echo(f"A = {tr['A']:.3f} ({tr['robots']} robots, {tr['targets']} targets; per target: {per}); robots "
               f"apart {sp['robots_start']:.2f} -> {sp['robots_end']:.2f} m while targets {sp['targets_start']:.2f} "
               f"-> {sp['targets_end']:.2f} m; collisions {sum(run.collisions.values())}")
    click.echo(f"wrote {out / 'outcome.json'}, {out / 'trajectory.png'}")


def plot_tracking(run: TrackingRun, ax=None, title: str | None = None, instants: int = 4):
    """Fig. 13: the targets' paths (grey, arrow at the end), each robot's path in its colour,
    and its sensing circle at a few instants (fainter earlier)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from world.draw import draw_paths, draw_tracking, draw_world, legend_outside, robot_colours

    own = ax is None
    if own:
        xmin, ymin, xmax, ymax = run.geometry["bounds"]
        aspect = (ymax - ymin) / max(xmax - xmin, 1e-9)
        fig, ax = plt.subplots(figsize=(6.5 + 1.7, max(3.0, 6.5 * aspect)))
    draw_world(ax, run.geometry, None)
    colours = robot_colours(sorted(run.paths))
    step = draw_paths(ax, {r: ([q[0] for q in p], [q[1] for q in p], [q[2] for q in p]) for r, p in run.paths.items()},
                      colours)
    draw_tracking(ax, {r: ([q[1] for q in p], [q[2] for q in p]) for r, p in run.paths.items()}, run.target_paths,
                  run.target_range, colours, instants)
    bx0, by0, bx1, by1 = run.geometry["bounds"]
    ax.set_xlim(bx0 - 0.05, bx1 + 0.05)
    ax.set_ylim(by0 - 0.05, by1 + 0.05)
    ax.set_aspect("equal")
    ax.set_title(title or f"{run.scenario}: {run.controller}, seed {run.seed}, A = {run.tracking['A']:.3f}",
                 fontsize=9)
    legend_outside(ax, time_step=step)
    if own:
        fig.tight_layout()
        return fig
    return ax


# --------------------------------------------------------------------------- team sizes


def team_scenario(robots: int, seed: int, targets_per_robot: float = 1.5, side_per_sqrt_robot: float = 2.0 / math.sqrt(2),
                  target_range: float = 0.5, speed: float = 0.05, turn_noise: float = 1.0):
    """A tracking scenario for a team of ``robots``: a square walled arena whose area grows
    with the team (side = side_per_sqrt_robot * sqrt(robots): 2 m for 2 robots, as
    tracking.toml), round(targets_per_robot * robots) random-walk targets at uniform
    starts, robots in a ring around the centre. Densities of robots and targets are the
    same for every size, so A compares across sizes. ``seed`` draws the starts and the world."""
    from world.scenario import parse_scenario

    rng = np.random.default_rng([seed, robots, 13])
    side = side_per_sqrt_robot * math.sqrt(robots)
    m = max(1, round(targets_per_robot * robots))
    ring = 0.15 * side
    c = side / 2
    raw: dict[str, Any] = {
        "name": f"tracking-{robots}", "seed": seed, "arena": {"bounds": [0.0, 0.0, side, side]},
        "sensors": {"target_range": target_range},
        "robots": [{"id": f"r{i + 1}", "start": [c + ring * math.cos(2 * math.pi * i / robots),
                                                 c + ring * math.sin(2 * math.pi * i / robots),
                                                 float(2 * math.pi * i / robots) if i else 0.0]}
                   for i in range(robots)],
        "targets": [{"id": f"t{k + 1}", "position": [float(x) for x in rng.uniform(0.1, side - 0.1, 2)],
                     "motion": {"type": "random_walk", "speed": speed, "turn_noise": turn_noise,
                                "heading": float(rng.uniform(-math.pi, math.pi))}}
                    for k in range(m)],
    }
    for r in raw["robots"]:
        r["start"][2] = math.atan2(math.sin(r["start"][2]), math.cos(r["start"][2]))
    return parse_scenario(raw, source=f"<team of {robots}>")


_MODELS: dict[str, Any] = {}


def _one(args) -> dict[str, Any]:
    robots, seed, controller, duration, model_path = args
    from ..models.io import load_model

    model = None
    if controller == "cekm":  # one load per process
        model = _MODELS.get(model_path) or _MODELS.setdefault(model_path, load_model(model_path))
    sc = team_scenario(robots, seed)
    run = run_tracking(sc, controller, model, seed, duration)
    return {"robots": robots, "seed": seed, "controller": controller, "A": run.tracking["A"],
            "targets": run.tracking["targets"], "run": run if seed == 1 else None}


def mean_ci95(xs: list[float]) -> dict[str, Any]:
    """Mean and a 95 % t interval."""
    from scipy import stats

    a = np.asarray(xs, dtype=float)
    m = float(a.mean())
    if len(a) < 2:
        return {"mean": m, "ci95": [m, m], "n": len(a)}
    h = float(stats.t.ppf(0.975, len(a) - 1) * a.std(ddof=1) / math.sqrt(len(a)))
    return {"mean": m, "ci95": [m - h, m + h], "n": len(a)}


def run_experiment(sizes: tuple[int, ...], seeds: int, duration: float, model_path, workers: int | None = None,
                   progress: bool = True) -> tuple[dict[str, Any], dict[str, TrackingRun]]:
    """Every controller on the same seeds (1..seeds) for every team size."""
    import os
    from concurrent.futures import ProcessPoolExecutor

    from tqdm import tqdm

    jobs = [(n, s, c, duration, str(model_path)) for n in sizes for s in range(1, seeds + 1) for c in CONTROLLERS]
    workers = workers or max(1, min(len(jobs), os.cpu_count() or 1))
    rows = []
    if workers == 1:  # in this process (no pool to start)
        for job in tqdm(jobs, disable=not progress, desc="tracking runs"):
            rows.append(_one(job))
    else:
        with ProcessPoolExecutor(workers) as ex:
            for row in tqdm(ex.map(_one, jobs), total=len(jobs), disable=not progress, desc="tracking runs"):
                rows.append(row)
    pictures = {}
    configs = []
    for n in sizes:
        sub = [r for r in rows if r["robots"] == n]
        conf: dict[str, Any] = {"robots": n, "targets": sub[0]["targets"], "controllers": {}}
        for c in CONTROLLERS:
            a = [r["A"] for r in sub if r["controller"] == c]
            conf["controllers"][c] = {"A": mean_ci95(a), "per_seed": a}
            for r in sub:
                if r["controller"] == c and r["run"] is not None and n == sizes[0]:
                    pictures[c] = r["run"]
        configs.append(conf)
    return {"configs": configs, "seeds": list(range(1, seeds + 1)), "duration_s": duration,
            "arena_rule": "square arena, side 2 m * sqrt(robots / 2); round(1.5 * robots) random-walk targets "
                          "(0.05 m/s, turn noise 1 rad/sqrt(s)); target sensing range 0.5 m"}, pictures


def parse_team_sizes(text: str) -> tuple[int, ...]:
    """``--robots 2,4,8`` as team sizes; a clear usage error otherwise."""
    import click

    try:
        sizes = tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise click.UsageError(f"--robots {text!r}: expected team sizes like 2,4,8") from None
    if not sizes or any(n < 1 or n > 64 for n in sizes):
        raise click.UsageError(f"--robots {text!r}: give team sizes between 1 and 64")
    return sizes


def run_tracking_experiment_cmd(out_dir, seeds: int, sizes: tuple[int, ...], duration: float, model_path, workers,
                                quiet: bool) -> None:
    """``cekm experiment tracking`` once its options are checked."""
    import time

    import click

    if model_path is None:
        from .default_model import default_model, default_model_path

        default_model()
        model_path = default_model_path()
    t0 = time.perf_counter()
    doc, pictures = run_experiment(sizes, seeds, duration, model_path, workers, progress=not quiet)
    doc["wall_seconds"] = round(time.perf_counter() - t0, 1)
    paths = write_experiment(doc, pictures, out_dir)
    click.echo(table_markdown(doc))
    click.echo(f"{doc['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in paths))


def write_experiment(doc: dict[str, Any], pictures: dict[str, TrackingRun], out_dir) -> list:
    """results.json, tables.md, tracking.png, one Fig.-13 picture per controller."""
    import json
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    (out / "results.json").write_text(json.dumps(doc, indent=1))
    written.append(out / "results.json")
    (out / "tables.md").write_text(table_markdown(doc))
    written.append(out / "tables.md")
    fig, ax = plt.subplots(figsize=(6, 4))
    sizes = [c["robots"] for c in doc["configs"]]
    for i, ctl in enumerate(CONTROLLERS):
        ms = [c["controllers"][ctl]["A"]["mean"] for c in doc["configs"]]
        lo = [c["controllers"][ctl]["A"]["ci95"][0] for c in doc["configs"]]
        hi = [c["controllers"][ctl]["A"]["ci95"][1] for c in doc["configs"]]
        x = np.array(sizes, dtype=float) * (1 + 0.02 * (i - 1))
        ax.errorbar(x, ms, yerr=[np.subtract(ms, lo), np.subtract(hi, ms)], marker="o", capsize=3, label=ctl)
    ax.set_xscale("log", base=2)
    ax.set_xticks(sizes)
    ax.set_xticklabels([str(s) for s in sizes])
    ax.set_xlabel("robots (arena and targets grow with the team)")
    ax.set_ylabel("A (fraction of targets observed)")
    ax.set_ylim(0, 1)
    ax.legend()
    ax.set_title(f"Parker's A, mean and 95 % interval over {len(doc['seeds'])} seeds")
    fig.tight_layout()
    fig.savefig(out / "tracking.png", dpi=120)
    plt.close(fig)
    written.append(out / "tracking.png")
    for ctl, run in pictures.items():
        fig = plot_tracking(run)
        fig.savefig(out / f"fig13_{ctl}.png", dpi=120)
        plt.close(fig)
        written.append(out / f"fig13_{ctl}.png")
    return written


def table_markdown(doc: dict[str, Any]) -> str:
    lines = ["| robots | targets | " + " | ".join(f"A {c}" for c in CONTROLLERS) + " |",
             "|---:|---:|" + "---:|" * len(CONTROLLERS)]
    for c in doc["configs"]:
        cells = []
        for ctl in CONTROLLERS:
            a = c["controllers"][ctl]["A"]
            cells.append(f"{a['mean']:.3f} [{a['ci95'][0]:.3f}, {a['ci95'][1]:.3f}]")
        lines.append(f"| {c['robots']} | {c['targets']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
