"""Target reaching as section 4.1 trains it, in the world (docs/learning.md): each robot
is given a new random target when it stops at its target, or when it has not reached it
within a budget of steps; the run goes on to its max time. Plain data in, plain data out:
no controller code here."""

from __future__ import annotations

import numpy as np

from .episode import Episode
from .sim import World

MARGIN = 0.05  # m: targets at least this far inside the arena's bounds (section 4.1: from its edge)


class TrainingEpisode(Episode):
    """:class:`Episode` with targets re-drawn (uniform in the arena, ``seed``'s own stream
    per robot) when a robot stops at its target or after ``budget_ticks``."""

    def __init__(self, world: World, seed: int, budget_ticks: int = 800) -> None:
        super().__init__(world)
        x0, y0, x1, y1 = world.scenario.bounds
        self.box = (x0 + MARGIN, y0 + MARGIN, x1 - MARGIN, y1 - MARGIN)
        self.rngs = {r: np.random.default_rng([seed, i]) for i, r in enumerate(world.robot_ids)}
        self.budget = budget_ticks
        self.since = {r: 0 for r in world.robot_ids}  # the tick the robot's current target was given
        self.reached_count = {r: 0 for r in world.robot_ids}

    def apply(self, commands: dict[str, tuple[float, float]]) -> None:
        super().apply(commands)
        for r, p in self.progress.items():
            if p.reached:
                self.reached_count[r] += 1
            if p.reached or self.tick - self.since[r] >= self.budget:
                x, y = self.rngs[r].uniform(self.box[:2], self.box[2:])
                self.world.set_goal(r, (float(x), float(y)))
                p.checkpoints, p.next_index, p.reached, p.reached_time = [(float(x), float(y))], 0, False, None
                p.last_d = float("inf")
                self.since[r] = self.tick

    @property
    def done(self) -> bool:
        return False  # training runs to its max time

    def outcome(self) -> dict[str, dict]:
        """:meth:`Episode.outcome` (of each robot's current target) and the targets it reached."""
        out = super().outcome()
        for r, o in out.items():
            o["targets_reached"] = self.reached_count[r]
        return out
