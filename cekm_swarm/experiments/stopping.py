"""When a target-reaching robot has come to a stop: the end of a test target (where E, T
and D are measured, Eqs. 18-20) and of a training target (the next one is presented).

Two rules (docs/reproduction-4.1.md section 1 has the measurements behind them):

* ``command``, the paper's: E is measured "after it has come to a stop (i.e., motor control
  c = 0)". The network's own output c drives the robot (no rule of ours at the goal
  state), and the robot has stopped when c is 0 at the motor's resolution: both wheel
  commands under half of ``motor_resolution``, the Khepera's speed unit of 8 mm/s (one
  encoder pulse per 10 ms, the smallest speed its motors can be set to), so a command under
  4 mm/s rounds to no motion. An indirect EKM's output at the goal state u = (0, 0) is
  M_s 0 = 0 by Eq. 1 itself; a direct EKM outputs its winner's stored command there and a
  basis-function network its weighted sum, which stop the robot only if they are that small.
* ``goal``, the project's earlier rule (and the controllers' in section 4.2): every network
  commands c = 0 at the goal state (the sensed d rounds to 0 at the target sensor's 1 mm),
  and the robot stops when its executed command is 0 on both wheels (on continuous wheels
  only at the goal state). Every network then stops within the sensor's resolution.

Either way a target also ends when its step budget runs out (counted and reported).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numba import njit

from ..errors import ParameterError
from ..robot import KHEPERA

STOP_RULES = ("command", "goal")


@dataclass(frozen=True)
class StopRule:
    """Which stop rule (:data:`STOP_RULES`) and, for ``command``, the motor's resolution (m/s)."""

    rule: str = "command"
    motor_resolution: float = KHEPERA.speed_unit

    def __post_init__(self) -> None:
        if self.rule not in STOP_RULES:
            raise ParameterError(f"StopRule.rule must be one of {', '.join(STOP_RULES)}, got {self.rule!r}")
        r = self.motor_resolution
        if not (isinstance(r, (int, float)) and math.isfinite(r) and 0.0 < r < KHEPERA.v_max):
            raise ParameterError(f"StopRule.motor_resolution must be a positive speed below v_max "
                                 f"({KHEPERA.v_max:.4f} m/s), got {r!r}")

    @property
    def code(self) -> float:
        """The number the kernels read: 0 for ``goal``, the motor's resolution for ``command``."""
        return self.motor_resolution if self.rule == "command" else 0.0


GOAL_STOP = StopRule("goal")
PAPER_STOP = StopRule("command")


def stopped(c0: float, c1: float, q0: float, q1: float, stop_code: float) -> bool:
    """Whether the robot has come to a stop: the executed command (q0, q1) is 0 on both
    wheels, or (``command`` rule, stop_code > 0) the network's command (c0, c1) is under half
    the motor's resolution on both wheels. Pure Python; the kernels call a jitted copy."""
    if q0 == 0.0 and q1 == 0.0:
        return True
    return stop_code > 0.0 and abs(c0) < 0.5 * stop_code and abs(c1) < 0.5 * stop_code


stopped_nb = njit(cache=True)(stopped)
