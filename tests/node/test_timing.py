"""The one rule of what a node sees at tick k, and when it runs, without Zenoh: lockstep
(every value of the tick, whatever order it arrives in, from every live producer; a
repeat answered again; values no run can use dropped) and real time (at once when the
tick's fields are in, or when the next tick begins; stale values left out)."""

from __future__ import annotations

import itertools
import random

import numpy as np
import pytest

from cekm_swarm.graph.plan import needed_tick
from cekm_swarm.node import Node
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.node.runner import Runner
from cekm_swarm.node.timing import LockstepGate, RealtimeGate
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import ObstacleField, SensePose, SenseTargets, Share, TargetField, TrackingField, WheelCommand
from cekm_swarm.ticks import tick_time

N = 12


def test_the_rule_names_the_producers_latest_run():
    # delay 0: the latest run at or before k; delay 1: strictly before k
    assert [needed_tick(k, 2, 0) for k in range(5)] == [0, 0, 2, 2, 4]
    assert [needed_tick(k, 1, 0) for k in range(3)] == [0, 1, 2]
    assert [needed_tick(k, 2, 1) for k in range(6)] == [None, 0, 0, 2, 2, 4]
    assert [needed_tick(k, 1, 1) for k in range(3)] == [None, 0, 1]


class Recorder(Node):
    """Stands in for a node: records what each step saw, answers with a command."""

    def __init__(self, outputs, calls):
        self.outputs = outputs
        self.calls = calls

    def step(self, t, inputs):
        self.calls.append((t, {p: inputs[p] for p in inputs}))
        out = {}
        for port, o in self.outputs.items():
            if o.type is WheelCommand:
                out[port] = WheelCommand(t, "r1/motor", float(len(self.calls)), 0.0, 0)
            elif o.type is TrackingField:
                out[port] = TrackingField(t, "r1/target", np.ones(4), np.zeros(4), (), {}, False)
            elif o.type is Share:
                out[port] = Share(t, "r1/target", (0.0, 0.0, 0.0), {})
        return out


def motor_gate(gate_cls=LockstepGate, drops=None):
    plan = check_graph("cekm-tuned-navigation").plan(("r1",), "navigation")
    node = plan.node("r1", "motor")
    calls = []
    from cekm_swarm.modules.motor_integration import MotorIntegration

    runner = Runner(node, Recorder(MotorIntegration.outputs, calls))
    gate = gate_cls(
        runner, drop=(lambda key, why: drops.append((key, why))) if drops is not None else (lambda k, w: None)
    )
    return gate, calls


def obstacle(k, j):
    return K.field_obstacle("r1", j), ObstacleField(tick_time(k), f"r1/obstacle-{j}", j, None, None)


def target(k, winner=2):
    return K.field_target("r1"), TargetField(tick_time(k), "r1/target", winner, np.ones(8), 0.1, 0.5)


def test_lockstep_runs_once_every_value_of_the_tick_is_in_whatever_the_order():
    msgs = [target(0)] + [obstacle(0, j) for j in range(N)]
    for order in (msgs, msgs[::-1], random.Random(3).sample(msgs, len(msgs))):
        gate, calls = motor_gate()
        out = []
        for key, m in order[:-1]:
            out += gate.put(key, m)
        assert out == [] and calls == []
        out = gate.put(*order[-1])
        assert [k for k, _ in out] == [K.cmd_wheels("r1")] and len(calls) == 1
        t, seen = calls[0]
        assert t == 0.0 and seen["target"].stamp == 0.0
        assert list(seen["obstacles"]) == list(range(N))  # in sensor order, whatever the arrival order


def test_lockstep_odd_ticks_read_the_latest_even_target_field():
    gate, calls = motor_gate()
    for key, m in [target(0)] + [obstacle(0, j) for j in range(N)]:
        gate.put(key, m)
    out = []
    for j in reversed(range(N)):
        out += gate.put(*obstacle(1, j))
    assert len(out) == 1 and calls[-1][1]["target"].stamp == 0.0
    for j in range(N):  # tick 2: the field of tick 0 is no longer enough
        assert gate.put(*obstacle(2, j)) == []
    assert len(gate.put(*target(2, winner=5))) == 1 and calls[-1][1]["target"].winner == 5


def test_lockstep_answers_a_repeat_again_and_drops_what_no_run_can_use():
    drops = []
    gate, calls = motor_gate(drops=drops)
    for key, m in [target(0)] + [obstacle(0, j) for j in range(N)]:
        gate.put(key, m)
    first = gate.put(*[obstacle(1, j) for j in range(N)][0]) or None
    for j in range(1, N):
        first = gate.put(*obstacle(1, j)) or first
    # the world re-publishes tick 1 (a restarted module catches up): the same answer again
    again = gate.put(*obstacle(1, 3))
    assert again == first and gate.repeats == 1 and len(calls) == 2
    # the target field tick 1 used, sent again: answered again, not a drop
    assert gate.put(*target(0)) == first and drops == []
    # a field of tick 0, which no run after tick 1 reads: dropped and counted
    assert gate.put(*obstacle(0, 3)) == [] and drops == [(K.field_obstacle("r1", 3), drops[0][1])]
    assert "which no run after t=0.128 reads" in drops[0][1]


