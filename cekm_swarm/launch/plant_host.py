"""``cekm launch SCENARIO --plant ros2``: the launcher's side of a run whose robots live in
ROS 2 (docs/ros2.md, "Driving a ROS 2 robot"). The graph's nodes start as in a real-time
launch; in the world server's place the ROS 2 plant process
(:mod:`cekm_swarm.ros2.plant_server`) starts, fed ``OUT/plant.json``: the robots and their
goals from the scenario, the robot description, the ROS domain and distribution.

The robot's body is declared (``--robot-description FILE``; default: the scenario's
simulated body). When the graph reads a model, a body other than the one the model was
trained for (the simulated Khepera of the scenario) is refused before anything starts."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from cekm_swarm.errors import CekmError
from cekm_swarm.robot import RobotBody
from cekm_swarm.ros2.plant import RobotDescription, check_body, load_description
from cekm_swarm.ros2.plant_server import PlantConfig
from world import World, load_scenario

from .prepare import body_of

PLANTS = ("ros2",)


def plant_description(scenario: Any, description: Path | None, trained: RobotBody, uses_model: bool,
                      task: str) -> RobotDescription:
    """The robot description of a ``--plant ros2`` run, checked (when the graph reads a
    model) against the body the model was trained for. ``task``: navigation or tracking
    (whose targets come on ``/targets``)."""
    desc = RobotDescription(trained) if description is None else load_description(description, trained)
    if uses_model:
        check_body(desc.body, trained, str(description) if description else scenario.name)
    return desc


def goals_of(scenario: Any) -> tuple[dict[str, list[float] | None], dict[str, str]]:
    """Each robot's goal (x, y) from the scenario (None: it takes one from ``goal_pose``) and its target id."""
    targets = {t.id: t for t in scenario.targets}
    goals: dict[str, list[float] | None] = {}
    ids: dict[str, str] = {}
    for r in scenario.robots:
        if r.goal is None:
            goals[r.id] = None
            continue
        goals[r.id] = [float(targets[r.goal].position[0]), float(targets[r.goal].position[1])]
        ids[r.id] = r.goal
    return goals, ids


def plant_argv(launcher: Any, where: str, hosts_router: bool) -> list[str]:
    """Write ``OUT/plant.json`` for ``launcher``'s run and return the plant's command line."""
    c = launcher.c
    sc = load_scenario(c.scenario)
    goals, ids = goals_of(sc)
    cfg = PlantConfig(scenario=sc.name, seed=sc.seed if c.seed is None else c.seed, robots=goals,
                      description=launcher.plant_desc.to_dict(), out=str(c.out), spec=str(launcher.spec_path),
                      root=c.root, run_id=launcher.run_id, domain=c.plant_domain, distro=c.plant_distro,
                      listen=where if hosts_router else None, connect=None if hosts_router else where,
                      zenoh_config=None if hosts_router or c.zenoh_config is None else str(c.zenoh_config),
                      max_time=float(c.max_time), deadman=c.deadman, wait_modules=c.alive_timeout,
                      progress_every=c.progress_every, geometry=World(sc).static_geometry(), goal_ids=ids,
                      task=launcher.task, target_ids=[t.id for t in sc.targets] if launcher.task == "tracking" else [])
    path = cfg.write(c.out / "plant.json")
    return [sys.executable, "-m", "cekm_swarm.ros2.plant_server", str(path)]


def refuse_plant(scenario: Any, checked: Any, task: str, mode: str, description: Path | None) -> None:
    """``cekm launch --plant ros2``'s checks before anything is written or started, each a
    one-line usage error: a real-time run, a readable description whose body fits the model."""

    if mode != "realtime":
        raise click.UsageError("--plant ros2 runs in real time (a robot does not wait for lockstep ticks): "
                               "leave out --mode lockstep")
    try:
        plant_description(scenario, description, body_of(scenario), checked.uses_model, task)
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
