"""The movers' detector and the command that keeps clear of them (cekm_swarm.controller.movers)."""

import math

import numpy as np
import pytest

from cekm_swarm.controller.movers import MoverDetector, MoverParams, clearance, fit_disc, keep_clear

ANGLES = [math.atan2(math.sin(2 * math.pi * j / 12), math.cos(2 * math.pi * j / 12)) for j in range(12)]
REACH = 0.2  # m from the centre a ray sees
AXLE = 0.053
V = 0.156


def wall_readings(pose, wall_x):
    """The 12 readings of a robot at ``pose`` in front of the infinite wall x = wall_x."""
    x, _, th = pose
    out = []
    for a in ANGLES:
        c = math.cos(th + a)
        d = (wall_x - x) / c if c > 1e-9 else math.inf
        out.append((a, d if d <= REACH else None))
    return out


def disc_readings(pose, centre, radius=0.04):
    """The 12 readings of a robot at ``pose`` seeing only a disc at ``centre``."""
    x, y, th = pose
    out = []
    for a in ANGLES:
        ux, uy = math.cos(th + a), math.sin(th + a)
        fx, fy = centre[0] - x, centre[1] - y
        along = fx * ux + fy * uy
        off2 = fx * fx + fy * fy - along * along
        d = along - math.sqrt(radius * radius - off2) if along > 0 and off2 < radius * radius else None
        out.append((a, d if d is not None and d <= REACH else None))
    return out


@pytest.mark.parametrize("turn", [0.0, 0.06, 0.12])
@pytest.mark.parametrize("heading", [0.0, 0.3, 0.6, 1.0, 1.2])
@pytest.mark.parametrize("wall_x", [0.15, 0.25])
def test_a_wall_the_robot_drives_at_and_turns_before_is_no_mover(turn, heading, wall_x):
    """Every hit of a still wall lies where the rays before ended, at any heading, while the
    robot drives at it (0.02 m a tick) and while it turns in place before it."""
    det = MoverDetector(reach=REACH)
    x, th = 0.0, heading
    for k in range(40):
        pose = (x, 0.0, th)
        assert det.update(k * 0.128, pose, wall_readings(pose, wall_x)) == []
        if k < 20 or turn == 0.0:
            x += 0.02 if x < wall_x - 0.08 else 0.0
        else:
            th += turn


def noisy(readings, rng, body=0.03):
    """The world's range noise: the surface range times 1 + U(-0.1, 0.1), to 5 mm."""
    out = []
    for a, d in readings:
        if d is not None:
            d = min(body + round((d - body) * (1.0 + rng.uniform(-0.1, 0.1)) / 0.005) * 0.005, REACH)
        out.append((a, d))
    return out


def crossing(speed, noise_seed=None, drive=0.0):
    """A disc crossing the robot's front 0.12 m ahead, up at ``speed``, the robot driving
    ahead at ``drive``: per tick, the disc's centre and what the detector returns."""
    det = MoverDetector(reach=REACH)
    rng = np.random.default_rng(noise_seed)
    out = []
    for k in range(int(0.4 / speed / 0.128) + 1):
        t = k * 0.128
        pose = (drive * t, 0.0, 0.0)
        centre = (0.12 + drive * 0.4 / speed / 2.0, -0.2 + speed * t)
        readings = disc_readings(pose, centre)
        out.append((centre, det.update(t, pose, readings if noise_seed is None else noisy(readings, rng))))
    return out


@pytest.mark.parametrize("speed", [0.05, 0.1])
def test_a_disc_crossing_into_free_space_is_found_where_it_is_moving_its_way(speed):
    """Once found for half a second, the disc's fitted centre and velocity are the truth's
    (an alpha-beta filter on centres guessed from single hits was 0.05 m/s off, as slow as
    the discs; the fit uses the rays that miss the disc as well)."""
    run = crossing(speed)
    found = [k for k, (_, movers) in enumerate(run) if movers]
    assert found
    settled = [(c, m) for c, movers in run[found[0] + 4:] for m in movers if abs(c[1]) < 0.1]
    assert len(settled) >= 8
    assert np.median([math.hypot(m[0] - c[0], m[1] - c[1]) for c, m in settled]) < 0.01
    assert np.median([math.hypot(m[2], m[3] - speed) for c, m in settled]) < 0.01


def test_a_fast_disc_hit_by_one_ray_at_a_time_is_found_near_where_it_is():
    """At 0.15 m/s a disc 0.12 m ahead crosses the gap between two rays in a tick or two and
    is hit by one ray at a time: one ray's hits do not tell its velocity (the fit takes its
    sliding across the ray for a radial motion), but it is found, near where it is."""
    run = crossing(0.15)
    near = [math.hypot(m[0] - c[0], m[1] - c[1]) for c, movers in run for m in movers]
    assert len(near) >= 5 and np.median(near) < 0.05


