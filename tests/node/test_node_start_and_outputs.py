"""A node that cannot start, and a node that sends a field its readers cannot use, without
Zenoh: ``cekm run`` (the in-process executor) and the launcher's check of a graph say the
same one line naming the node (robot/node); a field that does not fit the model's lattice
fails its producer's step, not its reader's (the launch side: tests/runtime)."""

from __future__ import annotations

import logging
import textwrap

import numpy as np
import pytest

from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.node import Context, NodeError
from cekm_swarm.node.api import cannot_start, start_node
from cekm_swarm.node.checks import output_check
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.protocol import ObstacleField, TargetField, WheelCommand
from cekm_swarm.protocol.checks import lattice_misfit, on_lattice
from world import load_scenario

MODULE = '''
import numpy as np

from cekm_swarm.node import In, Node, NodeError, Out
from cekm_swarm.protocol import Data, ObstacleField, SenseRange, WheelCommand


class Base(Node):
    inputs = {"raw": In(WheelCommand)}
    outputs = {"command": Out(WheelCommand)}

    def step(self, t, inputs):
        c = inputs["raw"]
        return {"command": WheelCommand(t, self.ctx.sender, c.v_l, c.v_r, c.seq)}


class SetupRaises(Base):
    def setup(self):
        raise RuntimeError("setup went wrong")


class SetupNodeError(Base):
    def setup(self):
        raise NodeError("no such device /dev/qa0")


class InitRaises(Base):
    def __init__(self, ctx, params=None):
        raise KeyError("own init")


class Hangs(Base):
    """A step that never returns at its fourth run."""

    def step(self, t, inputs):
        if t > 0.3:
            import threading
            threading.Event().wait()  # the hang
        return super().step(t, inputs)


class WrongShape(Node):
    """An obstacle module's replacement whose field has 10 values (the lattice has 225)."""

    inputs = {"reading": In(SenseRange)}
    outputs = {"field": Out(ObstacleField)}

    def step(self, t, inputs):
        return {"field": ObstacleField(t, self.ctx.sender, self.ctx.instance, 3, np.ones(10))}


class Picky(Base):
    """A reader with its own check of what it receives: no command faster than 0.01 m/s."""

    def check_input(self, port, msg):
        return None if abs(msg.v_l) <= 0.01 else f"v_l {msg.v_l} is too fast for me"
'''

CEKM = '''
[graph]
controller = "qa"
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
program = "OBSTACLE"
instances = "sensors"
every = 1
inputs = { reading = "sense/range/{i}" }
outputs = { field = "field/obstacle/{i}" }

[[node]]
name = "motor"
program = "cekm_swarm.modules.motor_integration"
inputs = { target = "field/target", obstacles = "field/obstacle/*" }
outputs = { command = "MOTOR_KEY" }
'''

SMOOTH = '''
[[node]]
name = "smooth"
program = "PROGRAM"
every = 1
inputs = { raw = "qa/raw" }
outputs = { command = "cmd/wheels" }
'''

SCENARIO = '''
name = "qa-s1"
seed = 4242
[arena]
bounds = [-0.5, 0.2, 2.7, 1.1]
[[robots]]
id = "r1"
start = [-0.44, 0.26, 2.3]
goal = "g"
[[targets]]
id = "g"
position = [2.6, 1.0]
[[obstacles]]
shape = "disc"
center = [0.6, 0.55]
radius = 0.07
'''

OBSTACLE = "cekm_swarm.modules.obstacle_localization"


@pytest.fixture
def graph(tmp_path, monkeypatch):
    """A graph file: the shipped controller with ``obstacle`` as the obstacle program and,
    when ``smooth`` is given, that program between the motor and the wheels."""
    (tmp_path / "qa_start_mods.py").write_text(textwrap.dedent(MODULE))
    monkeypatch.syspath_prepend(str(tmp_path))

    def make(obstacle: str = OBSTACLE, smooth: str | None = None) -> str:
        text = CEKM.replace("OBSTACLE", obstacle)
        if smooth is None:
            text = text.replace("MOTOR_KEY", "cmd/wheels")
        else:
            text = text.replace("MOTOR_KEY", "qa/raw") + SMOOTH.replace("PROGRAM", smooth)
        path = tmp_path / "g.toml"
        path.write_text(text)
        return str(path)

    return make


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    path = tmp_path_factory.mktemp("sc") / "s1.toml"
    path.write_text(SCENARIO)
    return load_scenario(str(path))


@pytest.fixture(scope="module")
def model():
    return default_model(progress=False)


def line_of(text: str) -> int:
    """The line of MODULE (as written to qa_start_mods.py) that holds ``text``."""
    return next(i for i, line in enumerate(textwrap.dedent(MODULE).splitlines(), 1) if text in line)


def run_error(scenario, model, path: str) -> str:
    with pytest.raises(NodeError) as info:
        run_graph(scenario, graph=path, model=model, max_time=1.0)
    return str(info.value)


def preflight_error(path: str, model) -> str:
    """The line the launcher's check of the graph refuses it with (before any process starts)."""
    from cekm_swarm.launch.prepare import PreflightError, preflight
    from cekm_swarm.node.graph_check import check_graph as check
    from cekm_swarm.robot import RobotBody

    checked = check(path)
    plan = checked.plan(("r1",), "navigation")
    with pytest.raises(PreflightError) as info:
        preflight(checked, plan, RobotBody(), model)
    return str(info.value)


