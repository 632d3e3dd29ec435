"""Section 4.2 in one process: a scenario and a controller's graph (cooperative EKMs or
command fusion) run by :func:`.graph_run.run_graph`, the results as a
:class:`NavigationRun`, and a run stopped at one instant for Fig. 4's activities
(:func:`fields_at`). The pictures of both are :mod:`.navigation_figures`'.
"""

from __future__ import annotations

import copy
import functools
from dataclasses import dataclass, field

import numpy as np

from cekm_swarm.ticks import TICK_S, tick_of

from ..controller.cooperative import CooperativeEKM
from ..controller.planner import PlanningError, plan_checkpoints
from ..errors import ParameterError
from .field_widths import fields_graph
from .graph_run import run_graph, with_params
from .learning_run import learning_outcome

CONTROLLERS = ("cekm", "cekm-tuned", "fusion")
DEFAULT_MAX_TIME = 600.0  # s of sim time before a robot counts as trapped


@dataclass
class RobotLog:
    """One robot's run: its path at every tick and what happened."""

    robot: str
    t: list[float] = field(default_factory=list)
    x: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    theta: list[float] = field(default_factory=list)
    v_l: list[float] = field(default_factory=list)
    v_r: list[float] = field(default_factory=list)
    checkpoints: list[tuple[float, float]] = field(default_factory=list)
    checkpoint_times: list[float] = field(default_factory=list)
    reached: bool = False
    reached_time: float | None = None


@dataclass
class NavigationRun:
    scenario: str
    controller: str
    seed: int
    logs: dict[str, RobotLog]
    outcome: dict[str, dict]
    geometry: dict
    final_state: dict
    plan_paths: dict[str, list] = field(default_factory=dict)
    learning: dict[str, dict] = field(default_factory=dict)  # per robot with a learner (docs/learning.md)


def run_scenario(scenario, controller: str = "cekm", model=None, seed: int | None = None,
                 max_time: float = DEFAULT_MAX_TIME, use_checkpoints: bool | None = None,
                 fields: str | None = None, progress=None, graph=None) -> NavigationRun:
    """Run a scenario to the end (every robot reached its goal, or max_time) with the
    controller's graph in one process (:func:`.graph_run.run_graph`; a distributed
    lockstep run computes the same, bit for bit).

    ``use_checkpoints``: plan checkpoints on the known walls (Fig. 12); default: the
    scenario's ``plan_checkpoints``. ``fields``: cekm's field widths (``--fields``:
    paper, tuned or learned, :mod:`.field_widths`); None runs the controller's graph as
    shipped. ``graph``: a graph file instead of the controller's own.
    ``progress(t)`` is called every simulated second.
    """

    if graph is None and controller not in CONTROLLERS:
        raise ParameterError(f"unknown controller {controller!r}; expected one of {list(CONTROLLERS)}")
    if model is None:
        from .default_model import default_model  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

        model = default_model()
    if use_checkpoints is None:
        use_checkpoints = scenario.plan_checkpoints
    checkpoints, plan_paths = planned(scenario) if use_checkpoints else (None, {})
    run = run_graph(scenario, controller, graph=cekm_graph(controller, fields, graph), model=model, seed=seed,
                    max_time=max_time, checkpoints=checkpoints, progress=progress)
    world, episode = run.world, run.episode
    logs = {}
    for r, p in episode.progress.items():
        t, x, y, th = (list(col) for col in zip(*p.path, strict=True))
        logs[r] = RobotLog(r, t, x, y, th, [c[0] for c in p.commands], [c[1] for c in p.commands],
                           list(p.checkpoints), list(p.checkpoint_times), p.reached, p.reached_time)

    return NavigationRun(scenario.name, controller, world_seed(world, seed, scenario), logs, episode.outcome(),
                         world.static_geometry(), world.state(), plan_paths,
                         learning_outcome(run.executor, world.robot_ids, model))


def cekm_graph(controller: str, fields: str | None, graph=None):
    """The graph a run takes: ``graph`` if given, else with ``fields`` cekm's graph with
    those field widths (:func:`.field_widths.fields_graph`), else None (the controller's
    own)."""
    if graph is not None or fields is None:
        return graph
    if controller != "cekm":
        raise ParameterError(f"field widths ({fields}) go with controller 'cekm', not {controller!r}")
    return with_params(*fields_graph(fields, "navigation"))


