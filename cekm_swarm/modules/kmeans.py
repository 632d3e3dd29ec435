"""The K-means tracking baselines (Luke et al., AAMAS 2005; MASON's CTO ``KMeansEngine``)
as nodes: the goal node (every 0.256 s) and A-CMOMMT's motor
(:class:`.acmommt.ACMOMMTMotor`, the same obstacle repulsion and wheel limits), which
turns the goal's pull into wheel speeds each tick
(:class:`cekm_swarm.controller.kmeans.KMeansTracker`).

* :class:`KMeansLocal` (``kmeans``): the robot's own pose and sensed targets and its
  teammates' shares; it sends its own share.
* :class:`KMeansGlobal` (``kmeans-global``): the world's state (every robot's and target's
  true position), read on ``world/state``: the centralized upper baseline."""

from __future__ import annotations

import math
from typing import Any

from cekm_swarm.controller.kmeans import GoalForce, KMeansTracker, local_view, usable_shares
from cekm_swarm.controller.team import to_world
from cekm_swarm.models.params import KMeansParams
from cekm_swarm.node import In, Inputs, Node, NodeError, Out, need
from cekm_swarm.protocol import Data, SensePose, SenseTargets, Share, WorldState


def tracker(node: Node) -> KMeansTracker:
    b = node.ctx.body
    if not math.isfinite(b.target_range):
        raise NodeError(f"{node.ctx.sender}: tracking needs a finite target sensing range (sensors.target_range)")
    return KMeansTracker(node.ctx.robot, b.target_range, b.v_max, node.params)


def force_data(f: GoalForce, sender: str) -> Data:
    """What the motor reads (A-CMOMMT's force message), with the goal for the log."""
    return Data(f.stamp, sender, {"fx": f.fx, "fy": f.fy, "searching": f.searching, "goal": [f.aim[0], f.aim[1]]})


class KMeansLocal(Node):
    """Pose, sensed targets and teammates' shares -> the pull toward the K-means goal, and the robot's share."""

    inputs = {"pose": In(SensePose, doc="the robot's own pose"),
              "targets": In(SenseTargets, doc="every target within sensing range, (alpha, d)"),
              "team": In(Share, many=True, doc="each teammate's share of its previous run")}
    outputs = {"force": Out(Data, doc="{fx, fy, searching, goal} in the robot's frame"),
               "share": Out(Share, doc="own pose and the targets seen, for the teammates")}
    Params = KMeansParams
    stateful = True  # the goal, the waypoint and its random stream

    def setup(self) -> None:
        self.brain = tracker(self)
        self.shares: dict[str, Any] = {}

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        pose_msg, sensed_msg = need(inputs, "pose", "targets")  # real time: skipped until both are in
        for robot, sh in inputs["team"].items():
            held = self.shares.get(robot)
            if robot != self.ctx.robot and (held is None or sh.stamp >= held[0]):
                self.shares[robot] = (sh.stamp, tuple(sh.pose), dict(sh.targets))
        pose, sensed = tuple(pose_msg.pose), dict(sensed_msg.targets)
        robots, targets = local_view(pose, sensed, usable_shares(self.shares, t, self.params.share_timeout_s))
        f = self.brain.update(t, pose, {r: p for r, p in robots.items()}, targets)
        own = {tid: to_world(pose, a, d) for tid, (a, d) in sorted(sensed.items())}
        return {"force": force_data(f, self.ctx.sender), "share": Share(t, self.ctx.sender, pose, own)}

    def teammate_left(self, robot: str) -> None:
        self.shares.pop(robot, None)


class KMeansGlobal(Node):
    """The world's state -> the pull toward the K-means goal over every target (centralized)."""

    inputs = {"state": In(WorldState, doc="every robot's and target's true position")}
    outputs = {"force": Out(Data, doc="{fx, fy, searching, goal} in the robot's frame")}
    Params = KMeansParams
    stateful = True

    def setup(self) -> None:
        self.brain = tracker(self)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        st: WorldState = inputs["state"]
        me = st.robots[self.ctx.robot]
        pose = (me.x, me.y, me.theta)
        robots = {r: (s.x, s.y) for r, s in sorted(st.robots.items()) if r != self.ctx.robot}
        targets = {tid: (s.x, s.y) for tid, s in sorted(st.targets.items())}
        return {"force": force_data(self.brain.update(t, pose, robots, targets), self.ctx.sender)}
