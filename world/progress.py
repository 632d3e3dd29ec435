"""A robot's progress over a run (:class:`RobotProgress`): its checkpoints and goal, its
path and commands tick by tick; every episode (navigation, tracking, training) keeps one
per robot."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .rows import Rows


@dataclass
class RobotProgress:
    checkpoints: list[tuple[float, float]]
    next_index: int = 0
    checkpoint_times: list[float] = field(default_factory=list)
    reached: bool = False
    reached_time: float | None = None
    path: Rows = field(default_factory=lambda: Rows(4))  # t, x, y, theta per tick (flat memory: world.rows)
    commands: Rows = field(default_factory=lambda: Rows(2))  # v_l, v_r per tick
    last_d: float = math.inf  # the last sensed distance to the current goal

    @property
    def final(self) -> bool:
        return self.next_index == len(self.checkpoints) - 1
