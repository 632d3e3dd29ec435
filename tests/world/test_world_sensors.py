"""Range and target sensors against analytic geometry (real pymunk worlds)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from world import World, parse_scenario

R = 0.03
V = 0.16 / 1.024


def make(robots, obstacles=(), targets=(), walls=(), bounds=(0.0, 0.0, 2.0, 2.0), sensors=None, seed=0):
    doc = {
        "seed": seed,
        "arena": {"bounds": list(bounds)},
        "robots": [dict(r) for r in robots],
        "targets": [dict(t) for t in targets],
        "walls": [dict(w) for w in walls],
        "obstacles": [dict(o) for o in obstacles],
    }
    if sensors:
        doc["sensors"] = dict(sensors)
    return World(parse_scenario(doc, source="<test>"))


def test_sensor_angles():
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.0]}])
    a = w.sensor_angles
    assert a.shape == (12,)
    assert a[0] == 0.0
    assert a[6] == pytest.approx(math.pi)
    assert np.all(a > -math.pi) and np.all(a <= math.pi)
    assert np.allclose(np.sort(np.mod(a, 2 * math.pi)), 2 * math.pi * np.arange(12) / 12)
    assert a[3] == pytest.approx(math.pi / 2) and a[9] == pytest.approx(-math.pi / 2)
    assert w.body_radius == R


@pytest.mark.parametrize("gap", [0.0, 0.02, 0.05, 0.1, 0.16])
def test_range_to_wall_matches_geometry(gap):
    # east boundary wall's inner face is x = 2.0; sensor 0 faces it at surface range gap
    w = make([{"id": "r1", "start": [2.0 - R - gap, 1.0, 0.0]}])
    true = w.true_ranges("r1")
    assert true[0] == pytest.approx(gap, abs=1e-9)
    for j in (1, 11):  # +-30 degrees: slanted distance to the same face
        expect = (gap + R) / math.cos(math.pi / 6) - R
        if expect <= 0.17:
            assert true[j] == pytest.approx(expect, abs=1e-9)
        else:
            assert math.isnan(true[j])
    for j in (3, 4, 5, 6, 7, 8, 9):  # facing away or along the wall: nothing within range
        assert math.isnan(true[j])
    reads = np.array([w.range_readings("r1")[0] for _ in range(3000)])
    # one reading: true x (1 +- 10 %), quantized to 5 mm
    assert np.all(np.abs(reads - gap) <= 0.1 * gap + 0.0025 + 1e-12)
    assert np.allclose(reads / 0.005, np.round(reads / 0.005), atol=1e-9)
    # many readings: unbiased
    assert reads.mean() == pytest.approx(gap, abs=0.0006 + 0.02 * gap)


def test_range_nan_beyond_range_and_edge():
    w = make([{"id": "r1", "start": [2.0 - R - 0.171, 1.0, 0.0]}])
    assert math.isnan(w.true_ranges("r1")[0])
    assert math.isnan(w.range_readings("r1")[0])
    w = make([{"id": "r1", "start": [2.0 - R - 0.169, 1.0, 0.0]}])
    assert w.true_ranges("r1")[0] == pytest.approx(0.169, abs=1e-9)
    assert not math.isnan(w.range_readings("r1")[0])


def test_sensor_range_is_a_scenario_field():
    w = make([{"id": "r1", "start": [2.0 - R - 0.25, 1.0, 0.0]}], sensors={"range": 0.3})
    assert w.sensor_range == 0.3
    assert w.true_ranges("r1")[0] == pytest.approx(0.25, abs=1e-9)


def test_alone_robot_sees_nothing_rays_skip_own_body():
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.3]}])
    assert np.all(np.isnan(w.true_ranges("r1")))
    assert np.all(np.isnan(w.range_readings("r1")))


def test_robots_see_each_other():
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.0]}, {"id": "r2", "start": [1.1, 1.0, math.pi]}])
    t1 = w.true_ranges("r1")
    t2 = w.true_ranges("r2")
    assert t1[0] == pytest.approx(0.1 - 2 * R, abs=1e-9)
    assert t2[0] == pytest.approx(0.1 - 2 * R, abs=1e-9)
    assert math.isnan(t1[6]) and math.isnan(t2[6])
    # sideways neighbour seen by the side sensor (j = 3 is +90 degrees, to the left)
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.0]}, {"id": "r2", "start": [1.0, 1.15, 0.0]}])
    assert w.true_ranges("r1")[3] == pytest.approx(0.15 - 2 * R, abs=1e-9)
    assert w.true_ranges("r2")[9] == pytest.approx(0.15 - 2 * R, abs=1e-9)


def test_rays_see_static_and_moving_obstacles():
    w = make(
        [{"id": "r1", "start": [1.0, 1.0, math.pi / 2]}],
        obstacles=[
            {"shape": "disc", "center": [1.0, 1.2], "radius": 0.05},  # ahead (heading +y)
            {
                "shape": "box",
                "size": [0.1, 0.1],
                "motion": {"type": "line", "a": [0.8, 1.0], "b": [0.5, 1.0], "speed": 0.01},
            },
        ],
    )
    t = w.true_ranges("r1")
    assert t[0] == pytest.approx(0.2 - 0.05 - R, abs=1e-9)
    # the box (its near face at x = 0.85) is to the robot's left: sensor 3
    assert t[3] == pytest.approx(1.0 - 0.85 - R, abs=1e-9)


def test_readings_never_negative_when_touching():
    w = make([{"id": "r1", "start": [2.0 - R - 0.01, 1.0, 0.0]}])
    w.set_wheels("r1", V, V)
    w.advance(2.0)
    assert w.in_contact("r1")
    for _ in range(50):
        r = w.range_readings("r1")
        assert r[0] >= 0.0 and r[0] <= 0.005


def test_target_reading_geometry():
    # heading +y; target 1 m ahead, 0.5 m to the left and 0.8 m behind
    w = make(
        [{"id": "r1", "start": [1.0, 1.0, math.pi / 2], "goal": "ahead"}],
        targets=[
            {"id": "ahead", "position": [1.0, 2.0]},
            {"id": "left", "position": [0.5, 1.0]},
            {"id": "behind", "position": [1.0, 0.2]},
            {"id": "diag", "position": [1.6, 1.8]},
        ],
        bounds=(0.0, 0.0, 3.0, 3.0),
    )
    assert w.goal_of("r1") == (1.0, 2.0)
    for _ in range(200):
        a, d, vis = w.target_reading("r1")
        assert vis and abs(a) < 1e-12 and 0.9 - 1e-9 <= d <= 1.1 + 1e-9
        assert d * 1000 == pytest.approx(round(d * 1000), abs=1e-6)
        a, d, vis = w.target_reading("r1", "left")
        assert a == pytest.approx(math.pi / 2, abs=1e-9) and 0.45 - 1e-9 <= d <= 0.55 + 1e-9
        a, d, vis = w.target_reading("r1", "behind")
        assert a == pytest.approx(math.pi, abs=1e-9) and a > 0 and 0.72 - 1e-9 <= d <= 0.88 + 1e-9
    # general direction: robot frame (0.8, -0.6) -> alpha = atan2(-0.6, 0.8), d = 1
    samples = np.array([w.target_reading("r1", "diag")[:2] for _ in range(4000)])
    assert np.all(samples[:, 1] <= 1.1 + 1e-9) and np.all(samples[:, 1] >= 0.9 - 1e-9)
    assert samples[:, 0].mean() == pytest.approx(math.atan2(-0.6, 0.8), abs=0.005)
    assert samples[:, 1].mean() == pytest.approx(1.0, abs=0.005)
    # every alpha lies between the extremes the +-10 % coordinate noise allows
    lo, hi = math.atan2(-0.66, 0.72), math.atan2(-0.54, 0.88)
    assert np.all(samples[:, 0] >= lo - 1e-12) and np.all(samples[:, 0] <= hi + 1e-12)


def test_target_reading_quantization_and_zero():
    w = make(
        [{"id": "r1", "start": [1.0, 1.0, 0.7], "goal": "here"}],
        targets=[{"id": "here", "position": [1.0, 1.0]}, {"id": "tiny", "position": [1.0003, 1.0002]}],
    )
    assert w.target_reading("r1") == (0.0, 0.0, True)
    assert w.target_reading("r1", "tiny") == (0.0, 0.0, True)  # 0.36 mm rounds to 0
    w.set_goal("r1", (1.0, 1.0025))  # 2.5 mm +- 10 %: 2 or 3 mm after rounding
    vals = {w.target_reading("r1")[1] for _ in range(300)}
    assert vals <= {0.002, 0.003} and len(vals) == 2


def test_target_visibility_by_range():
    w = make(
        [{"id": "r1", "start": [1.0, 1.0, 0.0]}],
        targets=[{"id": "near", "position": [1.4, 1.0]}, {"id": "far", "position": [1.0, 1.6]}],
        sensors={"target_range": 0.5},
    )
    a, d, vis = w.target_reading("r1", "near")
    assert vis and abs(a) < 1e-12 and 0.36 <= d <= 0.44
    a, d, vis = w.target_reading("r1", "far")
    assert not vis and math.isnan(a) and math.isnan(d)
    with pytest.raises(ValueError):
        w.target_reading("r1")  # no goal set
    with pytest.raises(KeyError):
        w.target_reading("r1", "nope")
    with pytest.raises(KeyError):
        w.target_reading("r9")


def test_goal_follows_a_moving_target():
    w = make(
        [{"id": "r1", "start": [0.5, 0.5, 0.0], "goal": "t"}],
        targets=[{"id": "t", "motion": {"type": "circle", "center": [1.0, 1.0], "radius": 0.3, "angular_speed": 0.5}}],
    )
    assert w.goal_of("r1") == pytest.approx((1.3, 1.0))
    w.advance(1.0)
    a = 0.5 * w.time
    assert w.goal_of("r1") == pytest.approx((1.0 + 0.3 * math.cos(a), 1.0 + 0.3 * math.sin(a)), abs=1e-12)


@pytest.mark.slow
def test_skipping_rays_when_nothing_is_near_is_exact():
    # the world skips the 12 ray casts when its nearest-surface query finds nothing
    # within range; forcing the casts must give the same answer everywhere
    from world import ScenarioError, load_scenario

    checked = 0
    for x in np.arange(0.1, 3.0, 0.13):
        for y in np.arange(0.1, 1.2, 0.11):
            try:
                sc = load_scenario("checkpoints", overrides={"robots[0].start": [float(x), float(y), 0.3]})
            except ScenarioError:
                continue  # start inside something
            w = World(sc)
            fast = w.true_ranges("r1")
            w._ranges.near[0] = True
            slow = w.true_ranges("r1")
            assert np.array_equal(fast, slow, equal_nan=True)
            checked += 1
    assert checked > 150
