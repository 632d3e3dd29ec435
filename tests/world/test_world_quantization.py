"""Wheel-speed quantization in the pymunk world (``[plant] speed_unit``): the Khepera's
motor controller executes whole speed units, and a command below half a unit is a stop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from world import World, parse_scenario
from world.scenario import WHEEL_SPEED_UNIT, ScenarioError
from world.sim import V_MAX, quantize_speed

UNIT = WHEEL_SPEED_UNIT


def make(speed_unit=None, seed=0):
    doc = {"seed": seed, "arena": {"bounds": [0.0, 0.0, 2.0, 2.0]}, "robots": [{"id": "r1", "start": [1.0, 1.0, 0.3]}]}
    if speed_unit is not None:
        doc["plant"] = {"speed_unit": speed_unit}
    return World(parse_scenario(doc, source="<test>"))


def test_quantize_speed_rounds_to_whole_units_within_the_limit():
    assert quantize_speed(0.49 * UNIT, UNIT) == 0.0
    assert quantize_speed(-0.49 * UNIT, UNIT) == 0.0
    assert quantize_speed(0.5 * UNIT, UNIT) == pytest.approx(UNIT)
    assert quantize_speed(-1.6 * UNIT, UNIT) == pytest.approx(-2 * UNIT)
    top = math.floor(V_MAX / UNIT) * UNIT
    assert top <= V_MAX and quantize_speed(V_MAX, UNIT) == pytest.approx(top)
    assert quantize_speed(0.0123, 0.0) == 0.0123  # unit 0: continuous


def test_a_command_below_half_a_unit_stops_the_robot():
    w = make(UNIT)
    x0, y0, th0 = w.pose("r1")
    w.set_wheels("r1", 0.45 * UNIT, -0.3 * UNIT)
    assert w.wheel_command("r1") == (0.0, 0.0)
    w.advance(1.024)
    assert w.pose("r1") == (x0, y0, th0)
    # the same command on a continuous plant moves it
    c = make(0.0)
    c.set_wheels("r1", 0.45 * UNIT, -0.3 * UNIT)
    c.advance(1.024)
    assert c.pose("r1") != (x0, y0, th0)


def test_executed_speeds_are_whole_units_times_the_slip_noise():
    w = make(UNIT, seed=3)
    top = math.floor(V_MAX / UNIT) * UNIT  # the fastest whole number of units within v*
    rng = np.random.default_rng(0)
    for _ in range(50):
        vl, vr = rng.uniform(-1.2 * V_MAX, 1.2 * V_MAX, size=2)
        w.set_wheels("r1", vl, vr)
        held = w.wheel_command("r1")
        for v, cmd in zip(held, (vl, vr), strict=True):
            n = v / UNIT
            assert abs(n - round(n)) < 1e-9  # a whole number of units
            assert abs(v) <= V_MAX
            assert abs(v - max(-top, min(top, cmd))) <= 0.5 * UNIT + 1e-12
        w.step()
        s = w.state()["robots"]["r1"]
        for ex, v in ((s["v_l_exec"], held[0]), (s["v_r_exec"], held[1])):
            assert abs(ex - v) <= 0.1 * abs(v) + 1e-15  # slip noise acts on the quantized speed


def test_plant_speed_unit_is_validated():
    with pytest.raises(ScenarioError, match=r"plant\.speed_unit.*>= 0"):
        make(-0.001)
    with pytest.raises(ScenarioError, match=r"plant: unknown key|plant\.unit"):
        World(parse_scenario({"arena": {"bounds": [0, 0, 1, 1]}, "robots": [{"id": "r1", "start": [0.5, 0.5, 0]}],
                              "plant": {"unit": 0.008}}, source="<test>"))


def test_the_world_unit_is_the_robot_unit():
    from cekm_swarm import robot

    unit = getattr(robot.Khepera(), "speed_unit", None)
    if unit is None:
        pytest.skip("cekm_swarm.robot.Khepera.speed_unit not defined on this branch yet")
    assert unit == WHEEL_SPEED_UNIT


def _episode(start_x, speed_unit):
    from world.episode import Episode

    doc = {"seed": 1, "arena": {"bounds": [0.0, 0.0, 2.0, 2.0]}, "plant": {"speed_unit": speed_unit},
           "robots": [{"id": "r1", "start": [start_x, 1.0, 0.0], "goal": "g"}],
           "targets": [{"id": "g", "position": [1.0, 1.0]}]}
    return Episode(World(parse_scenario(doc, source="<test>")))


def test_a_stop_within_the_goal_radius_reaches_the_goal():
    ep = _episode(0.98, UNIT)  # 2 cm short of the goal
    ep.readings()
    ep.apply({"r1": (0.004, 0.003)})  # moves on: not a stop
    assert not ep.done
    ep.advance()
    ep.readings()
    ep.apply({"r1": (0.3 * UNIT, -0.2 * UNIT)})  # quantizes to zero: a stop at the goal
    assert ep.done and ep.outcome()["r1"]["reached"] and ep.outcome()["r1"]["time_s"] == ep.t


def test_a_stop_far_from_the_goal_is_not_reaching_it():
    ep = _episode(0.5, UNIT)
    ep.readings()
    ep.apply({"r1": (0.001, 0.001)})
    assert not ep.done and not ep.outcome()["r1"]["reached"]