def test_a_setup_that_raises_is_one_line_naming_the_node_in_cekm_run_as_in_a_launch(graph, scenario, model):
    path = graph(smooth="qa_start_mods:SetupRaises")
    line = run_error(scenario, model, path)
    assert line == f"r1/smooth: cannot start: RuntimeError: setup went wrong (qa_start_mods.py:{line_of('setup went')})"
    assert preflight_error(path, model) == line


def test_a_node_error_raised_in_setup_names_the_node(graph, scenario, model):
    path = graph(smooth="qa_start_mods:SetupNodeError")
    line = run_error(scenario, model, path)
    assert line == "r1/smooth: no such device /dev/qa0"
    assert preflight_error(path, model) == line


def test_a_node_whose_own_init_raises_cannot_start_in_cekm_run(graph, scenario, model):
    assert run_error(scenario, model, graph(smooth="qa_start_mods:InitRaises")) == \
        f"r1/smooth: cannot start: KeyError: 'own init' (qa_start_mods.py:{line_of('own init')})"


def test_the_cannot_start_line_is_said_in_one_place():
    class Boom(Exception):
        pass

    assert cannot_start("r1/x", Boom("it\nbroke")) == "r1/x: cannot start: Boom: it broke"  # no traceback: no line
    assert cannot_start("r1/x", NodeError("bad model")) == "r1/x: bad model"
    assert cannot_start("r1/x", NodeError("r1/x: bad model")) == "r1/x: bad model"
    assert cannot_start("r1/x", ValueError("gain must be positive")) == \
        "r1/x: cannot start: ValueError: gain must be positive"  # its type, as any fault of the node's code

    from cekm_swarm.node import Node

    class Fine(Node):
        pass

    assert isinstance(start_node(Fine, Context("r1", "x")), Fine)


def test_a_field_that_does_not_fit_the_lattice_fails_its_producer_not_its_reader(graph, scenario, model):
    """Before, the motor (its reader) failed with numpy's broadcast error in cekm run, and
    a lockstep launch waited for good while the motor dropped every such field."""
    line = run_error(scenario, model, graph(obstacle="qa_start_mods:WrongShape"))
    assert line == ("r1/obstacle-0: its step at t=0.000 s failed: output 'field': field b has 10 values, "
                    "the model's lattice 225 neurons")


def test_a_readers_own_check_of_a_message_of_the_run_fails_the_producer_in_cekm_run(graph, scenario, model):
    line = run_error(scenario, model, graph(smooth="qa_start_mods:Picky"))
    assert line.startswith("r1/motor: its step at t=0.000 s failed: output 'command': r1/smooth cannot use it: v_l ")
    assert line.endswith(" is too fast for me")


def test_the_output_check_is_the_readers_lattice_check(graph, model):
    """The producer's check is what the motor's check_input says (one function)."""
    plan = check_graph(graph(obstacle="qa_start_mods:WrongShape")).plan(("r1",), "navigation")
    node_plan = plan.node("r1", "obstacle-3")
    ctx = Context("r1", "obstacle", 3, ("r1",), model_source=model, log=logging.getLogger("t"))
    from qa_start_mods import WrongShape

    node = WrongShape(ctx)
    check = output_check(node_plan, node)
    assert check is not None
    bad = ObstacleField(0.128, "r1/obstacle-3", 3, 3, np.ones(10))
    with pytest.raises(NodeError, match=r"^r1/obstacle-3: its step at t=0.128 s failed: output 'field': "
                                        r"field b has 10 values, the model's lattice 225 neurons$"):
        check(0.128, [("cekm/r1/field/obstacle/3", bad)])
    check(0.128, [("cekm/r1/field/obstacle/3", ObstacleField(0.128, "r1/obstacle-3", 3, 3, np.ones(225)))])
    check(0.128, [("cekm/r1/field/obstacle/3", ObstacleField(0.128, "r1/obstacle-3", 3, None, None))])

    motor = start_node(check_graph(graph()).classes["motor"], Context("r1", "motor", model_source=model))
    assert motor.check_input("obstacles", bad) == lattice_misfit(bad, 225)
    assert on_lattice(ObstacleField) and on_lattice(TargetField) and not on_lattice(WheelCommand)
    # no model in the run: nothing to fit
    no_model = WrongShape(Context("r1", "obstacle", 3))
    output_check(node_plan, no_model)(0.128, [("k", bad)])


def test_a_step_that_hangs_in_cekm_run_ends_the_run_naming_its_line(graph, scenario, model):
    """The in-process watchdog (node.watchdog): after step_timeout s the run fails (exit 1)
    with the line a lockstep launch says of a stalled tick, instead of hanging without a word."""
    import time

    from cekm_swarm.node.watchdog import StepTimeout

    path = graph(smooth="qa_start_mods:Hangs")
    from cekm_swarm.experiments import graph_run

    t0 = time.monotonic()
    with pytest.raises(StepTimeout) as info:
        graph_run.run_graph(scenario, graph=path, model=model, max_time=1.0, step_timeout=1.0)
    assert time.monotonic() - t0 < 10
    line = str(info.value)
    assert line.startswith("r1/smooth: its step at t=0.384 s has run for "), line
    assert f'qa_start_mods.py", line {line_of("the hang")} in step; --step-timeout 1 s passed' in line, line
    assert info.value.exit_code == 1
