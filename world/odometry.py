"""The robots' odometry, as the world publishes it (``<robot>/sense/odometry``, every 8 ticks).

What a real Khepera's motor controller can report: for each of the robot's last ticks
(:data:`~cekm_swarm.protocol.messages.ODOMETRY_ROWS`) the wheel speeds it held (the
robot's command, clipped to c*), what the two wheel encoders measured over the tick (the
executed wheel speeds, with the plant's slip noise, summed over the sub-steps), and
whether the body touched a wall, an obstacle or a robot meanwhile (the motors' stall
signal). Never the pose: a learner forms the displacement v from these alone
(docs/learning.md).
"""

from __future__ import annotations

from collections import deque

from cekm_swarm.protocol.messages import ODOMETRY_ROWS, SenseOdometry
from cekm_swarm.ticks import ODOMETRY_EVERY, TICK_S

from .sim import World

SENDER = "world"  # the sender of every message the world publishes (world.sense.SENDER)
KEY = "sense/odometry"
"""The reading's key below the robot."""


class Odometer:
    """Every robot's odometry reading at each tick: its last ticks' rows."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.last: dict[str, tuple[int, float, float, int]] = {}  # robot -> tick, left, right, contact steps
        self.rows: dict[str, deque[tuple[int, float, float, float, float, bool]]] = {}
        self.sent: dict[str, tuple[int, SenseOdometry]] = {}

    def reading(self, robot: str, tick: int, t: float) -> SenseOdometry:
        """The robot's odometry of tick ``tick`` (the same message however often it is asked;
        read before the tick's command is applied, so the held speeds are the tick before's)."""
        held = self.sent.get(robot)
        if held is not None and held[0] == tick:
            return held[1]
        w = self.world
        i = w._i(robot)
        left, right, contact = float(w._encoders[i, 0]), float(w._encoders[i, 1]), w._contact_steps[i]
        rows = self.rows.setdefault(robot, deque(maxlen=ODOMETRY_ROWS))
        prev = self.last.get(robot)
        if prev is not None and tick > prev[0]:
            set_l, set_r = w.wheel_command(robot)
            rows.append((tick, set_l, set_r, left - prev[1], right - prev[2], contact > prev[3]))
        self.last[robot] = (tick, left, right, contact)
        ticks, set_ls, set_rs, lefts, rights, blocked = zip(*rows, strict=True) if rows else [()] * 6
        msg = SenseOdometry(t, SENDER, ticks, set_ls, set_rs, lefts, rights, blocked, TICK_S)
        self.sent[robot] = (tick, msg)
        return msg

    def messages(self, robot: str, tick: int, t: float) -> list[tuple[str, SenseOdometry]]:
        """The reading as the episode's other messages of the tick: ``[(KEY, message)]`` every
        :data:`~cekm_swarm.ticks.ODOMETRY_EVERY` ticks (the record grows every tick)."""
        msg = self.reading(robot, tick, t)
        return [(KEY, msg)] if tick % ODOMETRY_EVERY == 0 else []
