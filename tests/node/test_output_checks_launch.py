"""A node that sends a field its readers cannot use (10 values, the model's lattice 225),
through ``cekm launch --mode lockstep`` with real processes: the launch ends at once with
the producer's one line, as a step that raises ends it. Before, every motor dropped each
such field (counted in its log) and the launch waited for good, the world re-publishing
its tick; ``cekm run``'s side is tests/node/test_node_start_and_outputs.py."""

from __future__ import annotations

import textwrap

import pytest

from cekm_swarm.experiments.default_model import default_model_path
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow

MODULE = '''
import numpy as np

from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import ObstacleField, SenseRange


class WrongShape(Node):
    inputs = {"reading": In(SenseRange)}
    outputs = {"field": Out(ObstacleField)}

    def step(self, t, inputs):
        return {"field": ObstacleField(t, self.ctx.sender, self.ctx.instance, 3, np.ones(10))}
'''

GRAPH = '''
[graph]
controller = "wrongshape"
task = "navigation"
answer = "cmd/wheels"

[[node]]
name = "target"
program = "cekm_swarm.modules.target_localization"
every = 2
inputs = { reading = "sense/target" }
outputs = { field = "field/target" }

[[node]]
name = "obstacle"
program = "wrongshape:WrongShape"
instances = "sensors"
every = 1
inputs = { reading = "sense/range/{i}" }
outputs = { field = "field/obstacle/{i}" }

[[node]]
name = "motor"
program = "cekm_swarm.modules.motor_integration"
inputs = { target = "field/target", obstacles = "field/obstacle/*" }
outputs = { command = "cmd/wheels" }
'''


def test_a_lockstep_launch_ends_with_the_producers_line(tmp_path):
    (tmp_path / "wrongshape.py").write_text(textwrap.dedent(MODULE))
    (tmp_path / "wrongshape.toml").write_text(textwrap.dedent(GRAPH))
    run = LaunchProcess("lone_obstacle", tmp_path / "ls", "--graph", str(tmp_path / "wrongshape.toml"), "--mode",
                        "lockstep", "--max-time", "3", "--model", str(default_model_path()), "--no-plot", cwd=tmp_path)
    try:
        code = run.finish(timeout=120)
    finally:
        run.kill()
    assert code == 1, "\n".join(run.lines[-20:])
    last = run.lines[-1]
    assert last.startswith("cekm: failed: r1/obstacle-"), last
    assert ": its step at t=0.000 s failed: output 'field': field b has 10 values, the model's lattice 225 neurons" \
           in last, last
    assert "lockstep the run cannot go on" in last
    assert not any("republish" in line for line in run.lines), "the world waited for the refused fields"