def test_lockstep_a_value_ahead_waits_for_its_own_tick():
    gate, calls = motor_gate()
    gate.put(*target(0))
    gate.put(*obstacle(5, 0))  # ahead (early, or a peer's): kept for tick 5, displaces nothing
    for j in range(N):
        gate.put(*obstacle(0, j))
    assert len(calls) == 1 and all(f.stamp == 0.0 for f in calls[0][1]["obstacles"].values())


def tracking_gate(robot="r1", team=("r1", "r2", "r3")):
    plan = check_graph("cekm-tracking").plan(team, "tracking")
    node = plan.node(robot, "target")
    calls = []
    from cekm_swarm.modules.tracking_localization import TrackingLocalization

    return LockstepGate(Runner(node, Recorder(TrackingLocalization.outputs, calls))), calls


def sense(k, robot="r1"):
    t = tick_time(k)
    return [(K.sense_pose(robot), SensePose(t, "world", (0.0, 0.0, 0.0))),
            (K.sense_targets(robot), SenseTargets(t, "world", {}))]


def share(k, robot):
    return K.share(robot), Share(tick_time(k), f"{robot}/target", (1.0, 2.0, 0.0), {})


def test_lockstep_teammates_shares_of_their_previous_run_are_waited_for():
    gate, calls = tracking_gate()
    for key, m in sense(0):
        gate.put(key, m)
    assert len(calls) == 1 and calls[0][1]["team"] == {}  # tick 0: no previous run
    for key, m in sense(2):
        gate.put(key, m)
    assert len(calls) == 1  # waits for r2's and r3's shares of tick 0
    gate.put(*share(2, "r2"))  # a share of tick 2 arriving early waits for tick 4
    gate.put(*share(0, "r3"))
    assert len(calls) == 1
    gate.put(*share(0, "r2"))
    assert len(calls) == 2 and {r: s.stamp for r, s in calls[1][1]["team"].items()} == {"r2": 0.0, "r3": 0.0}


def test_lockstep_every_arrival_order_of_a_tick_gives_the_same_inputs():
    """Pose, targets and both teammates' shares of tick 2, in all 24 orders."""
    seen = set()
    for order in itertools.permutations(sense(2) + [share(0, "r2"), share(0, "r3")]):
        gate, calls = tracking_gate()
        for key, m in sense(0):
            gate.put(key, m)
        for key, m in order:
            gate.put(key, m)
        assert len(calls) == 2
        t, inp = calls[1]
        seen.add((t, inp["pose"].stamp, inp["targets"].stamp, tuple((r, s.stamp) for r, s in inp["team"].items())))
    assert seen == {(0.256, 0.256, 0.256, (("r2", 0.0), ("r3", 0.0)))}


def test_lockstep_a_gone_teammate_is_not_waited_for():
    gate, calls = tracking_gate()
    for key, m in sense(0) + sense(2) + [share(0, "r2")]:
        gate.put(key, m)
    assert len(calls) == 1
    gate.teammate("r3", False)  # every token of r3 vanished
    assert len(calls) == 2 and set(calls[1][1]["team"]) == {"r2"}


def test_realtime_runs_when_the_tick_is_complete_or_when_the_next_begins():
    gate, calls = motor_gate(RealtimeGate)
    gate.put(*target(0))
    for j in range(N):
        gate.put(*obstacle(0, j))
    assert len(calls) == 1  # the first field ran at once (nothing else heard of yet); tick 0 is done
    for j in range(N - 1):  # tick 1 without obstacle 11's field ...
        gate.put(*obstacle(1, j))
    assert len(calls) == 1
    gate.put(*obstacle(2, 0))  # ... until tick 2 begins: tick 1 runs with what came
    assert len(calls) == 2 and calls[1][0] == tick_time(1) and 11 in calls[1][1]["obstacles"]
    assert calls[1][1]["obstacles"][11].stamp == tick_time(0)  # the latest of each source


def test_realtime_a_stale_value_counts_as_missing():
    gate, calls = motor_gate(RealtimeGate)
    for k in range(6):
        if k % 2 == 0 and k < 4:  # the target module died after tick 2
            gate.put(*target(k))
        for j in range(N):
            if not (j == 4 and k > 0):  # sensor 4's module died after tick 0
                gate.put(*obstacle(k, j))
    by_tick = {round(t / 0.128): seen for t, seen in calls}
    assert 4 in by_tick[2]["obstacles"]  # two periods old at tick 2: at its limit, still used
    assert 4 not in by_tick[3]["obstacles"]  # three: left out, not waited for
    # tick 4 waited for a target field that never came, and ran when tick 5 began, with the
    # field of tick 2 (two of its periods old: still used)
    assert by_tick[4]["target"].stamp == tick_time(2)
    assert set(gate.stale_drops) == {K.field_obstacle("r1", 4)}  # counted once, however many ticks it stays stale


@pytest.mark.parametrize("stale_s", [0.0, 0.1, 0.128, 0.2, 0.256, 0.5, 0.512, 1.0, 1.024, 3.0])
def test_realtime_max_age_is_the_most_ticks_within_the_staleness_limit(stale_s):
    from cekm_swarm.node.timing import _max_age
    from cekm_swarm.ticks import TICK_S

    n = _max_age(stale_s)
    assert n * TICK_S <= stale_s + 1e-9 < (n + 1) * TICK_S
    assert _max_age(float("inf")) == float("inf")
