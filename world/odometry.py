"""The robots' wheel odometry, as the world publishes it (``<robot>/sense/odometry``).

What a real Khepera has: two wheel encoders. Each tick the world sends each wheel's
travel since the robot's previous reading (the executed wheel speeds, with the plant's
slip noise, summed over the sub-steps) and whether the body touched a wall, an obstacle
or a robot meanwhile (the motors' stall signal). Never the pose: a learner forms the
displacement v from these alone (docs/learning.md).
"""

from __future__ import annotations

from cekm_swarm.protocol.messages import SenseOdometry
from cekm_swarm.ticks import TICK_S

from .sim import World

SENDER = "world"  # the sender of every message the world publishes (world.sense.SENDER)

KEY = "sense/odometry"
"""The reading's key below the robot."""


class Odometer:
    """Every robot's encoder reading at each tick: the travel since its previous reading."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.last: dict[str, tuple[int, float, float, float, int]] = {}  # robot -> tick, t, left, right, contact steps
        self.sent: dict[str, tuple[int, SenseOdometry]] = {}

    def reading(self, robot: str, tick: int, t: float) -> SenseOdometry:
        """The robot's odometry of tick ``tick`` (the same message however often it is asked)."""
        held = self.sent.get(robot)
        if held is not None and held[0] == tick:
            return held[1]
        w = self.world
        i = w._i(robot)
        left, right, contact = float(w._encoders[i, 0]), float(w._encoders[i, 1]), w._contact_steps[i]
        prev = self.last.get(robot)
        if prev is None:  # the first reading: nothing travelled yet
            msg = SenseOdometry(t, SENDER, 0.0, 0.0, TICK_S, False)
        else:
            msg = SenseOdometry(t, SENDER, left - prev[2], right - prev[3], max(t - prev[1], 1e-6), contact > prev[4])
        self.last[robot] = (tick, t, left, right, contact)
        self.sent[robot] = (tick, msg)
        return msg

    def messages(self, robot: str, tick: int, t: float) -> list[tuple[str, SenseOdometry]]:
        """The reading as the episode's other messages of the tick: ``[(KEY, message)]``."""
        return [(KEY, self.reading(robot, tick, t))]
