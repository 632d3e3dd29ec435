import math

import numpy as np
import pytest

from cekm_swarm.experiments.arena import Arena, displacement, drive, executed_command, keep_inside, move, sense_target
from cekm_swarm.robot import KHEPERA, quantize_speed

E = np.empty(0)


def test_straight_move_and_arc_are_exact():
    x, y, th, ds = move(0.0, 0.0, 0.0, 0.1, 0.1, 1.0, 0.053)
    assert (x, y, th, ds) == pytest.approx((0.1, 0.0, 0.0, 0.1))
    # quarter circle of radius 0.1: omega = (vr - vl)/axle
    axle = 0.05
    om = math.pi / 2
    v = 0.1 * om
    x, y, th, ds = move(0.0, 0.0, 0.0, v - om * axle / 2, v + om * axle / 2, 1.0, axle)
    assert (x, y, th) == pytest.approx((0.1, 0.1, math.pi / 2))
    assert ds == pytest.approx(v)


def test_pure_turn_displacement_uses_half_the_heading_change():
    a, d = displacement(1.0, 1.0, 0.3, 1.0, 1.0, 0.8)
    assert d == 0.0 and a == pytest.approx(0.4)
    a, d = displacement(0.0, 0.0, math.pi / 2, 0.0, 0.1, 0.0)  # straight ahead in the robot frame
    assert a == pytest.approx(0.0) and d == pytest.approx(0.1)


def test_target_sensor_quantization_and_goal_state():
    a, d = sense_target(0.0, 0.0, 0.0, 0.0, 0.1234, 1.0, 1.0, 0.001)
    assert a == pytest.approx(math.pi / 2) and d == pytest.approx(0.123)
    assert sense_target(0.0, 0.0, 0.0, 0.0004, 0.0, 1.0, 1.0, 0.001) == (0.0, 0.0)
    a, d = sense_target(0.0, 0.0, 0.0, 1.0, 0.0, 1.1, 1.0, 0.001)  # noise factor scales the coordinate
    assert d == pytest.approx(1.1)


def test_walls_clamp_and_report():
    assert keep_inside(0.01, 0.5, 0.03, 4.97) == (0.03, 0.5, True)
    assert keep_inside(0.5, 0.5, 0.03, 4.97) == (0.5, 0.5, False)
    arena = Arena()
    pose = np.array([0.05, 2.5, math.pi])  # facing the wall at x = 0
    path, touched, _ = drive(pose, 0.15, 0.15, np.ones((32, 2)), arena.vector(), 0, 0, E, E, E, 0, 0)
    assert touched and pose[0] == pytest.approx(arena.body_radius)


def test_drive_records_first_time_within_eps():
    arena = Arena()
    pose = np.array([1.0, 1.0, 0.0])
    eps = np.array([0.01, 0.05])
    t_eps, p_eps = np.full(2, np.nan), np.full(2, np.nan)
    path, _, _ = drive(pose, 0.1, 0.1, np.ones((32, 2)), arena.vector(), 1.08, 1.0, eps, t_eps, p_eps, 10.0, 2.0)
    # 0.1 m/s straight: within 5 cm after 0.3 s, within 1 cm after 0.7 s (sub-step resolution 0.032 s)
    assert t_eps[1] - 10.0 == pytest.approx(0.32, abs=0.033) and t_eps[0] - 10.0 == pytest.approx(0.704, abs=0.033)
    assert p_eps[1] == pytest.approx(2.0 + 0.1 * (t_eps[1] - 10.0))
    assert path == pytest.approx(0.1024)


# ---------------------------------------------------------------- wheel-speed quantization


def test_khepera_speed_unit_is_one_pulse_per_10_ms():
    assert KHEPERA.speed_unit == pytest.approx(0.08e-3 / 0.01)  # 0.08 mm per pulse, per 10 ms: 8 mm/s


def test_executed_speeds_are_whole_multiples_of_the_unit():
    unit, v_max = 0.008, KHEPERA.v_max
    rng = np.random.default_rng(0)
    for c in rng.uniform(-0.3, 0.3, size=2000):
        q = quantize_speed(float(c), unit, v_max)
        n = q / unit
        assert abs(n - round(n)) < 1e-9  # a whole number of units
        assert abs(q) <= v_max  # never beyond c*
        if abs(c) <= v_max - unit / 2:
            assert abs(q - c) <= unit / 2 + 1e-12  # the nearest multiple
    assert quantize_speed(0.0039, unit, v_max) == 0.0 and quantize_speed(-0.0039, unit, v_max) == 0.0
    assert quantize_speed(0.0041, unit, v_max) == pytest.approx(0.008)
    assert quantize_speed(0.05, 0.0, v_max) == 0.05  # unit 0: continuous
    av = Arena(speed_unit=0.008).vector()
    assert executed_command(0.0123, -0.9, av) == pytest.approx((0.016, -19 * 0.008))  # clipped to c*, then quantized


def test_a_command_under_half_a_unit_stops_the_robot():
    """In the test runner a command whose both wheels are under 4 mm/s executes as c = 0: the
    robot stops where it is (the paper's stop, c = 0), while the same command on continuous
    wheels creeps on until the step budget ends."""
    from cekm_swarm.experiments.streams import Schedule, TrialStreams
    from cekm_swarm.experiments.trial import test_reference

    schedule = Schedule(steps=10, test_interval=10, test_targets=3, test_budget=20)
    creep = lambda u: np.array([0.0039, -0.0035])  # noqa: E731
    quantized = test_reference(
        creep, TrialStreams(1, 0, Arena(speed_unit=KHEPERA.speed_unit), schedule), np.array([0.005])
    )
    assert quantized.stopped.all() and (quantized.steps == 0).all() and (quantized.path == 0).all()
    continuous = test_reference(creep, TrialStreams(1, 0, Arena(speed_unit=0.0), schedule), np.array([0.005]))
    assert not continuous.stopped.any() and (continuous.path > 0).all()


def test_bad_speed_unit_is_refused():
    from cekm_swarm.errors import ParameterError

    with pytest.raises(ParameterError, match="speed_unit"):
        Arena(speed_unit=-0.001)
    with pytest.raises(ParameterError, match="speed_unit"):
        Arena(speed_unit=1.0)
