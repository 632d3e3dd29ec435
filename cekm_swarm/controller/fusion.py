"""The command-fusion baseline of section 4.2 (Low et al. 2002): a weighted sum of the
trained target-reaching EKM's command and a Braitenberg type-3c obstacle avoider.

Avoider: each sensor j's activation s_j = 1 - (surface range / sensor range), 0 when it
sees nothing. An obstacle in front pushes both wheels backward; an obstacle on the left
drives the left wheel forward and the right wheel backward, faster (the paper's "the
right motor will rotate backward faster than the left motor's rotation forward"), so the
robot turns away; on the right, the mirror image. Only forward-facing sensors drive it,
and the sensor straight ahead turns the robot away from the side that senses more: with
a symmetric avoider a head-on disc gave two equal and opposite turns and the robot sat in
front of it (lone_obstacle 0/5), which is not an honest baseline. It still cancels, as
the paper describes, where the obstacle surrounds the robot (the U's arms, the doorway's
blocks): the turns of the two sides cancel and the backing cancels the forward drive.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..models.networks import IndirectEKM
from ..robot import KHEPERA
from .readings import RangeReading, TargetReading


@dataclass
class CommandFusion:
    """c = w_t c_target + w_o c_avoid, clipped to c*."""

    model: IndirectEKM
    body_radius: float = KHEPERA.body_radius
    sensor_range: float = KHEPERA.sensor_range
    weight_target: float = 1.0
    weight_avoid: float = 1.0
    gain_turn: float = 1.5  # x v_max per unit activation x sin(alpha_j)
    # x v_max per unit activation x cos(alpha_j). 2.0: two front sensors beside a narrow
    # gap (or a wall ahead) push back as hard as the target EKM drives forward once the
    # robot is within about 0.05 m, so the sum cancels there (the paper's account of why
    # fusion is trapped); at 1.0 the forward drive won and the robot scraped through the
    # 86 mm doorway with collisions. The lone obstacle is still passed (turns, not backing).
    gain_back: float = 2.0
    backward_bias: float = 1.5  # the wheel turning backward turns faster
    # the straight-ahead sensor turns as hard as one at 90 degrees (0.5 grazed the disc in 5/5 seeds)
    front_turn: float = 1.0

    def target_command(self, reading: TargetReading) -> np.ndarray:
        """The target-reaching EKM alone (Eq. 11 with k = s); zero at the goal or with no target."""
        if not reading.usable:
            return np.zeros(2)
        return self.model.command(np.array([reading.alpha, reading.d]))

    def avoid_command(self, ranges: Sequence[RangeReading]) -> np.ndarray:
        """The Braitenberg avoider's wheel speeds from the 12 distance readings.

        Only the sensors facing forward (|alpha_j| < pi/2) drive it, as a Braitenberg
        vehicle's sensors face its direction of travel. The sensor straight ahead
        (sin alpha_j = 0) turns the robot towards the side that senses less, so that a
        head-on obstacle is not a dead lock between two equal turns.
        """
        act = []
        for r in ranges:
            if r.d is None or math.cos(r.alpha) <= 1e-9:
                continue
            s = min(1.0, max(0.0, 1.0 - (r.d - self.body_radius) / self.sensor_range))
            act.append((r.alpha, s))
        left = sum(s for a, s in act if math.sin(a) > 1e-9)
        right = sum(s for a, s in act if math.sin(a) < -1e-9)
        vl = vr = 0.0
        for a, s in act:
            side = math.sin(a)
            if abs(side) <= 1e-9:  # straight ahead: turn away from the side that senses more
                side = self.front_turn if left >= right else -self.front_turn
            turn = self.gain_turn * s * side
            back = self.gain_back * s * math.cos(a)
            if turn >= 0.0:  # obstacle on the left: left wheel forward, right wheel backward faster
                vl += turn
                vr -= self.backward_bias * turn
            else:
                vl += self.backward_bias * turn
                vr -= turn
            vl -= back
            vr -= back
        return self.model.v_max * np.array([vl, vr])

    def fuse(self, c_target: np.ndarray, c_avoid: np.ndarray) -> np.ndarray:
        v = self.model.v_max
        return np.clip(self.weight_target * c_target + self.weight_avoid * c_avoid, -v, v)
