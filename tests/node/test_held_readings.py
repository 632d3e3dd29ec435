"""Held readings: a reading whose every reader is a pure node of it alone may be left out
while it is unchanged; the readers' readers take the pure node's previous output,
restamped, for the tick. Which readings the plan lets the world hold, the gates' side
(lockstep and real time, the value arriving before or after the hold) and the protocol's
``sense/unchanged`` message, without Zenoh."""

from __future__ import annotations

import numpy as np
import pytest

from cekm_swarm.node import Node
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.node.runner import Runner
from cekm_swarm.node.timing import LockstepGate, RealtimeGate
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import (
    KeyKind,
    MessageError,
    ObstacleField,
    TargetField,
    Unchanged,
    WheelCommand,
    decode,
    encode,
    with_stamp,
)
from cekm_swarm.ticks import tick_time

N = 12


def test_the_default_navigation_graph_holds_only_the_target_reading():
    """The default's motor reads every raw range (the movers' detector, docs/fields.md), so
    the world sends each range reading every tick; only the target reading may be held."""
    plan = check_graph("cekm-navigation").plan(("r1",), "navigation")
    assert plan.held_readings("r1") == [K.sense_target("r1")]


def test_the_constant_width_navigation_graph_holds_every_reading_its_pure_localizations_read():
    plan = check_graph("cekm-tuned-navigation").plan(("r1", "r2"), "navigation")
    assert plan.held_readings("r1") == [K.sense_target("r1")] + [K.sense_range("r1", j) for j in range(N)]
    motor = plan.node("r1", "motor")
    holds = plan.holds(motor)
    assert list(holds) == [K.sense_unchanged("r1")]  # its own robot's, no teammate's
    assert holds[K.sense_unchanged("r1")][K.sense_range("r1", 4)] == (K.field_obstacle("r1", 4),)
    assert holds[K.sense_unchanged("r1")][K.sense_target("r1")] == (K.field_target("r1"),)
    assert plan.listens(motor)[-1] == K.sense_unchanged("r1")
    assert plan.holds(plan.node("r1", "obstacle-4")) == {}  # a reader of readings learns nothing from it


def test_a_reading_with_a_stateful_or_many_keyed_reader_is_not_held():
    tracking = check_graph("cekm-tracking").plan(("r1", "r2", "r3"), "tracking")
    held = tracking.held_readings("r2")
    assert held == [K.sense_range("r2", j) for j in range(N)]  # pose and targets: the stateful tracker reads them
    fusion = check_graph("fusion-navigation").plan(("r1",), "navigation")
    assert K.sense_range("r1", 0) not in fusion.held_readings("r1")  # avoidance reads all 12 at once


def test_a_pure_reader_of_a_held_reading_takes_any_stamp_in_bounds_and_its_reader_judges_the_output():
    from cekm_swarm.node.process import stamp_window

    plan = check_graph("cekm-tuned-navigation").plan(("r1",), "navigation")
    obstacle, motor = stamp_window(plan, plan.node("r1", "obstacle-4")), stamp_window(plan, plan.node("r1", "motor"))
    for w in (obstacle, motor):
        assert w.check(tick_time(100)) is None
    # the reading held for 500 ticks comes next: its reader takes it (no window of its own)
    assert obstacle.check(tick_time(600)) is None and obstacle.check(tick_time(3)) is None
    assert obstacle.check(tick_time(600) + 0.01) is not None  # off the grid: still refused
    assert obstacle.check(1e18) is not None  # out of bounds: still refused
    # the motor hears from the world every tick: 8 ticks either side of its newest
    assert motor.check(tick_time(110)) is not None and motor.check(tick_time(90)) is not None
    plan_off = check_graph("fusion-navigation").plan(("r1",), "navigation")  # its ranges are not held
    assert all(stamp_window(plan_off, n).future == stamp_window(plan, plan.node("r1", "motor")).future
               for n in plan_off.nodes["r1"])


def test_holding_can_be_turned_off_in_the_run_spec():
    checked = check_graph("cekm-tuned-navigation")
    from cekm_swarm.graph.resolve import build_plan

    plan = build_plan(checked.graph, ("r1",), "navigation", checked.ports, hold=False)
    assert plan.held_readings("r1") == [] and plan.holds(plan.node("r1", "motor")) == {}


class Recorder(Node):
    """Stands in for the motor: records what each step saw, answers with a command."""

    def __init__(self, calls):
        self.calls = calls

    def step(self, t, inputs):
        self.calls.append((t, {p: inputs[p] for p in inputs}))
        return {"command": WheelCommand(t, "r1/motor", 0.0, 0.0, 0)}


def gate(cls=LockstepGate):
    plan = check_graph("cekm-tuned-navigation").plan(("r1",), "navigation")
    from cekm_swarm.modules.motor_integration import MotorIntegration

    calls = []
    rec = Recorder(calls)
    rec.outputs = MotorIntegration.outputs
    return cls(Runner(plan.node("r1", "motor"), rec)), calls


def obstacle(k, j, seen=False):
    b = np.full(8, 0.5) if seen else None
    return K.field_obstacle("r1", j), ObstacleField(tick_time(k), f"r1/obstacle-{j}", j, 1 if seen else None, b)


def target(k):
    return K.field_target("r1"), TargetField(tick_time(k), "r1/target", 2, np.ones(8), 0.1, 0.5)


def tick_zero(g):
    for key, m in [target(0)] + [obstacle(0, j, seen=j == 3) for j in range(N)]:
        g.put(key, m)


