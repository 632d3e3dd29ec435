"""Target reaching as section 4.1 trains it, in the world (docs/learning.md): each robot
is given a new random target when it stops at its target, or when it has not reached it
within a budget of steps; the run goes on to its max time. Plain data in, plain data out:
no controller code here."""

from __future__ import annotations

from typing import Any

import numpy as np

from .episode import Episode
from .sim import World

MARGIN = 0.05  # m: targets at least this far inside the arena's bounds (section 4.1: from its edge)
EXPLORE_REL, EXPLORE_ABS = 0.2, 0.005  # c += N(0, (0.2 |c| + 0.005 m/s)^2) per wheel (docs/design.md section 7)
EXPLORE_STREAM = 1  # the exploration noise's stream: default_rng([seed, robot index, 1])


class TrainingEpisode(Episode):
    """:class:`Episode` with targets re-drawn (uniform in the arena, ``seed``'s own stream
    per robot) when a robot stops at its target or after ``budget_ticks``. With the
    scenario's ``explore``, section 4.1's training exploration noise on each robot's
    executed wheel speeds (:func:`explore`); a stop stays a stop."""

    def __init__(self, world: World, seed: int, budget_ticks: int = 800) -> None:
        super().__init__(world)
        x0, y0, x1, y1 = world.scenario.bounds
        self.box = (x0 + MARGIN, y0 + MARGIN, x1 - MARGIN, y1 - MARGIN)
        self.rngs = {r: np.random.default_rng([seed, i]) for i, r in enumerate(world.robot_ids)}
        self.budget = budget_ticks
        self.since = {r: 0 for r in world.robot_ids}  # the tick the robot's current target was given
        self.reached_count = {r: 0 for r in world.robot_ids}
        self.explore_rngs = ({r: np.random.default_rng([seed, i, EXPLORE_STREAM])
                              for i, r in enumerate(world.robot_ids)} if world.scenario.explore else None)

    def apply(self, commands: dict[str, tuple[float, float]]) -> None:
        if self.explore_rngs is not None:
            commands = {r: explore(c, self.explore_rngs[r]) for r, c in commands.items()}
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

    def outcome(self) -> dict[str, dict[str, Any]]:
        """:meth:`Episode.outcome` (of each robot's current target) and the targets it reached."""
        out = super().outcome()
        for r, o in out.items():
            o["targets_reached"] = self.reached_count[r]
        return out


def explore(c: tuple[float, float], rng: np.random.Generator) -> tuple[float, float]:
    """Training-only exploration noise on the executed command (docs/design.md section 7:
    c += N(0, (0.2 |c| + 0.005 m/s)^2) per wheel; the world then clips it to v*, and the
    robot's odometry reports the speeds held, so a learner learns from the executed
    command, as Eqs. 15-17 say). A stopped command (c = 0) stays stopped and draws nothing."""
    if c[0] == 0.0 and c[1] == 0.0:
        return c
    z = rng.standard_normal(2)
    return (float(c[0] + z[0] * (EXPLORE_REL * abs(c[0]) + EXPLORE_ABS)),
            float(c[1] + z[1] * (EXPLORE_REL * abs(c[1]) + EXPLORE_ABS)))
