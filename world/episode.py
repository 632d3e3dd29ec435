"""The world's side of a run, tick by tick: shared by the in-process runner and the world
server, so that a distributed lockstep run reproduces an in-process run bit for bit.

A tick is 0.128 s (4 sub-steps). At tick k (sim time k * 0.128 s) the world:

1. takes, for every robot in order, the 12 distance readings, then (on even ticks, every
   0.256 s) the target reading; if the robot is following checkpoints and the sensed
   target is within ``checkpoint_radius`` of the current checkpoint, the next one becomes
   the goal and the target is read again;
2. (the controllers compute and send their wheel commands;)
3. applies each robot's command and advances 0.128 s.

A robot has reached its goal when its target reading at the final goal is the goal state
(d = 0, the controller stops), or when it stops there: the command it is given
quantizes to zero on the plant (``[plant] speed_unit``; the paper's stop criterion)
while its last reading of the final goal was within ``checkpoint_radius``. Plain data
in, plain data out: no controller code here.
"""

from __future__ import annotations

import math
from typing import Any

from cekm_swarm.ticks import TARGET_EVERY, TICK_S, tick_time

from .odometry import Odometer
from .progress import RobotProgress
from .sense import TickReadings
from .sim import World

__all__ = ["CHECKPOINT_RADIUS", "TARGET_EVERY", "TICK_S", "Episode", "pushed_out_note"]
CHECKPOINT_RADIUS = 0.03  # m (section 4.2: on to the next checkpoint once this close)


class Episode:
    """Drive a :class:`World` tick by tick; the caller supplies the wheel commands."""

    task = "navigation"

    def __init__(self, world: World, checkpoints: dict[str, list[tuple[float, float]]] | None = None,
                 checkpoint_radius: float = CHECKPOINT_RADIUS) -> None:
        self.world = world
        self.radius = checkpoint_radius
        self.tick = 0
        self.odometer: Odometer | None = None  # the robots' odometry readings (world.odometry), made on first use
        self.progress: dict[str, RobotProgress] = {}
        for r in world.robot_ids:
            cps = [(float(x), float(y)) for x, y in (checkpoints or {}).get(r, [])] or [world.goal_of(r)]
            self.progress[r] = RobotProgress(cps)
            if checkpoints and r in checkpoints:
                world.set_goal(r, cps[0])

    @property
    def t(self) -> float:
        return tick_time(self.tick)

    @property
    def target_due(self) -> bool:
        return self.tick % TARGET_EVERY == 0

    def readings(self) -> list[TickReadings]:
        """Step 1 of the tick, for every robot in order."""
        w = self.world
        out = []
        for r in w.robot_ids:
            p = self.progress[r]
            x, y, th = w.pose(r)
            p.path.append((self.t, x, y, th))
            ranges = w.range_readings(r)
            target = None
            if self.target_due:
                target = w.target_reading(r)
                alpha, d, visible = target
                if not p.final and visible and math.isfinite(d) and d <= self.radius:
                    p.next_index += 1
                    p.checkpoint_times.append(self.t)
                    w.set_goal(r, p.checkpoints[p.next_index])
                    target = w.target_reading(r)
                p.last_d = target[1] if target[2] and math.isfinite(target[1]) else math.inf
                if p.final and not p.reached and target[2] and target[1] == 0.0:
                    p.reached, p.reached_time = True, self.t
                    p.checkpoint_times.append(self.t)
            out.append(TickReadings(r, self.t, ranges, target))
        return out

    def apply(self, commands: dict[str, tuple[float, float]]) -> None:
        """Step 3: set every robot's wheels (a robot without a command keeps its last one)."""
        for r, (v_l, v_r) in commands.items():
            self.world.set_wheels(r, v_l, v_r)
            p = self.progress[r]
            p.commands.append((v_l, v_r))
            if (p.final and not p.reached and p.last_d <= self.radius
                    and self.world.wheel_command(r) == (0.0, 0.0)):
                p.reached, p.reached_time = True, self.t  # a stop at the goal
                p.checkpoint_times.append(self.t)

    def advance(self) -> None:
        self.world.advance(TICK_S)
        self.tick += 1

    def messages(self, robot: str) -> list[tuple[str, Any]]:
        if self.odometer is None:  # made when a run publishes them
            self.odometer = Odometer(self.world)
        return self.odometer.messages(robot, self.tick, self.t)  # the target reading is part of the readings

    def summary(self) -> dict[str, Any]:
        return {}

    def to_goal(self, robot: str) -> float | None:
        x, y, _ = self.world.pose(robot)
        gx, gy = self.world.goal_of(robot)
        return math.hypot(gx - x, gy - y)

    def draw(self, views: Any, t: float, state: dict[str, Any]) -> None:
        return None

    @property
    def done(self) -> bool:
        return all(p.reached for p in self.progress.values())

    def outcome(self) -> dict[str, dict[str, Any]]:
        """Per robot: reached, time_s, path_length_m, collisions, min_clearance_m, final distance, checkpoints.
        ``min_clearance_m`` is None when nothing (wall, obstacle, robot) came within sensor
        range in the whole run: the world's ``stats`` say infinity, which JSON cannot hold."""
        out = {}
        for r, p in self.progress.items():
            st = self.world.stats(r)
            gx, gy = self.world.goal_of(r)
            x, y, _ = self.world.pose(r)
            out[r] = {
                "reached": p.reached,
                "time_s": p.reached_time if p.reached else self.t,
                "path_length_m": float(st["path_length_m"]),
                "collisions": int(st["collisions"]),
                "collisions_with": st["collisions_with"],
                "min_clearance_m": _finite_or_none(st["min_clearance_m"]),
                "final_distance_m": float(math.hypot(gx - x, gy - y)),
                "left_arena_s": st["left_arena_s"],  # pushed through a boundary wall (None: never)
                "checkpoints": [list(c) for c in p.checkpoints],
                "checkpoints_reached": len(p.checkpoint_times),
            }
        return out


def pushed_out_note(robot: dict[str, Any]) -> str:
    """What a run's line adds for a robot of ``outcome()`` pushed through a boundary wall ("" if none)."""
    left = robot.get("left_arena_s")
    return "" if left is None else f", PUSHED OUT of the arena at t={left:.1f} s"


def _finite_or_none(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None
