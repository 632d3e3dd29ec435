"""The tracking target module (multi-robot tracking, Fig. 13; docs/tracking.md): on the
robot's pose and the targets it senses (every 0.256 s) and its teammates' shares of
their previous run, the weighted target fields, the teammate fields and their inputs
(one ``field/tracking`` message for the motor), and the robot's own share.

It runs :class:`cekm_swarm.controller.tracking.TrackingRobot`, whose team view remembers
where targets were last reported: the node keeps state across ticks (``stateful``)."""

from __future__ import annotations

import math
from typing import Any

from cekm_swarm.controller.team import TeammateShare, TeamView
from cekm_swarm.controller.tracking import TrackingActivity, TrackingEKM, TrackingRobot
from cekm_swarm.models.params import FieldParams, TrackingParams
from cekm_swarm.node import Context, In, Inputs, Node, NodeError, Out, need
from cekm_swarm.protocol import SensePose, SenseTargets, Share, TrackingField

from .ekm import indirect_model


def tracking_field(act: TrackingActivity, sender: str) -> TrackingField:
    """The message of one tracking-target-module output."""
    return TrackingField(act.stamp, sender, act.a, act.b_team, act.inputs, act.weights, act.searching)


def tracking_activity(msg: TrackingField) -> TrackingActivity:
    """The activity the motor integrates, from its message (the inverse of :func:`tracking_field`)."""
    return TrackingActivity(msg.stamp, msg.a, msg.b, msg.inputs, msg.weights, msg.searching)


def tracking_ekm(ctx: Context, params: TrackingParams) -> TrackingEKM:
    """The robot's cooperative-EKM tracking controller (the paper's field widths)."""
    R = ctx.body.target_range
    if not math.isfinite(R):
        raise NodeError(f"{ctx.sender}: tracking needs a finite target sensing range (sensors.target_range)")
    return TrackingEKM(ctx.robot, indirect_model(ctx), R, params, FieldParams.paper(), backend=ctx.backend)


class TrackingLocalization(Node):
    """Pose, sensed targets and teammates' shares -> tracking fields and the robot's share."""

    inputs = {"pose": In(SensePose, doc="the robot's own pose"),
              "targets": In(SenseTargets, doc="every target within sensing range, (alpha, d)"),
              "team": In(Share, many=True, doc="each teammate's share of its previous run")}
    outputs = {"field": Out(TrackingField, doc="weighted target and teammate fields, with their inputs"),
               "share": Out(Share, doc="own pose and the targets seen, for the teammates")}
    Params = TrackingParams
    stateful = True
    uses_model = True
    warm_setup = True  # setup builds the shared EKM tables only

    def setup(self) -> None:
        p = self.params
        self.brain = TrackingRobot(self.ctx.robot, tracking_ekm(self.ctx, p),
                                   TeamView(self.ctx.robot, p.share_timeout_s, p.memory_s))

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        pose, sensed = need(inputs, "pose", "targets")  # real time: skipped until both are in
        for robot, share in inputs["team"].items():
            self.brain.receive(robot, TeammateShare(share.stamp, share.pose, share.targets))
        own = self.brain.on_sense(pose.stamp, pose.pose, sensed.targets)
        share = Share(own.stamp, self.brain.robot, own.pose, own.targets)
        return {"field": tracking_field(self.brain.activity, self.ctx.sender), "share": share}

    def teammate_left(self, robot: str) -> None:
        self.brain.drop(robot)