def test_under_the_sensors_noise_the_velocity_is_still_the_discs():
    """The same crossing at the rooms' 0.07 m/s with the world's range noise, the robot
    driving at it, on eight noise draws: the median velocity error is a third of the disc's
    speed (the alpha-beta filter's was 0.05-0.07 m/s, the disc's speed itself)."""
    errors = []
    for noise_seed in range(8):
        run = crossing(0.07, noise_seed, drive=0.05)
        errors += [math.hypot(m[2], m[3] - 0.07) for c, movers in run for m in movers if abs(c[1]) < 0.1]
    assert len(errors) >= 50
    assert np.median(errors) < 0.03


@pytest.mark.parametrize("truth", [(0.12, 0.03, 0.02, 0.12), (0.11, 0.02, -0.05, 0.06)])
def test_fit_disc_recovers_a_disc_from_rays_on_several_ticks(truth):
    """Noiseless hits of a disc crossing rays over six ticks (x, y, vx, vy now), from a guess
    0.02 m and 0.09 m/s off: the fit is the truth to a millimetre and 5 mm/s. (Hits of one
    ray alone do not tell a disc crossing it from one beside it standing still.)"""
    truth = np.array(truth)
    hits, rays = [], []
    for k in range(-5, 1):
        dt = k * 0.128
        centre = (truth[0] + truth[2] * dt, truth[1] + truth[3] * dt)
        for (a, d) in disc_readings((0.0, 0.0, 0.0), centre):
            ux, uy = math.cos(a), math.sin(a)
            if d is None:
                rays.append((0.0, 0.0, ux, uy, REACH, dt))
            else:
                hits.append((d * ux, d * uy, dt))
                rays.append((0.0, 0.0, ux, uy, d - 0.001, dt))
    q = fit_disc(truth + np.array([0.02, -0.015, -0.05, 0.08]), np.array(hits), np.array(rays), 0.04, 0.01, 1.0)
    assert np.allclose(q[:2], truth[:2], atol=1e-3) and np.allclose(q[2:], truth[2:], atol=5e-3)


def test_two_tracks_of_one_disc_are_merged():
    """A first guess left behind and the fit that caught the disc: one mover, the later."""
    det = MoverDetector(reach=REACH)
    for k in range(12):
        t = k * 0.128
        movers = det.update(t, (0.0, 0.0, 0.0), disc_readings((0.0, 0.0, 0.0), (0.12, -0.2 + 0.15 * t)))
        centres = [(m[0], m[1]) for m in movers]
        assert all(math.hypot(a[0] - b[0], a[1] - b[1]) > 1.5 * 0.04 for i, a in enumerate(centres)
                   for b in centres[i + 1:])


def test_keep_clear_backs_away_from_a_disc_coming_at_the_front():
    pose = (0.0, 0.0, 0.0)
    movers = [(0.15, -0.12, 0.0, 0.12)]  # ahead and to the right, coming up across the path
    reach = 0.027 + 0.04
    assert clearance(pose, (V, V), movers, reach, AXLE, 1.5) < 0.0
    cmd = keep_clear(pose, (V, V), movers, reach, AXLE, V, MoverParams())
    assert cmd != (V, V) and clearance(pose, cmd, movers, reach, AXLE, 1.5) > 0.0


def test_keep_clear_does_not_drive_into_a_wall_to_escape_a_mover():
    """A disc coming at the robot from behind: forward is the escape, unless a wall is 3 cm
    ahead of the body, when the replacement must not close on it."""
    pose = (0.0, 0.0, 0.0)
    movers = [(-0.12, 0.05, 0.1, -0.04)]
    reach = 0.03 + 0.04
    assert keep_clear(pose, (0.0, 0.0), movers, reach, AXLE, V, MoverParams()) == (V, V)
    wall = [(0.06, y / 100) for y in range(-5, 6, 2)]
    cmd = keep_clear(pose, (0.0, 0.0), movers, reach, AXLE, V, MoverParams(), wall)
    assert cmd != (V, V)
    still = [(x, y, 0.0, 0.0) for x, y in wall]
    assert clearance(pose, cmd, still, 0.03, AXLE, MoverParams().still_horizon) >= MoverParams().margin


def test_keep_clear_leaves_a_safe_command_alone():
    pose = (0.0, 0.0, 0.0)
    far = [(1.0, 1.0, 0.0, 0.0)]
    assert keep_clear(pose, (V, 0.1), far, 0.067, AXLE, V, MoverParams()) == (V, 0.1)
    assert keep_clear(pose, (V, 0.1), [], 0.067, AXLE, V, MoverParams()) == (V, 0.1)


@pytest.mark.parametrize("name,value,words", [("history", 0, "mover history must be >= 1 tick"),
                                              ("eps", 0.0, "mover eps must be > 0"),
                                              ("margin", -0.1, "mover margin must be >= 0")])
def test_bad_parameters_are_refused_by_name(name, value, words):
    with pytest.raises(ValueError, match=words):
        MoverParams(**{name: value}).check()
