"""Section 4.2 in one process: a pymunk world and the robots' controllers, stepped in the
tick order of :mod:`cekm_swarm.controller.schedule` (the runtime's lockstep mode must
reproduce it exactly).

This module composes the two sides: it reads the world's sensors, hands the controllers
plain readings (the message protocol's content) and applies their wheel commands. The
controller modules never import the world, and the world never imports them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..controller.cooperative import CooperativeEKM, ObstacleActivity, TargetActivity
from ..controller.fusion import CommandFusion
from ..controller.planner import plan_checkpoints
from ..controller.readings import TargetReading, range_readings
from ..errors import ParameterError
from ..models.params import FieldParams

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
class RobotBrain:
    """Per robot: its controller and the latest output of every module."""

    kind: str
    controller: Any
    target: TargetActivity | None = None
    obstacles: dict[int, ObstacleActivity] = field(default_factory=dict)
    c_target: np.ndarray = field(default_factory=lambda: np.zeros(2))
    goal_state: bool = False

    def tick(self, t: float, target_reading: TargetReading | None, ranges) -> tuple[float, float]:
        """Steps 2-3 of a tick: the modules due compute, then the motor integrates the latest of each."""
        if self.kind == "cekm":
            ekm: CooperativeEKM = self.controller
            if target_reading is not None:
                self.target = ekm.localize_target(target_reading, t)
            for ob in ekm.localize_obstacles(ranges, t):
                self.obstacles[ob.index] = ob
            out = ekm.integrate(self.target, self.obstacles.values())
            self.goal_state = self.target is not None and self.target.at_goal
            return out.v_l, out.v_r
        fusion: CommandFusion = self.controller
        if target_reading is not None:
            self.c_target = fusion.target_command(target_reading)
            self.goal_state = target_reading.at_goal
        if self.goal_state:
            return 0.0, 0.0
        c = fusion.fuse(self.c_target, fusion.avoid_command(ranges))
        return float(c[0]), float(c[1])


def make_brain(kind: str, model, world_constants: dict, fields: FieldParams | None = None) -> RobotBrain:
    if kind == "cekm":
        return RobotBrain(kind, CooperativeEKM(model, fields or FieldParams()))
    if kind == "fusion":
        return RobotBrain(kind, CommandFusion(model, body_radius=world_constants["body_radius"],
                                              sensor_range=world_constants["sensor_range"]))
    raise ParameterError(f"unknown controller {kind!r}; expected one of {list(CONTROLLERS)}")


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


def run_scenario(scenario, controller: str = "cekm", model=None, seed: int | None = None,
                 max_time: float = DEFAULT_MAX_TIME, use_checkpoints: bool | None = None,
                 fields: FieldParams | None = None, progress=None) -> NavigationRun:
    """Run a scenario to the end (every robot reached its goal, or max_time).

    The world's side of every tick is :class:`world.episode.Episode` (the world server
    runs the same); the robots' side is their controllers. ``use_checkpoints``: plan
    checkpoints on the known walls (Fig. 12); default: when the scenario is called
    "checkpoints". ``progress(t)`` is called every simulated second.
    """
    from world import World
    from world.episode import TICK_S, Episode

    if controller not in CONTROLLERS:
        raise ParameterError(f"unknown controller {controller!r}; expected one of {list(CONTROLLERS)}")
    if model is None:
        from .default_model import default_model

        model = default_model()
    world = World(scenario, seed=seed)
    consts = {"body_radius": world.body_radius, "sensor_range": world.sensor_range}
    geometry = world.static_geometry()
    if use_checkpoints is None:
        use_checkpoints = scenario.name == "checkpoints"
    robots = list(world.robot_ids)
    brains = {r: make_brain(controller, model, consts, fields) for r in robots}
    checkpoints, plan_paths = plan_all(world, geometry) if use_checkpoints else (None, {})
    episode = Episode(world, checkpoints)
    max_ticks = int(math.ceil(max_time / TICK_S))
    while True:
        if progress and episode.tick % 8 == 0:
            progress(episode.t)
        control_tick(episode, brains)
        if episode.done or episode.tick >= max_ticks:
            break
        episode.advance()
    logs = {}
    for r, p in episode.progress.items():
        t, x, y, th = (list(col) for col in zip(*p.path))
        logs[r] = RobotLog(r, t, x, y, th, [c[0] for c in p.commands], [c[1] for c in p.commands],
                           list(p.checkpoints), list(p.checkpoint_times), p.reached, p.reached_time)
    return NavigationRun(scenario.name, controller, world_seed(world, seed, scenario), logs, episode.outcome(),
                         geometry, world.state(), plan_paths)


def control_tick(episode, brains: dict[str, RobotBrain]) -> None:
    """Steps 1-3 of a tick: the world's readings, every robot's modules, the commands applied."""
    world = episode.world
    commands = {}
    for rd in episode.readings():
        ranges = range_readings(rd.ranges, world.sensor_angles, world.body_radius)
        target = TargetReading(*rd.target) if rd.target is not None else None
        commands[rd.robot] = brains[rd.robot].tick(rd.t, target, ranges)
    episode.apply(commands)


def plan_all(world, geometry) -> tuple[dict, dict]:
    """Checkpoints for every robot from its start to its goal, on the known walls (Fig. 12)."""
    checkpoints, paths = {}, {}
    for r in world.robot_ids:
        x, y, _ = world.pose(r)
        plan = plan_checkpoints(geometry, (x, y), world.goal_of(r), body_radius=world.body_radius)
        checkpoints[r], paths[r] = plan.checkpoints, plan.path
    return checkpoints, paths


def world_seed(world, seed, scenario) -> int:
    return int(seed if seed is not None else scenario.seed)


def plot_run(run: NavigationRun, ax=None, title: str | None = None):
    """The run drawn like the paper's figures: walls, obstacles and their motion, robot path, goal, checkpoints."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    from world.draw import draw_paths, draw_world, figure_size, fit_bounds, legend_outside, robot_colours

    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(7, 6))
    colours = robot_colours(sorted(run.logs))
    draw_world(ax, run.geometry, run.final_state, colours)
    labels = {r: f"{r} ({'reached' if log.reached else 'not reached'})" for r, log in run.logs.items()}
    step = draw_paths(ax, {r: (log.t, log.x, log.y) for r, log in run.logs.items()}, colours, labels)
    for r, log in run.logs.items():
        col = colours[r]
        n = max(1, len(log.x) // 40)
        for x, y in zip(log.x[::n], log.y[::n]):
            ax.add_patch(Circle((x, y), 0.03, fill=False, edgecolor=col, lw=0.4, alpha=0.5))
        cps = log.checkpoints
        if len(cps) > 1:
            ax.plot([c[0] for c in cps[:-1]], [c[1] for c in cps[:-1]], "o", color="k", ms=4, label="checkpoints")
    points = [p for log in run.logs.values() for p in zip(log.x, log.y)] + [c for log in run.logs.values()
                                                                          for c in log.checkpoints]
    x0, x1, y0, y1 = fit_bounds(ax, run.geometry, points)
    ax.set_title(title or f"{run.scenario}: {run.controller}, seed {run.seed}")
    legend_outside(ax, time_step=step)
    if own:
        fig.set_size_inches(figure_size(x0, x1, y0, y1))
    if own:
        fig.tight_layout()
        return fig
    return ax


def fields_at(scenario, model, at_time: float, controller_seed: int | None = None, robot: str | None = None,
              fields: FieldParams | None = None) -> dict:
    """Run the cooperative EKM to sim time ``at_time`` and return the activities of Fig. 4:
    the target field, each obstacle field, the combined obstacle fields and the integrated
    activity, with the winners, the robot's pose and the input weights."""
    from world import World
    from world.episode import TICK_S, Episode

    world = World(scenario, seed=controller_seed)
    robot = robot or world.robot_ids[0]
    consts = {"body_radius": world.body_radius, "sensor_range": world.sensor_range}
    brains = {r: make_brain("cekm", model, consts, fields) for r in world.robot_ids}
    checkpoints = plan_all(world, world.static_geometry())[0] if scenario.name == "checkpoints" else None
    episode = Episode(world, checkpoints)
    last = int(round(at_time / TICK_S))
    while True:
        control_tick(episode, brains)
        if episode.tick >= last:
            break
        episode.advance()
    b = brains[robot]
    n = model.w.shape[0]
    a = b.target.a if b.target is not None and b.target.a is not None else np.zeros(n)
    obstacle = {j: o.b for j, o in sorted(b.obstacles.items()) if o.b is not None}
    combined = np.sum(list(obstacle.values()), axis=0) if obstacle else np.zeros(n)
    e = a - combined
    decision = b.controller.integrate(b.target, b.obstacles.values())
    return {"time": episode.t, "robot": robot, "pose": world.pose(robot), "w": model.w.copy(),
            "a": a, "s": None if b.target is None else b.target.winner, "obstacle": obstacle,
            "obstacle_winners": {j: o.winner for j, o in b.obstacles.items() if o.winner is not None},
            "combined": combined, "e": e, "k": decision.k, "eligible": b.controller.eligible.copy(),
            "command": (decision.v_l, decision.v_r), "sensor_angles": world.sensor_angles.copy(),
            "geometry": world.static_geometry(), "state": world.state()}


def plot_fields(f: dict, sensors: tuple[int, int, int] | None = None):
    """The six panels of Fig. 4 (plus the robot's situation): darker = stronger activity."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    w = f["w"]
    angles = f["sensor_angles"]
    if sensors is None:  # the sensors at -pi/6, 0, pi/6, as in the paper
        sensors = tuple(int(np.argmin(np.abs(np.angle(np.exp(1j * (angles - a)))))) for a in (-np.pi / 6, 0.0, np.pi / 6))
    panels = [("(A) target localization EKM", f["a"], f["s"])]
    for letter, j in zip("BCD", sensors):
        b = f["obstacle"].get(j, np.zeros(len(w)))
        panels.append((f"({letter}) obstacle EKM, sensor at {angles[j]:+.2f} rad", b, f["obstacle_winners"].get(j)))
    panels.append(("(E) obstacle EKMs combined", f["combined"], None))
    panels.append(("(F) integrated (motor EKM)", f["e"], f["k"]))
    fig, axes = plt.subplots(2, 4, figsize=(17, 7.5), gridspec_kw={"width_ratios": [1, 1, 1, 1.1]})
    flat = [axes[0, 0], axes[0, 1], axes[0, 2], axes[1, 0], axes[1, 1], axes[1, 2]]
    for ax, (title, act, win) in zip(flat, panels):
        sc = ax.scatter(w[:, 0], w[:, 1], c=act, cmap="Greys", s=18, edgecolors="0.6", linewidths=0.3)
        if title.startswith("(F)") and "eligible" in f and not f["eligible"].all():
            out = ~f["eligible"]
            ax.scatter(w[out, 0], w[out, 1], marker="x", s=22, color="tab:blue", linewidths=0.8,
                       label="not in the motor competition")
            ax.legend(fontsize=7, loc="upper left")
        if win is not None:
            ax.scatter([w[win, 0]], [w[win, 1]], s=90, facecolors="none", edgecolors="red", linewidths=1.5)
        ax.set_title(title, fontsize=9, loc="left")
        ax.set_xlim(-np.pi, np.pi)
        ax.set_xlabel("alpha (rad)")
        ax.set_ylabel("d (m)")
        fig.colorbar(sc, ax=ax, fraction=0.046)
    from world.draw import draw_world

    for ax in (axes[0, 3], axes[1, 3]):
        ax.remove()
    ax = fig.add_subplot(1, 4, 4)
    draw_world(ax, f["geometry"], f["state"])
    x, y, th = f["pose"]
    ax.set_xlim(x - 0.4, x + 0.4)
    ax.set_ylim(y - 0.4, y + 0.4)
    ax.set_title(f"robot at t = {f['time']:.2f} s", fontsize=9)
    fig.suptitle("Fig. 4: activities of the localization and motor EKMs (red: winner)")
    fig.tight_layout()
    return fig
