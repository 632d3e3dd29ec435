"""Before anything starts: the controller's graph for the scenario, checked (its programs
imported, its parameters and ports checked, resolved for the team), one node of every
kind built in the launcher's own process (so a bad model or parameter is refused here,
in one line, as ``cekm run`` refuses it, not by processes that die and restart), and the
run spec every process of the launch reads (``OUT/run-spec.json``)."""

from __future__ import annotations

import logging
import socket
from pathlib import Path
from typing import Any

from cekm_swarm.errors import CekmError
from cekm_swarm.experiments.graph_run import resolve_graph, robot_body, with_params
from cekm_swarm.graph.plan import RunPlan
from cekm_swarm.graph.runspec import RunSpec
from cekm_swarm.graph.spec import GraphError
from cekm_swarm.node.api import Context, cannot_start, traceback_text
from cekm_swarm.node.graph_check import CheckedGraph
from cekm_swarm.protocol import KeySpace
from cekm_swarm.protocol.user import user_schemas
from cekm_swarm.robot import RobotBody


class PreflightError(CekmError):
    """A node of the graph cannot start as configured (bad model, bad parameter); ``trace``
    is the traceback of the node's code that raised, for the launch's log."""

    def __init__(self, line: str, trace: str = "") -> None:
        super().__init__(line)
        self.trace = trace


def resolve(scenario: Any, controller: str | None, graph: str | Path | None,
            params: dict[str, Any] | None = None) -> tuple[CheckedGraph, str]:
    """The checked graph of ``--controller``/``--graph`` for the scenario, and the task."""
    from world.tracking import run_kind  # noqa: PLC0415 -- lazy: pymunk, world

    task = run_kind(scenario)
    return with_params(resolve_graph(controller, None if graph is None else str(graph), task), params), task


def body_of(scenario: Any) -> RobotBody:
    """What a robot's nodes know of their body and sensors, from the scenario's world."""
    from world import World  # noqa: PLC0415 -- lazy: pymunk, world

    return robot_body(World(scenario))


def preflight(checked: CheckedGraph, plan: RunPlan, body: RobotBody, model: Any) -> None:
    """Build one node of every kind (its first instance of the first robot) here: what a
    node process would do first. Raises :class:`PreflightError` with the node's reason."""
    robot = plan.team[0]
    if model is not None:  # the run's model first: a bad file is the run's fault, named as `cekm run` names it
        try:
            Context(robot, "model", None, plan.team, body, "check", model, "numpy").model()
        except (CekmError, ValueError) as exc:
            raise PreflightError(str(exc)) from None
    seen: set[str] = set()
    for node in plan.nodes[robot]:
        name = node.decl.name
        if name in seen:
            continue
        seen.add(name)
        ctx = Context(robot, name, node.instance, plan.team, body, "check", model, "numpy",
                      logging.getLogger(f"cekm_swarm.node.{name}"))
        try:
            checked.classes[name](ctx, checked.make_params(name)).close()
        except Exception as exc:  # noqa: BLE001 - a user's node may fail in any way while starting
            raise PreflightError(cannot_start(node.label, exc), traceback_text(exc)) from None


def run_spec(checked: CheckedGraph, team: tuple[str, ...], task: str, body: RobotBody, **settings: Any) -> RunSpec:
    """The run spec of a launch (see :mod:`cekm_swarm.graph.runspec`)."""
    types = [t for cls in checked.classes.values()
             for t in (*(p.type for p in cls.inputs.values()), *(p.type for p in cls.outputs.values()))]
    return RunSpec(checked.graph, dict(checked.ports), {k: dict(v) for k, v in checked.params.items()}, tuple(team),
                   task, body, **settings, schemas=user_schemas(types))


def plan_of(checked: CheckedGraph, team: tuple[str, ...], task: str, body: RobotBody, root: str,
            run_id: str | None = None) -> RunPlan:
    try:
        return checked.plan(team, task, body.sensors, KeySpace(root, body.sensors, run_id))
    except GraphError:
        raise


def port_taken(host: str, port: int) -> str | None:
    """Why the embedded router could not listen on ``host:port`` (the OS's words, say
    "Address already in use"), None when it could: probed by binding it a moment, as the
    router would (a race with another program remains, and the launch then says so)."""
    family = socket.AF_INET6 if ":" in host.strip("[]") else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host.strip("[]"), port))
            s.listen(1)
        except OSError as exc:
            return exc.strerror or str(exc)
    return None
