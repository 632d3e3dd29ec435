"""Motor integration (section 3.4): e = a - sum_j b_j (Eq. 9, obstacles in sensor
order), k = argmax e among the motor candidates (Eq. 10), c by Eq. 11 with M_k; at the
goal state c = 0. What the wheels execute is c clipped to c*."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from cekm_swarm.controller.cooperative import ObstacleActivity, TargetActivity
from cekm_swarm.node import In, Inputs, Node, Out
from cekm_swarm.protocol import ObstacleField, TargetField, WheelCommand
from cekm_swarm.protocol.checks import lattice_misfit
from cekm_swarm.ticks import tick_of

from .ekm import cooperative_ekm


def target_activity(f: TargetField | None) -> TargetActivity | None:
    """The target module's output as the controller takes it."""
    if f is None:
        return None
    nan = math.nan
    return TargetActivity(f.stamp, nan if f.alpha is None else f.alpha, nan if f.d is None else f.d, f.winner, f.a,
                          f.at_goal)


def obstacle_activities(fields: Iterable[ObstacleField]) -> list[ObstacleActivity]:
    """The obstacle fields as the controller's activities (Eq. 9 reads only each one's ``b``,
    so the motor nodes hand it the fields themselves: the same arrays, in the same order)."""
    return [ObstacleActivity(f.stamp, f.index, f.winner, f.b) for f in fields]


class MotorIntegration(Node):
    """Motor EKM: target field and obstacle fields -> wheel command (Eqs. 9-11)."""

    inputs = {"target": In(TargetField, doc="the target field (the latest target tick's)"),
              "obstacles": In(ObstacleField, many=True, doc="every obstacle field of the tick")}
    outputs = {"command": Out(WheelCommand, doc="c = (v_l, v_r), clipped to c*")}
    uses_model = True
    warm_setup = True  # setup builds the shared EKM tables only

    @dataclass(frozen=True)
    class Params:
        allow_reverse: bool = False  # reverse-displacement neurons may win Eq. 10 (docs/design.md section 3)
        reverse_min_d: float = 0.02  # m: a neuron this close to d = 0 turns in place, never counted as reverse

    def setup(self) -> None:
        self.ekm = cooperative_ekm(self.ctx, None, self.params.allow_reverse, self.params.reverse_min_d)
        self.integrated: tuple[TargetActivity | None, list] | None = None

    def check_input(self, port: str, msg: Any) -> str | None:
        return lattice_misfit(msg, self.ekm.n)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        target, obstacles = target_activity(inputs["target"]), list(inputs["obstacles"].values())
        self.integrated = (target, obstacles)  # what this step integrated (cekm fields draws it)
        out = self.ekm.integrate(target, obstacles)  # Eqs. 9-11
        return {"command": WheelCommand(t, self.ctx.sender, out.v_l, out.v_r, tick_of(t))}
