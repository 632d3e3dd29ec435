"""Two nodes of a user's own that speak a message type of their own, for docs/modules.md:
``FreeSpace`` turns the 12 range readings into the freest direction, ``Blend`` steers
between it and the target. Neither builds an envelope: a step returns each message's own
fields and the runner stamps, signs and numbers it. With nothing in sight, ``FreeSpace``
sends nothing (None), and ``Blend`` sees None for it."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import Angle, Distance, SenseRange, SenseTarget, UserMessage, WheelCommand


class FreeDirection(UserMessage):
    """The direction (rad, robot frame, 0 ahead, counter-clockwise positive) whose sensor
    sees farthest, and how far it sees (m, from the robot's centre; the sensor's range when
    it sees nothing)."""

    alpha: Angle
    clearance: Distance


class FreeSpace(Node):
    """The freest of the distance sensors' directions."""

    inputs = {"ranges": In(SenseRange, many=True, doc="every distance sensor's reading of the tick")}
    outputs = {"free": Out(FreeDirection, doc="the freest direction")}
    pure = True  # a function of the readings alone

    def step(self, t, inputs):
        body = self.ctx.body
        reach = body.body_radius + body.sensor_range  # a reading's d is from the centre, the range from the surface
        if all(r.d is None for r in inputs["ranges"].values()):
            return {"free": None}  # nothing in sight: nothing to say this tick
        best = max(inputs["ranges"].values(), key=lambda r: (reach if r.d is None else r.d, -abs(r.alpha)))
        return {"free": {"alpha": best.alpha, "clearance": reach if best.d is None else best.d}}


class Blend(Node):
    """Wheel speeds toward the target, turned toward the free direction when an obstacle is near."""

    inputs = {"target": In(SenseTarget), "free": In(FreeDirection)}
    outputs = {"command": Out(WheelCommand)}

    @dataclass(frozen=True)
    class Params:
        speed: float = 0.05  # m/s, each wheel when heading straight
        near: float = 0.2  # m: closer than this, the free direction counts
        gain: float = 0.08  # m/s per rad of turn

    def step(self, t, inputs):
        target, free = inputs["target"], inputs["free"]  # free: None when nothing is in sight
        p = self.params
        if target is None:  # real time: not yet arrived
            return {"command": {"v_l": 0.0, "v_r": 0.0}}
        if target.visible and target.d < 0.03:
            return {"command": {"v_l": 0.0, "v_r": 0.0}}
        heading = target.alpha if target.visible else 0.0
        if free is not None and free.clearance < p.near:
            w = 1.0 - free.clearance / p.near
            heading = math.atan2((1 - w) * math.sin(heading) + w * math.sin(free.alpha),
                                 (1 - w) * math.cos(heading) + w * math.cos(free.alpha))
        turn = p.gain * heading
        return {"command": {"v_l": p.speed - turn, "v_r": p.speed + turn}}
