"""A real-time node on a timer of its own (graph ``timer = S``, cekm_swarm.node.timer_gate),
without Zenoh: it runs when its timer fires, at the newest tick it has heard of, with the
newest value of each input, at most once a tick; its timer keeps a fixed grid and skips
what it missed; the graph refuses a bad timer; lockstep and ``cekm run`` ignore it."""

from __future__ import annotations

import pytest
from test_timing import motor_gate, obstacle, target

from cekm_swarm.graph.spec import GraphError, load_graph
from cekm_swarm.node.runner import Runner
from cekm_swarm.node.timer_gate import Timer, TimerGate
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import Clock
from cekm_swarm.ticks import tick_time


def timer_gate():
    gate, calls = motor_gate()
    runner: Runner = gate.runner
    return TimerGate(runner, clock_key=K.world_clock()), calls


def test_a_timer_node_runs_when_its_timer_fires_at_the_newest_tick_once_a_tick():
    gate, calls = timer_gate()
    assert gate.fire() == [] and gate.idle == 1  # no tick heard of yet
    gate.put(*target(0))
    for j in range(12):
        gate.put(*obstacle(0, j))
    assert calls == []  # a complete tick does not run it: its timer does
    gate.put(*obstacle(1, 3))
    gate.put(K.world_clock(), Clock(tick_time(3), "world", 3))  # the clock: tick 3 has begun
    out = gate.fire()
    assert [c[0] for c in calls] == [tick_time(3)] and out and all(m.stamp == tick_time(3) for _, m in out)
    seen = calls[0][1]
    assert seen["obstacles"][3].stamp == tick_time(1)  # the newest value of each source ...
    assert 0 not in seen["obstacles"] and seen["target"].stamp == tick_time(0)  # ... within its staleness limit
    assert gate.fire() == [] and gate.idle == 2 and len(calls) == 1  # no new tick: not again
    gate.put(*obstacle(4, 0))
    gate.fire()
    assert [c[0] for c in calls] == [tick_time(3), tick_time(4)]


def test_the_timer_keeps_its_grid_and_skips_what_it_missed():
    timer = Timer(0.5)
    assert timer.wait(10.0) == 0.5  # due 10.5
    assert timer.wait(10.6) == pytest.approx(0.4)  # due 11.0 (the grid, not 0.5 after 10.6)
    assert timer.wait(12.2) == pytest.approx(0.3)  # 11.5 and 12.0 missed: skipped, due 12.5
    assert timer.due == pytest.approx(12.5)


def graph_with_timer(tmp_path, timer) -> str:
    """The shipped cekm-navigation graph with a timer on its target node."""
    from cekm_swarm.graph.spec import shipped_graphs

    text = shipped_graphs()["cekm-navigation"].read_text()
    f = tmp_path / "g.toml"
    f.write_text(text.replace("every = 2 ", f"timer = {timer}\nevery = 2 ", 1))
    return str(f)


@pytest.mark.parametrize("bad", ["0", "0.001", "-1", '"fast"', "true", "nan", "4000"])
def test_the_graph_refuses_a_timer_that_is_not_a_number_of_seconds(tmp_path, bad):
    with pytest.raises(GraphError, match=r"node 'target'\.timer: .*expected seconds between 0.01 and 3600"):
        load_graph(graph_with_timer(tmp_path, bad))


def test_a_timer_is_carried_by_the_run_spec_and_used_in_real_time_only(tmp_path):
    from types import SimpleNamespace

    from cekm_swarm.graph.spec import Graph

    g = load_graph(graph_with_timer(tmp_path, 0.3))
    assert g.node("target").timer == 0.3 and g.node("target").every == 2  # its lockstep rate: its every
    assert Graph.from_dict(g.to_dict()) == g
    assert "timer" not in g.to_dict()["nodes"][1]  # a node without one: its run spec as before
    assert TimerGate.fits(SimpleNamespace(decl=g.node("target")), "realtime")
    assert not TimerGate.fits(SimpleNamespace(decl=g.node("target")), "lockstep")
    assert not TimerGate.fits(SimpleNamespace(decl=g.node("motor")), "realtime")
