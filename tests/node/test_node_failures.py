"""A node that fails, one that is not ready, and one timed by a reading sent every other
tick, without Zenoh: what the runner and the gates do with each (the shell and the
launcher's side are in tests/runtime/test_launch_node_failures.py)."""

from __future__ import annotations

import textwrap

import pytest

from cekm_swarm.graph.resolve import timed_by
from cekm_swarm.node import NodeError, NotReady, need
from cekm_swarm.node.api import Inputs
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.node.runner import Runner
from cekm_swarm.node.timing import LockstepGate, RealtimeGate
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import Clock, SenseRange, SenseTarget
from cekm_swarm.ticks import tick_time

MODULE = '''
from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import SenseTarget, WheelCommand


class ReadingMotor(Node):
    """Drives toward the raw target reading: due every tick, reads a reading sent every other tick."""

    inputs = {"reading": In(SenseTarget)}
    outputs = {"command": Out(WheelCommand)}

    def step(self, t, inputs):
        r = inputs["reading"]
        turn = 0.0 if r is None else 0.02 * r.alpha
        return {"command": WheelCommand(t, self.ctx.sender, 0.05 - turn, 0.05 + turn, 0)}
'''

GRAPH = '''
[graph]
controller = "reading"
task = "navigation"
answer = "cmd/wheels"

[[node]]
name = "motor"
program = "reading_motor:ReadingMotor"
every = 1
inputs = { reading = "sense/target" }
outputs = { command = "cmd/wheels" }
'''


@pytest.fixture
def reading_plan(tmp_path):
    (tmp_path / "reading_motor.py").write_text(textwrap.dedent(MODULE))
    (tmp_path / "reading.toml").write_text(textwrap.dedent(GRAPH))
    return check_graph(str(tmp_path / "reading.toml")).plan(("r1",), "navigation")


def reading(k: int, alpha: float = 0.1):
    return K.sense_target("r1"), SenseTarget(tick_time(k), "world", alpha, 1.0, True)


def clock(k: int):
    return K.world_clock(), Clock(tick_time(k), "world", k)


def test_a_node_due_every_tick_that_reads_only_an_every_other_tick_reading_listens_to_the_clock(reading_plan):
    node = reading_plan.node("r1", "motor")
    assert node.clock_key == K.world_clock()
    assert timed_by(1, {1, 2}) and timed_by(2, {2}) and timed_by(4, {2})
    assert not timed_by(1, {2}) and not timed_by(2, {4}) and not timed_by(1, set())


def test_lockstep_answers_an_odd_tick_only_once_the_world_has_begun_it(reading_plan):
    """The reading of tick 0 opens tick 0 alone: tick 1 runs on tick 1's clock (before,
    it ran at once and its command came before the world had begun tick 1)."""
    node = reading_plan.node("r1", "motor")
    gate = LockstepGate(Runner(node, _node(reading_plan)))
    assert gate.put(*clock(0)) == []
    out0 = gate.put(*reading(0))
    assert [m.stamp for _, m in out0] == [0.0]
    out1 = gate.put(*clock(1))
    assert [m.stamp for _, m in out1] == [tick_time(1)]
    assert [m.stamp for _, m in gate.put(*reading(2))] == [tick_time(2)]
    assert gate.put(*clock(2)) == []


def test_realtime_runs_every_tick_of_a_node_timed_by_the_clock(reading_plan):
    node = reading_plan.node("r1", "motor")
    gate = RealtimeGate(Runner(node, _node(reading_plan)))
    sent = []
    for k in range(6):
        if k % 2 == 0:
            sent += gate.put(*reading(k))
        sent += gate.put(*clock(k))
    assert [m.stamp for _, m in sent] == [tick_time(k) for k in range(6)]


def _node(plan):
    node = plan.node("r1", "motor")
    from cekm_swarm.node.api import Context
    from cekm_swarm.node.graph_check import node_class

    cls = node_class(node.decl.program, plan.graph.source, node.decl.where)
    return cls(Context("r1", "motor"), cls.Params())


NEEDY = '''
from cekm_swarm.node import In, Node, Out, need
from cekm_swarm.protocol import SenseRange, SenseTarget, WheelCommand


class Needy(Node):
    """Needs its front sensor's reading; raises on a target reading at alpha > 1 (a bug in the node)."""

    inputs = {"front": In(SenseRange), "reading": In(SenseTarget)}
    outputs = {"command": Out(WheelCommand)}

    def step(self, t, inputs):
        front, r = need(inputs, "front", "reading")
        if r.alpha > 1.0:
            raise ZeroDivisionError("the node's own bug")
        return {"command": WheelCommand(t, self.ctx.sender, 0.05 if front.d is None else 0.0, 0.0, 0)}
'''


@pytest.fixture
def needy_plan(tmp_path):
    (tmp_path / "needy.py").write_text(textwrap.dedent(NEEDY))
    (tmp_path / "needy.toml").write_text(textwrap.dedent('''
        [graph]
        controller = "needy"
        task = "navigation"
        answer = "cmd/wheels"

        [[node]]
        name = "motor"
        program = "needy:Needy"
        inputs = { front = "sense/range/0", reading = "sense/target" }
        outputs = { command = "cmd/wheels" }
        '''))
    return check_graph(str(tmp_path / "needy.toml")).plan(("r1",), "navigation")


def front(k: int):
    return K.sense_range("r1", 0), SenseRange(tick_time(k), "world", 0, 0.0, None)


def needy_runner(plan) -> Runner:
    return Runner(plan.node("r1", "motor"), _node(plan))


def test_need_names_what_is_missing():
    ins = Inputs({"pose": None, "reading": None, "x": 1})
    with pytest.raises(NotReady, match="pose, reading"):
        need(ins, "pose", "reading")
    assert need({"x": 1}, "x") == 1 and need({"x": 1, "y": 2}, "y", "x") == (2, 1)


def test_realtime_a_tick_not_ready_runs_when_its_missing_value_comes_or_is_given_up(needy_plan):
    gate = RealtimeGate(needy_runner(needy_plan))
    assert gate.put(*reading(0)) == []  # the front reading of tick 0 is not here yet: not ready, not run
    out = gate.put(*front(0))
    assert [m.stamp for _, m in out] == [0.0] and gate.not_ready == 0  # it came: tick 0 runs
    gate2 = RealtimeGate(needy_runner(needy_plan))
    assert gate2.put(*reading(0)) == []
    out = gate2.put(*front(1))  # tick 1 begins with tick 0 still not ready: given up; tick 1 runs
    assert [m.stamp for _, m in out] == [tick_time(1)] and gate2.not_ready == 1


def test_a_step_that_raises_is_a_node_error_naming_the_node_tick_exception_and_line(needy_plan):
    runner = needy_runner(needy_plan)
    inputs = Inputs({"front": front(3)[1], "reading": reading(3, alpha=2.0)[1]})
    with pytest.raises(NodeError) as err:
        runner.run(3, inputs)
    text = str(err.value)
    assert text.startswith("r1/motor: its step at t=0.384 s failed: ZeroDivisionError: the node's own bug")
    line = 1 + textwrap.dedent(NEEDY).splitlines().index("            raise ZeroDivisionError(\"the node's own bug\")")
    assert f"(needy.py:{line})" in text  # the node's own line
    assert isinstance(err.value.__cause__, ZeroDivisionError)


def test_not_ready_outside_real_time_is_a_failure(needy_plan):
    runner = needy_runner(needy_plan)
    with pytest.raises(NodeError, match="raised NotReady, but in lockstep"):
        runner.run(0, Inputs({"front": None, "reading": reading(0)[1]}))
