"""A-CMOMMT, the tracking baseline (Parker 2002), as two nodes: the weighted force vectors
from the pose, the sensed targets and the teammates' shares (every 0.256 s; it also sends
the robot's share), and the motor that adds each tick's obstacle repulsion from the 12
distance readings and turns the force into wheel speeds
(:class:`cekm_swarm.controller.acmommt.ACMOMMT`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from cekm_swarm.controller.acmommt import ACMOMMT, ForceActivity
from cekm_swarm.controller.readings import RangeReading
from cekm_swarm.controller.team import TeammateShare, TeamView
from cekm_swarm.controller.tracking import TrackingRobot
from cekm_swarm.models.params import ACMOMMTParams, TrackingParams, narrowed
from cekm_swarm.node import In, Inputs, Node, NodeError, Out, need
from cekm_swarm.protocol import Data, SensePose, SenseRange, SenseTargets, Share, WheelCommand
from cekm_swarm.ticks import tick_of

_SEARCH = ("search_reached", "wander_ahead_m", "share_timeout_s", "memory_s")
_TP = TrackingParams()

ACMOMMTNodeParams = dataclasses.make_dataclass(
    "ACMOMMTNodeParams",
    [(f.name, f.type, dataclasses.field(default=f.default)) for f in dataclasses.fields(ACMOMMTParams)]
    + [(name, float, dataclasses.field(default=getattr(_TP, name))) for name in _SEARCH],
    frozen=True)
ACMOMMTNodeParams.__doc__ = ("A-CMOMMT's force profiles (ACMOMMTParams), and the search and team-view settings every "
                             "tracking controller shares (TrackingParams).")


def acmommt(node: Node) -> ACMOMMT:
    b, p = node.ctx.body, node.params
    if not math.isfinite(b.target_range):
        raise NodeError(f"{node.ctx.sender}: tracking needs a finite target sensing range (sensors.target_range)")
    ap = narrowed(p, ACMOMMTParams)
    return ACMOMMT(node.ctx.robot, b.target_range, b.sensor_range, b.body_radius, b.axle, b.v_max, ap,
                   p.search_reached, p.wander_ahead_m)


class ACMOMMTForces(Node):
    """Pose, sensed targets and teammates' shares -> the summed force, and the robot's share."""

    inputs = {"pose": In(SensePose), "targets": In(SenseTargets), "team": In(Share, many=True)}
    outputs = {"force": Out(Data, doc="{fx, fy, searching} in the robot's frame"), "share": Out(Share)}
    Params = ACMOMMTNodeParams
    stateful = True

    def setup(self) -> None:
        p = self.params
        view = TeamView(self.ctx.robot, p.share_timeout_s, p.memory_s)
        self.brain = TrackingRobot(self.ctx.robot, acmommt(self), view)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        pose, sensed = need(inputs, "pose", "targets")  # real time: skipped until both are in
        for robot, share in inputs["team"].items():
            self.brain.receive(robot, TeammateShare(share.stamp, share.pose, share.targets))
        own = self.brain.on_sense(pose.stamp, pose.pose, sensed.targets)
        share = Share(own.stamp, self.brain.robot, own.pose, own.targets)
        a: ForceActivity = self.brain.activity
        return {"force": Data(t, self.ctx.sender, {"fx": a.fx, "fy": a.fy, "searching": a.searching}), "share": share}

    def teammate_left(self, robot: str) -> None:
        self.brain.drop(robot)


class ACMOMMTMotor(Node):
    """The held force plus this tick's obstacle repulsion -> wheel speeds."""

    inputs = {"force": In(Data), "ranges": In(SenseRange, many=True)}
    outputs = {"command": Out(WheelCommand)}
    Params = ACMOMMTNodeParams

    def setup(self) -> None:
        self.ctl = acmommt(self)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        f = inputs["force"]
        act = None if f is None else ForceActivity(f.stamp, f.values["fx"], f.values["fy"], f.values["searching"])
        ranges = [RangeReading(r.index, r.alpha, r.d) for r in inputs["ranges"].values()]
        v_l, v_r = self.ctl.integrate(act, ranges)
        return {"command": WheelCommand(t, self.ctx.sender, v_l, v_r, tick_of(t))}
