"""The static baseline: the robot stays where it starts (c = 0 every tick)."""

from __future__ import annotations

from typing import Any

from cekm_swarm.node import Inputs, Node, Out
from cekm_swarm.protocol import WheelCommand
from cekm_swarm.ticks import tick_of


class Stay(Node):
    """No inputs: runs on the world's clock and always commands c = 0."""

    outputs = {"command": Out(WheelCommand)}

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        return {"command": WheelCommand(t, self.ctx.sender, 0.0, 0.0, tick_of(t))}
