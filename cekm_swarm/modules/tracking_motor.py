"""The motor module of a tracking robot: e = sum_t w_t a_t - sum_r w_r b_r - sum_j b_j
(Eq. 9 with the teammate fields, docs/design.md section 5), k = argmax e (Eq. 10), and
Eq. 11 with the input u of the localized target (or search goal) whose winner is k."""

from __future__ import annotations

from typing import Any

from cekm_swarm.models.params import TrackingParams
from cekm_swarm.node import In, Inputs, Node, Out
from cekm_swarm.protocol import ObstacleField, TrackingField, WheelCommand
from cekm_swarm.protocol.checks import lattice_misfit
from cekm_swarm.ticks import tick_of

from .tracking_localization import tracking_activity, tracking_ekm


class TrackingMotor(Node):
    """Tracking fields and obstacle fields -> wheel command."""

    inputs = {"tracking": In(TrackingField, doc="the tracking fields of the latest target tick"),
              "obstacles": In(ObstacleField, many=True, doc="every obstacle field of the tick")}
    outputs = {"command": Out(WheelCommand)}
    Params = TrackingParams  # the target module's: face_turn_gain is executed here
    uses_model = True
    warm_setup = True  # setup builds the shared EKM tables only

    def setup(self) -> None:
        self.tekm = tracking_ekm(self.ctx, self.params)

    def check_input(self, port: str, msg: Any) -> str | None:
        return lattice_misfit(msg, self.tekm.ekm.n)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        f = inputs["tracking"]
        act = None if f is None else tracking_activity(f)
        out = self.tekm.integrate(act, inputs["obstacles"].values())  # Eqs. 9-11 (reads each field's b)
        return {"command": WheelCommand(t, self.ctx.sender, out.v_l, out.v_r, tick_of(t))}
