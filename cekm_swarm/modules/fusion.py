"""Command fusion, the section 4.2 baseline (Low et al. 2002), as three nodes: the
target-reaching EKM's command (every 0.256 s), a Braitenberg avoider's command from the
12 distance readings (every 0.128 s), and their weighted sum c = w_t c_target + w_o
c_avoid, clipped to c* (:class:`cekm_swarm.controller.fusion.CommandFusion`); at the goal
state the robot stops."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cekm_swarm.controller.fusion import CommandFusion
from cekm_swarm.controller.readings import RangeReading, TargetReading
from cekm_swarm.node import In, Inputs, Node, Out
from cekm_swarm.protocol import Data, SenseRange, SenseTarget, WheelCommand
from cekm_swarm.ticks import tick_of

from .ekm import indirect_model


@dataclass(frozen=True)
class FusionParams:
    """:class:`CommandFusion`'s weights and gains (see it for what each does); their
    defaults are its own (a dataclass's class attribute is the field's default)."""

    weight_target: float = CommandFusion.weight_target
    weight_avoid: float = CommandFusion.weight_avoid
    gain_turn: float = CommandFusion.gain_turn
    gain_back: float = CommandFusion.gain_back
    backward_bias: float = CommandFusion.backward_bias
    front_turn: float = CommandFusion.front_turn


def command_fusion(node: Node) -> CommandFusion:
    b, p = node.ctx.body, node.params
    return CommandFusion(indirect_model(node.ctx), b.body_radius, b.sensor_range, p.weight_target, p.weight_avoid,
                         p.gain_turn, p.gain_back, p.backward_bias, p.front_turn)


class FusionTarget(Node):
    """The target-reaching EKM alone (Eq. 11 with k = s): its proposed command."""

    inputs = {"reading": In(SenseTarget)}
    outputs = {"proposal": Out(Data, doc="{v_l, v_r, at_goal}")}
    Params = FusionParams
    uses_model = True

    def setup(self) -> None:
        self.fusion = command_fusion(self)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        r = inputs["reading"]
        reading = TargetReading(r.alpha, r.d, r.visible) if r is not None else TargetReading(0.0, 0.0, False)
        c = self.fusion.target_command(reading)
        return {"proposal": Data(t, self.ctx.sender, {"v_l": float(c[0]), "v_r": float(c[1]),
                                                       "at_goal": reading.at_goal})}


class BraitenbergAvoidance(Node):
    """The Braitenberg type-3c avoider: the 12 distance readings -> its proposed command."""

    inputs = {"ranges": In(SenseRange, many=True)}
    outputs = {"proposal": Out(Data, doc="{v_l, v_r}")}
    Params = FusionParams
    uses_model = True  # (for c*, the model's v_max)

    def setup(self) -> None:
        self.fusion = command_fusion(self)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        ranges = [RangeReading(r.index, r.alpha, r.d) for r in inputs["ranges"].values()]
        c = self.fusion.avoid_command(ranges)
        return {"proposal": Data(t, self.ctx.sender, {"v_l": float(c[0]), "v_r": float(c[1])})}


class FusionMotor(Node):
    """c = w_t c_target + w_o c_avoid, clipped to c*; zero at the goal state."""

    inputs = {"target": In(Data, doc="the target EKM's proposal"), "avoid": In(Data, doc="the avoider's proposal")}
    outputs = {"command": Out(WheelCommand)}
    Params = FusionParams
    uses_model = True

    def setup(self) -> None:
        self.fusion = command_fusion(self)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        tgt, avoid = inputs["target"], inputs["avoid"]
        if tgt is not None and tgt.values.get("at_goal"):
            v_l = v_r = 0.0
        else:
            c_t = np.array([tgt.values["v_l"], tgt.values["v_r"]]) if tgt is not None else np.zeros(2)
            c_a = np.array([avoid.values["v_l"], avoid.values["v_r"]]) if avoid is not None else np.zeros(2)
            c = self.fusion.fuse(c_t, c_a)
            v_l, v_r = float(c[0]), float(c[1])
        return {"command": WheelCommand(t, self.ctx.sender, v_l, v_r, tick_of(t))}
