"""Robot kinematics, wheel noise, collisions, moving obstacles (real pymunk worlds)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from world import World, load_scenario, parse_scenario

R = 0.03
AXLE = 0.053
V = 0.16 / 1.024
DT = 0.032


def make(robots, obstacles=(), walls=(), bounds=(0.0, 0.0, 2.0, 2.0), seed=0):
    doc = {
        "seed": seed,
        "arena": {"bounds": list(bounds)},
        "robots": [dict(r) for r in robots],
        "walls": [dict(w) for w in walls],
        "obstacles": [dict(o) for o in obstacles],
    }
    return World(parse_scenario(doc, source="<test>"))


def test_constants_and_clipping():
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.0]}])
    assert w.substep == DT and w.time == 0.0 and w.robot_ids == ["r1"]
    w.set_wheels("r1", 1.0, -7.0)
    s = w.state()["robots"]["r1"]
    assert s["v_l"] == V and s["v_r"] == -V
    with pytest.raises(ValueError):
        w.set_wheels("r1", float("nan"), 0.0)
    with pytest.raises(KeyError):
        w.set_wheels("nobody", 0.0, 0.0)
    w.advance(1.0)
    assert w.time == pytest.approx(31 * DT)  # round(1.0 / 0.032) = 31 sub-steps
    w.advance(0.0)
    assert w.time == pytest.approx(31 * DT)


def test_free_motion_is_the_exact_arc_of_the_executed_wheel_speeds():
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.4]}])
    cmds = [(0.1, 0.12), (V, -V), (0.05, 0.05), (-0.08, 0.02), (0.0, 0.0)]
    for vl, vr in cmds:
        w.set_wheels("r1", vl, vr)
        for _ in range(5):
            x0, y0, th0 = w.pose("r1")
            w.step()  # the command acts in the same sub-step (no lag)
            s = w.state()["robots"]["r1"]
            el, er = s["v_l_exec"], s["v_r_exec"]
            assert abs(el - vl) <= 0.1 * abs(vl) + 1e-15 and abs(er - vr) <= 0.1 * abs(vr) + 1e-15
            v, om = 0.5 * (el + er), (er - el) / AXLE
            if abs(om) > 1e-9:
                x1 = x0 + v / om * (math.sin(th0 + om * DT) - math.sin(th0))
                y1 = y0 - v / om * (math.cos(th0 + om * DT) - math.cos(th0))
            else:
                x1, y1 = x0 + v * DT * math.cos(th0), y0 + v * DT * math.sin(th0)
            x, y, th = w.pose("r1")
            assert x == pytest.approx(x1, abs=1e-9) and y == pytest.approx(y1, abs=1e-9)
            assert math.remainder(th - th0 - om * DT, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_wheel_noise_mean_and_spread():
    # turning in place keeps the robot in the open for thousands of sub-steps
    w = make([{"id": "r1", "start": [1.0, 1.0, 0.0]}], seed=5)
    w.set_wheels("r1", 0.1, -0.1)
    ratios = []
    dtheta = []
    for _ in range(6000):
        th0 = w.pose("r1")[2]
        w.step()
        s = w.state()["robots"]["r1"]
        ratios.append((s["v_l_exec"] / 0.1, s["v_r_exec"] / -0.1))
        dtheta.append(math.remainder(w.pose("r1")[2] - th0, 2 * math.pi))
    r = np.array(ratios)
    assert r.min() >= 0.9 and r.max() <= 1.1
    sd = 0.2 / math.sqrt(12.0)
    for k in (0, 1):
        assert r[:, k].mean() == pytest.approx(1.0, abs=0.003)
        assert r[:, k].std() == pytest.approx(sd, rel=0.04)
    assert abs(np.corrcoef(r[:, 0], r[:, 1])[0, 1]) < 0.05  # independent per wheel
    # the body really turns by the executed speeds: mean rate 2 * 0.1 / axle
    om = np.array(dtheta) / DT
    assert om.mean() == pytest.approx(-2 * 0.1 / AXLE, rel=0.003)
    assert om.std() == pytest.approx((0.1 / AXLE) * sd * math.sqrt(2.0), rel=0.05)
    # turning in place translates only by the wheel-speed difference:
    # |v| = 0.05 |u_l - u_r|, E|u_l - u_r| = 0.2 / 3 (triangular on [-0.2, 0.2])
    assert w.stats("r1")["path_length_m"] == pytest.approx(6000 * DT * 0.05 * 0.2 / 3, rel=0.05)


def test_straight_run_distance():
    w = make([{"id": "r1", "start": [0.3, 1.0, 0.0]}], seed=2)
    w.set_wheels("r1", 0.1, 0.1)
    w.advance(8.0)
    st = w.stats("r1")
    assert st["path_length_m"] == pytest.approx(0.1 * w.time, rel=0.01)
    assert st["collisions"] == 0 and st["contact_s"] == 0.0
    assert st["min_clearance_m"] == pytest.approx(0.3 - R, abs=1e-9)  # the start, by the west wall


@pytest.mark.parametrize("heading", [0.0, 0.5, 1.0, 1.35])
def test_full_speed_into_a_wall_never_passes_it(heading):
    # east boundary wall: inner face x = 2.0; drive at it for 15 s at full speed
    w = make([{"id": "r1", "start": [1.7, 0.6, heading]}], bounds=(0.0, 0.0, 2.0, 3.0))
    w.set_wheels("r1", V, V)
    worst = -1.0
    for _ in range(470):
        w.step()
        x, y, _ = w.pose("r1")
        worst = max(worst, x + R - 2.0)
        assert x < 2.0
    assert worst < 0.002
    assert worst > -0.001  # it did reach the wall
    st = w.stats("r1")
    assert st["collisions"] >= 1 and -0.002 < st["min_clearance_m"] < 0.0005
    assert 0.0 < st["contact_s"] < w.time


@pytest.mark.parametrize("heading", [0.0, 0.7])
def test_thin_interior_wall_is_never_tunnelled(heading):
    # a 4 mm wall across the arena at x = 1.0
    w = make(
        [{"id": "r1", "start": [0.7, 1.0, heading]}],
        walls=[{"a": [1.0, 0.0], "b": [1.0, 2.0], "thickness": 0.004}],
    )
    w.set_wheels("r1", V, V)
    for _ in range(400):
        w.step()
        x, y, _ = w.pose("r1")
        assert x + R - 0.998 < 0.002
    assert w.in_contact("r1")


def test_robot_backs_off_and_turns_after_contact():
    w = make([{"id": "r1", "start": [1.9, 1.0, 0.0]}])
    w.set_wheels("r1", V, V)
    w.advance(2.0)
    assert w.in_contact("r1")
    w.set_wheels("r1", -0.1, -0.1)
    w.advance(1.0)
    assert not w.in_contact("r1")
    assert w.pose("r1")[0] < 2.0 - R - 0.07
    th0 = w.pose("r1")[2]
    w.set_wheels("r1", -0.1, 0.1)
    w.advance(0.512)  # 16 sub-steps at 0.2 / axle rad/s
    assert math.remainder(w.pose("r1")[2] - th0, 2 * math.pi) == pytest.approx(0.512 * 0.2 / AXLE, rel=0.05)


def test_two_robots_collide_and_do_not_overlap():
    w = make([{"id": "r1", "start": [0.8, 1.0, 0.0]}, {"id": "r2", "start": [1.2, 1.0, math.pi]}])
    w.set_wheels("r1", V, V)
    w.set_wheels("r2", V, V)
    for _ in range(200):
        w.step()
        (x1, y1, _), (x2, y2, _) = w.pose("r1"), w.pose("r2")
        assert math.hypot(x2 - x1, y2 - y1) > 2 * R - 0.003
    assert w.stats("r1")["collisions"] >= 1 and w.stats("r2")["collisions"] >= 1


def test_moving_obstacles_circle_anticlockwise_on_script():
    sc = load_scenario("rooms")
    w = World(sc)
    movers = [o for o in sc.obstacles if o.motion is not None]
    assert len(movers) == 2
    angles = {o.id: [] for o in movers}
    for _ in range(300):
        w.step()
        st = w.state()["obstacles"]
        for o in movers:
            px, py = o.motion.position(w.time)
            assert st[o.id]["x"] == pytest.approx(px, abs=1e-9) and st[o.id]["y"] == pytest.approx(py, abs=1e-9)
            cx, cy = o.motion.center
            angles[o.id].append(math.atan2(st[o.id]["y"] - cy, st[o.id]["x"] - cx))
    for o in movers:
        a = np.unwrap(angles[o.id])
        assert np.all(np.diff(a) > 0)  # anticlockwise: the angle increases
        assert a[-1] - a[0] == pytest.approx(o.motion.angular_speed * 299 * DT, rel=1e-6)


def test_line_obstacle_pushes_a_robot():
    w = make(
        [{"id": "r1", "start": [1.0, 1.0, 0.0]}],
        obstacles=[
            {
                "id": "pusher",
                "shape": "box",
                "size": [0.1, 0.1],
                "motion": {"type": "line", "a": [0.5, 1.0], "b": [1.5, 1.0], "speed": 0.1},
            }
        ],
    )
    for _ in range(220):  # 7 s: the box travels 0.70 m, to x = 1.2
        w.step()
        ox = w.state()["obstacles"]["pusher"]["x"]
        x = w.pose("r1")[0]
        assert x - R - (ox + 0.05) > -0.003  # never deeply inside the box
    assert w.pose("r1")[0] > 1.2 + 0.05 + R - 0.003
    assert w.stats("r1")["collisions"] == 1


def test_a_robot_a_moving_box_pushes_through_the_boundary_wall_is_reported():
    """A box sweeping the whole width of a 1 m arena at 0.3 m/s squeezes a robot driving
    into the east wall; pymunk cannot hold a kinematic body, so the robot goes through. The
    world says when (stats' left_arena_s, in every outcome); without the box the robot
    stops at the wall, and nothing is reported."""
    plow = {"id": "plow", "shape": "box", "size": [0.98, 0.1],
            "motion": {"type": "line", "a": [0.5, 0.95], "b": [0.5, 0.05], "speed": 0.3}}
    for obstacles in ([plow], []):
        w = make([{"id": "r1", "start": [0.2, 0.5, 0.0]}], obstacles=obstacles, bounds=(0.0, 0.0, 1.0, 1.0))
        w.set_wheels("r1", 0.1, 0.1)
        for _ in range(400):  # 12.8 s
            w.step()
        left = w.stats("r1")["left_arena_s"]
        if obstacles:
            assert left is not None and 1.0 < left < 12.8 and not 0.0 <= w.pose("r1")[0] <= 1.0
        else:
            assert left is None and w.pose("r1")[0] < 1.0
    # without boundary walls leaving the bounds is no fault, and nothing is reported
    free_doc = {"seed": 0, "arena": {"bounds": [0.0, 0.0, 2.0, 2.0], "boundary_walls": False},
                "robots": [{"id": "r1", "start": [1.9, 1.0, 0.0]}]}
    free = World(parse_scenario(free_doc, source="<test>"))
    free.set_wheels("r1", 0.05, 0.05)
    for _ in range(200):
        free.step()
    assert free.pose("r1")[0] > 2.0 and free.stats("r1")["left_arena_s"] is None


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_robot_fits_through_the_86_mm_doorway(seed):
    sc = load_scenario("doorway", overrides={"robots[0].start": [1.38, 1.0, 0.0]})
    w = World(sc, seed=seed)
    w.set_wheels("r1", V, V)
    w.advance(2.5)
    x, y, _ = w.pose("r1")
    assert x > 1.55 + R  # through the 0.10 m deep gap
    assert abs(y - 1.0) < 0.043
