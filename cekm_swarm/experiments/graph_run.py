"""``cekm run``: a scenario and a controller's graph in one process.

The world's side of every tick is the world server's (:class:`world.episode.Episode` for
navigation, :class:`world.tracking.TrackingEpisode` for tracking; the sense messages of
:mod:`world.sense` and :func:`world.tracking.tracking_sense`); the robots' side is the
graph's nodes, run by :class:`cekm_swarm.node.inprocess.GraphExecutor` by the same rule
a lockstep run's processes follow. This module is where the two sides meet, as the
message protocol: the controller never imports the world, and the world never imports
the controller.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..errors import ParameterError
from ..graph.spec import Graph, GraphError, graph_for, shipped_graphs
from ..node.api import Context, param_fields
from ..node.graph_check import CheckedGraph, check_graph
from ..node.inprocess import GraphExecutor
from ..protocol import DEFAULT_KEYS, Clock, KeySpace, WorldState
from ..robot import RobotBody
from ..ticks import STEP_TIMEOUT, TICK_S

DEFAULT_MAX_TIME = {"navigation": 600.0, "tracking": 120.0}
"""Sim seconds of a run unless told otherwise, by task: the same for ``cekm run`` and
``cekm launch`` (a navigation run ends sooner when every robot is at its goal)."""


def default_max_time(task: str) -> float:
    return DEFAULT_MAX_TIME[task]


def resolve_graph(controller: str | None, graph: str | Graph | CheckedGraph | None, task: str) -> CheckedGraph:
    """The checked graph of ``--controller NAME`` (its shipped graph for the task) or ``--graph FILE``."""
    if isinstance(graph, CheckedGraph):
        return graph
    if graph is not None:
        return check_graph(graph)
    return check_graph(str(graph_for(controller or "cekm", task)))


def with_params(checked: CheckedGraph, overrides: dict[str, Any] | None) -> CheckedGraph:
    """``checked`` with ``overrides`` given to every node that declares them (like the
    graph's ``[params]``); a name no node declares is a ParameterError, unless the
    overrides say ``lenient = True`` (a whole parameter set handed to any graph)."""
    if not overrides:
        return checked

    overrides = dict(overrides)
    lenient = overrides.pop("lenient", False)

    used: set[str] = set()
    params = {}
    for name, cls in checked.classes.items():
        declared = param_fields(cls)
        values = dict(checked.params[name])
        for k, v in overrides.items():
            if k in declared:
                values[k] = v
                used.add(k)
        params[name] = values
    unused = sorted(set(overrides) - used)
    if unused and not lenient:
        raise ParameterError(f"no node of graph {checked.graph.name!r} has a parameter {unused[0]!r}")
    out = CheckedGraph(checked.graph, checked.classes, checked.ports, params)
    for name in out.classes:
        out.make_params(name)  # checks the values
    return out


def robot_body(world) -> RobotBody:
    """What a robot's nodes know of their body and sensors, from the world."""
    return RobotBody(world.body_radius, world.axle, world.v_max, world.sensor_range,
                     tuple(float(a) for a in world.sensor_angles), world.target_range)


@dataclass
class GraphRun:
    """One finished in-process run: the world, its episode, the plan and the executor."""

    world: Any
    episode: Any
    plan: Any
    executor: GraphExecutor
    task: str
    ticks: int
    target_paths: dict[str, list[tuple[float, float]]] = field(default_factory=dict)


def run_graph(scenario, controller: str | None = "cekm", *, graph: str | Graph | CheckedGraph | None = None,
              model=None, seed: int | None = None, max_time: float | None = None, checkpoints=None,
              params: dict[str, Any] | None = None, progress: Callable[[float], None] | None = None,
              stop_at: int | None = None, codec: bool = False, keys: KeySpace = DEFAULT_KEYS,
              step_timeout: float | None = STEP_TIMEOUT,
              observe: Callable[[GraphExecutor, int], None] | None = None) -> GraphRun:
    """Run ``scenario`` with a controller's graph to the end (navigation: every robot at
    its goal, or ``max_time``; tracking: ``max_time``). ``stop_at``: stop after computing
    that tick (for a look at the fields, Fig. 4). ``progress(t)`` every simulated second.
    ``step_timeout``: wall seconds a step may run before the run fails naming it.
    ``observe(executor, k)`` after each tick (a learning experiment's scores, docs/learning.md)."""
    session = GraphSession(scenario, controller, graph=graph, model=model, seed=seed, max_time=max_time,
                           checkpoints=checkpoints, params=params, codec=codec, keys=keys, step_timeout=step_timeout,
                           observe=observe)
    while not session.step(progress, stop_at):
        pass
    return session.result()


class GraphSession:
    """A :func:`run_graph` run one tick at a time (:meth:`step`), for a caller that acts
    between ticks (the field-parameter environments, :mod:`cekm_swarm.tune.env` and
    :mod:`cekm_swarm.tune.team_env`, through :mod:`cekm_swarm.tune.env_core`): the same
    world, the same graph, the same order of messages, so stepping to the end is
    :func:`run_graph`."""

    def __init__(self, scenario, controller: str | None = "cekm", *, graph: str | Graph | CheckedGraph | None = None,
                 model=None, seed: int | None = None, max_time: float | None = None, checkpoints=None,
                 params: dict[str, Any] | None = None, codec: bool = False, keys: KeySpace = DEFAULT_KEYS,
                 step_timeout: float | None = STEP_TIMEOUT,
                 observe: Callable[[GraphExecutor, int], None] | None = None) -> None:
        from world import World  # noqa: PLC0415 -- lazy: pymunk, world
        from world.run_episode import make_episode  # noqa: PLC0415 -- lazy: pymunk, world
        from world.tracking import run_kind  # noqa: PLC0415 -- lazy: pymunk, world

        task = run_kind(scenario, checkpoints or {})
        checked = with_params(resolve_graph(controller, graph, task), params)
        if max_time is None:
            max_time = default_max_time(task)
        world = World(scenario, seed=seed)
        team = tuple(world.robot_ids)
        plan = checked.plan(team, task, len(world.sensor_angles), keys)
        if checked.uses_model and model is None:
            from .default_model import default_model  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

            model = default_model()
        body = robot_body(world)

        def context(node) -> Context:
            return Context(node.robot, node.decl.name, node.instance, team, body, "inprocess", model, "numba")

        self.task, self.world, self.plan, self.keys = task, world, plan, keys
        self.executor = GraphExecutor(plan, checked, context, codec=codec, step_timeout=step_timeout)
        self.max_ticks = int(math.ceil(max_time / TICK_S))
        self.episode = make_episode(world, task, checkpoints, self.max_ticks)
        self.reads = {r: set(plan.world_keys(r)) for r in team}
        self.read_clock = any(n.clock_key is not None or any(s.key == keys.world_clock() for b in n.bindings
                                                             for s in b.sources)
                              for r in team for n in plan.nodes[r])
        self.read_state = any(s.key == keys.world_state() for r in team for n in plan.nodes[r] for b in n.bindings
                              for s in b.sources)
        self.tpaths: dict[str, list[tuple[float, float]]] = {t: [] for t in getattr(world, "target_ids", [])}
        self.observe = observe
        self.finished = False

    def step(self, progress: Callable[[float], None] | None = None, stop_at: int | None = None) -> bool:
        """One tick: the world's messages, every node due, the wheels set, the world
        advanced unless the run is over. True when it is over."""
        from world.sense import SENDER, sense_messages  # noqa: PLC0415 -- lazy: pymunk, world

        episode, world, executor, keys = self.episode, self.world, self.executor, self.keys
        k, t = episode.tick, episode.t
        if progress and k % 8 == 0:
            progress(t)
        readings = episode.readings()
        if self.task == "tracking":
            st = world.state()
            for tid, p in st["targets"].items():
                self.tpaths.setdefault(tid, []).append((p["x"], p["y"]))
        for rd in readings:
            want = self.reads[rd.robot]
            for key, msg in sense_messages(keys, rd, world.sensor_angles, world.body_radius):
                if key in want:
                    executor.put(key, k, msg)
            for rel, msg in episode.messages(rd.robot):  # tracking: the robot's pose and targets
                executor.put(keys.node_key(rd.robot, rel), k, msg)
        if self.read_clock:
            executor.put(keys.world_clock(), k, Clock(t, SENDER, k))
        if self.read_state:
            st = world.state()
            executor.put(keys.world_state(), k, WorldState(t, SENDER, st["robots"], st["targets"], st["obstacles"]))
        answers = executor.tick(k)
        episode.apply({r: (c.v_l, c.v_r) for r, c in answers.items()})
        if self.observe is not None:
            self.observe(executor, k)
        if episode.done or episode.tick >= self.max_ticks or (stop_at is not None and k >= stop_at):
            self.finished = True
            return True
        episode.advance()
        return False

    def result(self) -> GraphRun:
        return GraphRun(self.world, self.episode, self.plan, self.executor, self.task, self.episode.tick, self.tpaths)


def controller_names() -> list[str]:
    """Every controller that has a shipped graph."""
    return sorted({n.rsplit("-", 1)[0] if n.endswith(("-navigation", "-tracking")) else n for n in shipped_graphs()})


def check_controller(controller: str, task: str) -> None:
    """ParameterError when ``controller`` has no shipped graph for ``task``."""
    try:
        graph_for(controller, task)
    except GraphError as exc:
        raise ParameterError(exc.problem) from None
