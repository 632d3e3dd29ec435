"""Target localization (section 3.2): on each target reading (every 0.256 s) the winner s
for the sensed target u (Eqs. 2-4) and the target field a_i = G_a(w_s, w_i) (Eqs. 5-6)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cekm_swarm.controller.cooperative import CooperativeEKM
from cekm_swarm.controller.readings import TargetReading
from cekm_swarm.models.params import FieldParams
from cekm_swarm.node import In, Inputs, Node, Out
from cekm_swarm.protocol import SenseTarget, TargetField

from .ekm import cooperative_ekm

_DEFAULT = FieldParams()


def target_field(ekm: CooperativeEKM, reading: SenseTarget | None, t: float, sender: str) -> TargetField:
    """The target field of one reading, as a message: no target (not visible, or no
    reading) gives no field; the goal state (d = 0) gives ``at_goal`` and no field."""
    if reading is None:
        return TargetField(t, sender, None, None)
    act = ekm.localize_target(TargetReading(reading.alpha, reading.d, reading.visible), t)
    if act.at_goal:
        return TargetField(t, sender, None, None, act.alpha, act.d, at_goal=True)
    if act.a is None or not (math.isfinite(act.alpha) and math.isfinite(act.d)):
        return TargetField(t, sender, None, None)
    return TargetField(t, sender, act.winner, act.a, act.alpha, act.d)


class TargetLocalization(Node):
    """Target localization EKM: sensed target -> target field (Eqs. 2-6)."""

    inputs = {"reading": In(SenseTarget, doc="the target sensor's (alpha, d)")}
    outputs = {"field": Out(TargetField, doc="the winner s and the target field a")}
    uses_model = True
    pure = True  # its field is a function of the reading alone (Eqs. 2-6)
    warm_setup = True  # setup builds the shared EKM tables only

    @dataclass(frozen=True)
    class Params:
        sigma_a_alpha: float = _DEFAULT.sigma_a_alpha  # Eq. 6: elongation across the target direction
        sigma_a_d: float = _DEFAULT.sigma_a_d  # Eq. 6: along it

    def setup(self) -> None:
        p = self.params
        self.ekm = cooperative_ekm(self.ctx, FieldParams(sigma_a_alpha=p.sigma_a_alpha, sigma_a_d=p.sigma_a_d))

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        return {"field": target_field(self.ekm, inputs["reading"], t, self.ctx.sender)}
