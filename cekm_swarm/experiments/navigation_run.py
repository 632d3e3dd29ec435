"""Section 4.2 in one process: a scenario and a controller's graph (cooperative EKMs or
command fusion) run by :func:`.graph_run.run_graph`, the results as a
:class:`NavigationRun`, and a run stopped at one instant for Fig. 4's activities
(:func:`fields_at`). The pictures of both are :mod:`.navigation_figures`'.
"""

from __future__ import annotations

import copy
import functools
from dataclasses import asdict, dataclass, field

import numpy as np

from cekm_swarm.ticks import TICK_S, tick_of

from ..controller.cooperative import CooperativeEKM
from ..controller.planner import PlanningError, plan_checkpoints
from ..errors import ParameterError
from ..models.params import FieldParams
from ..modules.motor_integration import MotorIntegration, target_activity
from .graph_run import run_graph
from .learning_run import learning_outcome

CONTROLLERS = ("cekm", "fusion")
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
                 fields: FieldParams | None = None, progress=None, graph=None) -> NavigationRun:
    """Run a scenario to the end (every robot reached its goal, or max_time) with the
    controller's graph in one process (:func:`.graph_run.run_graph`; a distributed
    lockstep run computes the same, bit for bit).

    ``use_checkpoints``: plan checkpoints on the known walls (Fig. 12); default: the
    scenario's ``plan_checkpoints``. ``fields``: the field widths of the cooperative
    EKM's nodes (Eqs. 6, 8). ``graph``: a graph file instead of the controller's own.
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
    run = run_graph(scenario, controller, graph=graph, model=model, seed=seed, max_time=max_time,
                    checkpoints=checkpoints, params=field_overrides(fields), progress=progress)
    world, episode = run.world, run.episode
    logs = {}
    for r, p in episode.progress.items():
        t, x, y, th = (list(col) for col in zip(*p.path, strict=True))
        logs[r] = RobotLog(r, t, x, y, th, [c[0] for c in p.commands], [c[1] for c in p.commands],
                           list(p.checkpoints), list(p.checkpoint_times), p.reached, p.reached_time)

    return NavigationRun(scenario.name, controller, world_seed(world, seed, scenario), logs, episode.outcome(),
                         world.static_geometry(), world.state(), plan_paths,
                         learning_outcome(run.executor, world.robot_ids, model))


def field_overrides(fields: FieldParams | None) -> dict | None:
    """Field widths as parameters of the nodes that take them (a graph without such nodes,
    command fusion's, ignores them)."""
    if fields is None:
        return None

    return {"lenient": True, **asdict(fields)}


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
              fields: FieldParams | None = None) -> dict:
    """Run the cooperative EKM to sim time ``at_time`` and return the activities of Fig. 4:
    the target field, each obstacle field, the combined obstacle fields and the integrated
    activity, with the winners, the robot's pose and the input weights."""

    checkpoints = planned(scenario)[0] if scenario.plan_checkpoints else None
    last = tick_of(at_time)
    run = run_graph(scenario, "cekm", model=model, seed=controller_seed, checkpoints=checkpoints,
                    params=field_overrides(fields), stop_at=last, max_time=max(at_time, TICK_S) + 1.0)
    world, episode, ex = run.world, run.episode, run.executor
    robot = robot or world.robot_ids[0]
    k, keys = episode.tick, run.plan.keys
    target = ex.output(keys.field_target(robot), k - k % 2)
    n = model.w.shape[0]
    a = target.a if target is not None and target.a is not None else np.zeros(n)
    obs_fields = {j: ex.output(keys.field_obstacle(robot, j), k) for j in range(len(world.sensor_angles))}
    obstacle = {j: f.b for j, f in sorted(obs_fields.items()) if f is not None and f.b is not None}
    combined = np.sum(list(obstacle.values()), axis=0) if obstacle else np.zeros(n)
    e = a - combined
    motor = ex.node(robot, "motor")
    if not isinstance(motor, MotorIntegration):
        raise TypeError(f"{robot}'s motor node is a {type(motor).__name__}, not cekm's motor integration: "
                        f"cekm fields draws the cekm controller's fields")
    ekm: CooperativeEKM = motor.ekm

    decision = ekm.integrate(target_activity(target), [f for f in obs_fields.values() if f is not None])
    return {"time": episode.t, "robot": robot, "pose": world.pose(robot), "w": model.w.copy(),
            "a": a, "s": None if target is None else target.winner, "obstacle": obstacle,
            "obstacle_winners": {j: f.winner for j, f in obs_fields.items() if f is not None and f.winner is not None},
            "combined": combined, "e": e, "k": decision.k, "eligible": ekm.eligible.copy(),
            "command": (decision.v_l, decision.v_r), "sensor_angles": world.sensor_angles.copy(),
            "geometry": world.static_geometry(), "state": world.state()}
