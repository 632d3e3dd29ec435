"""Multi-robot tracking (Fig. 13) in one process, and running the experiment over team sizes.

A run is the controller's graph (cooperative EKMs, A-CMOMMT, or robots that stay) on a
tracking scenario, run by :func:`.graph_run.run_graph` with the world server's tracking
episode (:class:`world.tracking.TrackingEpisode`): at tick k each robot's nodes see the
world's readings of tick k and their teammates' shares of their previous run (the rule
of :mod:`cekm_swarm.graph.plan`). Parker's A is sampled at every tick before the readings.

The experiment's statistics are :mod:`.tracking_stats`'s, its pictures
:mod:`.tracking_figures`', its files :mod:`.tracking_report`'s and its command
:mod:`.commands`'.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from world.scenario import parse_scenario
from world.tracking import is_tracking

from ..errors import ParameterError
from ..models.io import load_model
from ..models.params import ACMOMMTParams, TrackingParams
from .engine import run_jobs
from .graph_run import run_graph
from .tracking_stats import team_stats

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
    graph: str | None = None
    robots: dict[str, dict] = field(default_factory=dict)  # outcome.json's per-robot block, the world's

    @property
    def collisions(self) -> dict[str, int]:
        """Each robot's collisions (from its block in :attr:`robots`)."""
        return {r: int(o["collisions"]) for r, o in self.robots.items()}


def run_tracking(scenario, controller: str = "cekm", model=None, seed: int | None = None,
                 duration: float = DEFAULT_DURATION, tparams: TrackingParams | None = None,
                 aparams: ACMOMMTParams | None = None, graph=None) -> TrackingRun:
    """Run a tracking scenario for ``duration`` s of sim time with the controller's graph
    in one process (:func:`.graph_run.run_graph`; a distributed lockstep run computes the
    same, bit for bit). ``tparams``/``aparams``: the tracking controllers' parameters."""

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
    return TrackingRun(scenario.name, controller, int(seed if seed is not None else scenario.seed), paths,
                       run.target_paths, episode.meter.summary(), world.static_geometry(), world.state(),
                       world.target_range, run.plan.graph.name, episode.outcome())


def outcome_doc(run: TrackingRun) -> dict[str, Any]:
    """``outcome.json`` of a tracking run (its per-robot block the world's own, as the world
    server writes it: :meth:`world.tracking.TrackingEpisode.outcome`)."""
    return {"scenario": run.scenario, "controller": run.controller, "graph": run.graph, "seed": run.seed,
            "robots": run.robots, "tracking": run.tracking}


# --------------------------------------------------------------------------- team sizes


def team_scenario(robots: int, seed: int, targets_per_robot: float = 1.5,
                  side_per_sqrt_robot: float = 2.0 / math.sqrt(2),
                  target_range: float = 0.5, speed: float = 0.05, turn_noise: float = 1.0):
    """A tracking scenario for a team of ``robots``: a square walled arena whose area grows
    with the team (side = side_per_sqrt_robot * sqrt(robots): 2 m for 2 robots, as
    tracking.toml), round(targets_per_robot * robots) random-walk targets at uniform
    starts, robots in a ring around the centre. Densities of robots and targets are the
    same for every size, so A compares across sizes. ``seed`` draws the starts and the world."""
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
    robots, seed, controller, duration, model_path, keep_run = args

    model = None
    if controller == "cekm":  # one load per process
        model = _MODELS.get(model_path) or _MODELS.setdefault(model_path, load_model(model_path))
    sc = team_scenario(robots, seed)
    run = run_tracking(sc, controller, model, seed, duration)
    return {"robots": robots, "seed": seed, "controller": controller, "A": run.tracking["A"],
            "targets": run.tracking["targets"], "run": run if keep_run else None}


def run_experiment(sizes: tuple[int, ...], seeds: int, duration: float, model_path, workers: int | None = None,
                   progress: bool = True, first_seed: int = 1) -> tuple[dict[str, Any], dict[str, TrackingRun]]:
    """Every controller on the same seeds (first_seed .. first_seed + seeds - 1) for every
    team size; the pictures are the first seed's runs of the smallest team."""
    seed_list = list(range(first_seed, first_seed + seeds))
    jobs = [(n, s, c, duration, str(model_path), n == sizes[0] and s == first_seed)
            for n in sizes for s in seed_list for c in CONTROLLERS]
    rows = run_jobs(_one, jobs, workers, desc="tracking runs", progress=progress)
    pictures = {}
    for c in CONTROLLERS:  # the first team size's run of the first seed, per controller
        for r in rows:
            if r["robots"] == sizes[0] and r["controller"] == c and r["run"] is not None:
                pictures[c] = r["run"]
    configs = team_stats(rows, sizes, CONTROLLERS)
    return {"configs": configs, "seeds": seed_list, "duration_s": duration,
            "arena_rule": "square arena, side 2 m * sqrt(robots / 2); round(1.5 * robots) random-walk targets "
                          "(0.05 m/s, turn noise 1 rad/sqrt(s)); target sensing range 0.5 m"}, pictures