@pytest.mark.parametrize("cls", [LockstepGate, RealtimeGate])
def test_a_held_field_stands_for_the_tick_restamped(cls):
    g, calls = gate(cls)
    tick_zero(g)
    assert len(calls) == 1
    out = []
    for j in range(N - 1):  # readings 0..10 unchanged since tick 0; 11 sent
        out += g.hold(K.field_obstacle("r1", j), 1, 0)
    assert out == [] or cls is RealtimeGate and not calls[1:]
    out += g.put(*obstacle(1, 11))
    assert [k for k, _ in out] == [K.cmd_wheels("r1")]
    t, seen = calls[-1]
    assert t == tick_time(1)
    assert {f.stamp for f in seen["obstacles"].values()} == {tick_time(1)}  # as if each had run at tick 1
    assert seen["obstacles"][3] == with_stamp(obstacle(0, 3, seen=True)[1], tick_time(1))
    assert g.holds == N - 1


def test_lockstep_a_hold_that_comes_before_its_value_waits_for_it():
    g, calls = gate()
    tick_zero(g)
    for j in range(N):
        g.put(*obstacle(1, j))
    g.put(*target(0))
    assert len(calls) == 2
    # tick 2: reading 5 was sent at tick 1 and is unchanged; its field of tick 1 is here, so
    # a hold naming tick 1 is at once usable; a hold naming a tick whose value is late waits
    g2, calls2 = gate()
    tick_zero(g2)
    out = []
    for j in range(N):
        if j != 5:
            out += g2.put(*obstacle(1, j))
    out += g2.hold(K.field_obstacle("r1", 5), 2, 1)  # for tick 2, from tick 1's field, not here yet
    for j in range(N):
        if j != 5:
            out += g2.hold(K.field_obstacle("r1", j), 2, 1)
    out += g2.put(*target(2))  # (the target field comes every TARGET_EVERY = 2 ticks)
    assert len(calls2) == 1 and g2.pending_holds
    out = g2.put(*obstacle(1, 5, seen=True))  # it comes: tick 1 runs, then tick 2 with it restamped
    assert [tick for tick, _ in calls2] == [0.0, tick_time(1), tick_time(2)]
    assert calls2[-1][1]["obstacles"][5].winner == 1 and calls2[-1][1]["obstacles"][5].stamp == tick_time(2)
    assert len(out) == 2


def test_lockstep_a_hold_from_long_ago_uses_what_stood_for_the_ticks_since():
    g, calls = gate()
    tick_zero(g)
    for k in range(1, 40):  # nothing changes for 39 ticks: each tick from tick 0's values
        for j in range(N):
            g.hold(K.field_obstacle("r1", j), k, 0)
        if k % 2 == 0:  # the target reading: every 2 ticks
            g.hold(K.field_target("r1"), k, 0)
    assert [t for t, _ in calls] == [tick_time(k) for k in range(40)]  # the store forgot tick 0 long ago


def test_realtime_a_hold_from_long_ago_uses_what_stood_for_the_ticks_since():
    """Tick after tick the world names the same ``since``: the value restamped for the last
    tick stands for this one too, so the motor answers every tick (a real-time run missed
    its deadline on the second tick of every held stretch before)."""
    g, calls = gate(RealtimeGate)
    tick_zero(g)
    for k in range(1, 40):
        for j in range(N):
            g.hold(K.field_obstacle("r1", j), k, 0)
        if k % 2 == 0:
            g.hold(K.field_target("r1"), k, 0)
    assert [t for t, _ in calls] == [tick_time(k) for k in range(40)]
    assert g.holds == 39 * N + 19


@pytest.mark.parametrize("cls", [LockstepGate, RealtimeGate])
def test_holds_taken_at_once_run_as_one_after_another(cls):
    """``hold_all`` (one look for runs after every hold of a message) runs the same ticks
    with the same inputs as ``hold`` per key, also with values that come late."""
    seen = {}
    for batch in (False, True):
        rng = np.random.default_rng(7)
        g, calls = gate(cls)
        tick_zero(g)
        late, sent = None, dict.fromkeys(range(N), 0)  # reading j last sent at tick sent[j]
        for k in range(1, 30):
            changed = set(rng.choice(N, size=3, replace=False).tolist()) if k % 5 == 0 else set()
            holds = [(K.field_obstacle("r1", j), k, sent[j]) for j in range(N) if j not in changed]
            sent.update(dict.fromkeys(changed, k))
            if k % 2 == 0:
                holds.append((K.field_target("r1"), k, 0))
            for j in sorted(changed):
                if late is None:
                    late = obstacle(k, j, seen=True)  # comes after the holds that stand on it
                else:
                    g.put(*obstacle(k, j, seen=True))
            if batch:
                g.hold_all(holds)
            else:
                for h in holds:
                    g.hold(*h)
            if late is not None:
                g.put(*late)
                late = None
        seen[batch] = [(t, {j: (f.stamp, f.winner) for j, f in inp["obstacles"].items()}) for t, inp in calls]
    assert seen[True] == seen[False] and len(seen[True]) > 20


def test_the_unchanged_message_names_readings_sent_before_it():
    m = Unchanged(1.28, "world", ("sense/range/3", "sense/target"), (0.128, 0.0))
    assert decode(K.sense_unchanged("r1"), encode(m)) == m
    assert K.parse(K.sense_unchanged("r1")).kind is KeyKind.SENSE_UNCHANGED
    for keys, since, why in [
        (("sense/range/3",), (1.28,), "not before"),
        (("sense/range/3",), (0.0, 0.1), "values for"),
        (("sense/range/3", "sense/range/3"), (0.0, 0.1), "named twice"),
        (("field/obstacle/3",), (0.0,), "not matching"),
    ]:
        with pytest.raises(MessageError, match=why):
            Unchanged(1.28, "world", keys, since)
