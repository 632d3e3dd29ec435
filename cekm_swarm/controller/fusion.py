"""The command-fusion baseline of section 4.2 (Low et al. 2002): a weighted sum of the
trained target-reaching EKM's command and a Braitenberg type-3c obstacle avoider.

Avoider: each sensor j's activation s_j = 1 - (surface range / sensor range), 0 when it
sees nothing. An obstacle in front pushes both wheels backward; an obstacle on the left
drives the left wheel forward and the right wheel backward, faster (the paper's "the
right motor will rotate backward faster than the left motor's rotation forward"), so the
robot turns away; on the right, the mirror image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..models.networks import IndirectEKM
from .readings import RangeReading, TargetReading


@dataclass
class CommandFusion:
    """c = w_t c_target + w_o c_avoid, clipped to c*."""

    model: IndirectEKM
    body_radius: float = 0.03
    sensor_range: float = 0.17
    weight_target: float = 1.0
    weight_avoid: float = 1.0
    gain_turn: float = 1.5  # x v_max per unit activation x sin(alpha_j)
    gain_back: float = 1.0  # x v_max per unit activation x cos(alpha_j)
    backward_bias: float = 1.5  # the wheel turning backward turns faster

    def target_command(self, reading: TargetReading) -> np.ndarray:
        """The target-reaching EKM alone (Eq. 11 with k = s); zero at the goal or with no target."""
        if not reading.usable:
            return np.zeros(2)
        return self.model.command(np.array([reading.alpha, reading.d]))

    def avoid_command(self, ranges: Sequence[RangeReading]) -> np.ndarray:
        """The Braitenberg avoider's wheel speeds from the 12 distance readings."""
        vl = vr = 0.0
        for r in ranges:
            if r.d is None:
                continue
            s = max(0.0, 1.0 - (r.d - self.body_radius) / self.sensor_range)
            turn = self.gain_turn * s * math.sin(r.alpha)
            back = self.gain_back * s * math.cos(r.alpha)
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
