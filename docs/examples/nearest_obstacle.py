"""Two nodes of a user's own, for docs/modules.md: obstacle avoidance from the nearest
obstacle alone (one process in place of the 12 obstacle localization modules), and a log
of every wheel command the robot is given."""

from __future__ import annotations

from dataclasses import dataclass

from cekm_swarm.models.params import FieldParams
from cekm_swarm.modules.ekm import cooperative_ekm
from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import ObstacleField, SenseRange, WheelCommand


class NearestObstacle(Node):
    """The obstacle field (Eqs. 7-8) of the nearest obstacle any distance sensor sees."""

    inputs = {"ranges": In(SenseRange, many=True, doc="every distance sensor's reading of the tick")}
    outputs = {"field": Out(ObstacleField, doc="the nearest obstacle's field, none when nothing is seen")}
    uses_model = True

    @dataclass(frozen=True)
    class Params:
        sigma_b_alpha: float = 0.6  # Eq. 8: how wide around the obstacle's direction neurons are inhibited

    def setup(self) -> None:
        self.ekm = cooperative_ekm(self.ctx, FieldParams(sigma_b_alpha=self.params.sigma_b_alpha))

    def step(self, t, inputs):
        seen = [r for r in inputs["ranges"].values() if r.d is not None]
        if not seen:
            return {"field": ObstacleField(t, self.ctx.sender, 0, None, None)}
        nearest = min(seen, key=lambda r: r.d)
        s = self.ekm.winner(nearest.alpha, nearest.d)  # Eqs. 2-4
        return {"field": ObstacleField(t, self.ctx.sender, nearest.index, s, self.ekm.obstacle_activity(s))}


class CommandLog(Node):
    """Writes every wheel command of its robot to a CSV file (t, v_l, v_r), replacing the
    file of an earlier run; sends nothing. A relative ``path`` is taken from the directory
    the command was started from (not ``--out``)."""

    inputs = {"command": In(WheelCommand)}

    @dataclass(frozen=True)
    class Params:
        path: str = "{robot}-commands.csv"  # {robot}: the robot's id

    def setup(self) -> None:
        self.file = None
        if self.ctx.mode != "check":  # the launcher builds every node once to check it: no file then
            self.file = open(self.params.path.format(robot=self.ctx.robot), "w")  # noqa: SIM115 -- the node owns it from setup to close
            self.file.write("t,v_l,v_r\n")

    def step(self, t, inputs):
        c = inputs["command"]
        self.file.write(f"{t},{c.v_l!r},{c.v_r!r}\n")
        self.file.flush()
        return {}

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