def plan_all(world, geometry, source: str = "scenario") -> tuple[dict, dict]:
    """Checkpoints for every robot from its start to its goal, on the known walls (Fig. 12).
    Raises :class:`PlanningError` naming ``source`` (the scenario file) and the robot when
    the known walls leave a robot no path."""
    checkpoints, paths = {}, {}
    for i, r in enumerate(world.robot_ids):
        x, y, _ = world.pose(r)
        try:
            plan = plan_checkpoints(geometry, (x, y), world.goal_of(r), body_radius=world.body_radius)
        except PlanningError as exc:
            raise PlanningError(f"{source}: robots[{i}].goal: {exc} (plan_checkpoints = true needs one for every "
                                f"robot)") from None
        checkpoints[r], paths[r] = plan.checkpoints, plan.path
    return checkpoints, paths


def planned(scenario) -> tuple[dict, dict]:
    """:func:`plan_all` of ``scenario`` (its start poses and goals on its known walls, which
    no seed changes), planned once: the command's early check, the run and a launch each
    want it, and a plan takes about a second. A copy, so no caller changes the next one's."""
    return copy.deepcopy(_planned(scenario))


@functools.lru_cache(maxsize=4)
def _planned(scenario) -> tuple[dict, dict]:
    from world import World  # noqa: PLC0415 -- lazy: pymunk, world

    world = World(scenario)
    return plan_all(world, world.static_geometry(), scenario.source)


def planned_checkpoints(scenario) -> dict[str, list[list[float]]]:
    """The checkpoints of a ``plan_checkpoints`` scenario as plain data (what a launch hands
    the world server), or raises :class:`PlanningError` as :func:`plan_all`."""
    return {r: [list(map(float, c)) for c in cps] for r, cps in planned(scenario)[0].items()}


def world_seed(world, seed, scenario) -> int:
    return int(seed if seed is not None else scenario.seed)


def fields_at(scenario, model, at_time: float, controller_seed: int | None = None, robot: str | None = None,
              fields: str | None = None) -> dict:
    """Run the cooperative EKM to sim time ``at_time`` and return the activities of Fig. 4:
    the target field, each obstacle field, the combined obstacle fields and the integrated
    activity, with the winners, the robot's pose and the input weights. The fields are the
    ones the motor node integrated at that tick: with learned widths (``fields``, as
    :func:`run_scenario`), the widths its policy chose."""

    checkpoints = planned(scenario)[0] if scenario.plan_checkpoints else None
    last = tick_of(at_time)
    run = run_graph(scenario, "cekm", graph=cekm_graph("cekm", fields), model=model, seed=controller_seed,
                    checkpoints=checkpoints, stop_at=last, max_time=max(at_time, TICK_S) + 1.0)
    world, episode, ex = run.world, run.episode, run.executor
    robot = robot or world.robot_ids[0]
    motor = ex.node(robot, "motor")
    ekm, integrated = getattr(motor, "ekm", None), getattr(motor, "integrated", None)
    if not isinstance(ekm, CooperativeEKM) or integrated is None:
        raise TypeError(f"{robot}'s motor node is a {type(motor).__name__}, not a cooperative EKM's motor "
                        f"integration that has run: cekm fields draws the cekm controller's fields")
    target, obs_fields = integrated
    n = model.w.shape[0]
    a = target.a if target is not None and target.a is not None else np.zeros(n)
    obstacle = {f.index: f.b for f in obs_fields if f.b is not None}
    combined = np.sum(list(obstacle.values()), axis=0) if obstacle else np.zeros(n)
    e = a - combined
    decision = ekm.integrate(target, obs_fields)
    return {"time": episode.t, "robot": robot, "pose": world.pose(robot), "w": model.w.copy(),
            "a": a, "s": None if target is None else target.winner, "obstacle": obstacle,
            "obstacle_winners": {f.index: f.winner for f in obs_fields if f.winner is not None},
            "combined": combined, "e": e, "k": decision.k, "eligible": ekm.eligible.copy(),
            "command": (decision.v_l, decision.v_r), "sensor_angles": world.sensor_angles.copy(),
            "geometry": world.static_geometry(), "state": world.state()}
