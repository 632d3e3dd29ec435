"""Obstacle localization j (section 3.3): on each reading of distance sensor j (every
0.128 s) the winner for u_j = (alpha_j, d_j) (Eqs. 2-4) and the obstacle field b_j
(Eqs. 7-8); nothing when the sensor sees nothing.

The reading's ``d`` is the obstacle input: the distance from the robot's centre (surface
range plus body radius), None when nothing is in range."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cekm_swarm.models.params import FieldParams
from cekm_swarm.node import In, Inputs, Node, Out
from cekm_swarm.protocol import ObstacleField, SenseRange

from .ekm import cooperative_ekm

_DEFAULT = FieldParams()


class ObstacleLocalization(Node):
    """Obstacle localization EKM of one distance sensor: reading -> obstacle field (Eqs. 7-8)."""

    inputs = {"reading": In(SenseRange, doc="distance sensor j's (alpha_j, d_j)")}
    outputs = {"field": Out(ObstacleField, doc="the winner and the obstacle field b_j")}
    uses_model = True
    pure = True  # its field is a function of the reading alone (Eqs. 2-8)
    warm_setup = True  # setup builds the shared EKM tables only

    @dataclass(frozen=True)
    class Params:
        sigma_b_alpha: float = _DEFAULT.sigma_b_alpha  # Eq. 8 (0.6: the project's resolution, docs/design.md)
        sigma_b_d_beyond: float = _DEFAULT.sigma_b_d_beyond  # Eq. 8, neurons at or beyond the obstacle
        sigma_b_d_near: float = _DEFAULT.sigma_b_d_near  # Eq. 8, neurons nearer than it

    def setup(self) -> None:
        p = self.params
        fields = FieldParams(sigma_b_alpha=p.sigma_b_alpha, sigma_b_d_beyond=p.sigma_b_d_beyond,
                             sigma_b_d_near=p.sigma_b_d_near)
        self.ekm = cooperative_ekm(self.ctx, fields)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        r: SenseRange | None = inputs["reading"]
        j = self.ctx.instance or 0
        if r is None:
            return {"field": ObstacleField(t, self.ctx.sender, j, None, None)}
        if r.d is None:  # the sensor sees nothing: no field
            return {"field": ObstacleField(t, self.ctx.sender, r.index, None, None)}
        s = self.ekm.winner(r.alpha, r.d)  # Eqs. 2-4, as localize_obstacle
        return {"field": ObstacleField(t, self.ctx.sender, r.index, s, self.ekm.obstacle_activity(s))}  # Eqs. 7-8
