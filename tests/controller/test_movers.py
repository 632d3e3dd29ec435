"""The movers' detector and the command that keeps clear of them (cekm_swarm.controller.movers)."""

import math

import pytest

from cekm_swarm.controller.movers import MoverDetector, MoverParams, clearance, keep_clear

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


@pytest.mark.parametrize("speed", [0.05, 0.1, 0.15])
def test_a_disc_crossing_into_free_space_is_tracked_moving_its_way(speed):
    """A disc crossing the robot's front 0.12 m away, up at ``speed``: it is found while it
    crosses, near where it is; from 0.1 m/s, mostly moving up (a slow disc's velocity is
    dominated by its centre's estimate jumping between rays 30 degrees apart)."""
    det = MoverDetector(reach=REACH)
    pose = (0.0, 0.0, 0.0)
    found = []
    for k in range(int(0.4 / speed / 0.128) + 1):
        t = k * 0.128
        centre = (0.12, -0.2 + speed * t)
        for mx, my, _, vy in det.update(t, pose, disc_readings(pose, centre)):
            found.append((math.hypot(mx - centre[0], my - centre[1]), vy))
    assert found
    assert all(gap < 0.06 for gap, _ in found)
    if speed >= 0.1:
        assert sum(vy > 0.0 for _, vy in found) > len(found) / 2


def test_keep_clear_backs_away_from_a_disc_coming_at_the_front():
    pose = (0.0, 0.0, 0.0)
    movers = [(0.15, -0.12, 0.0, 0.12)]  # ahead and to the right, coming up across the path
    reach = 0.027 + 0.04
    assert clearance(pose, (V, V), movers, reach, AXLE, 1.5) < 0.0
    cmd = keep_clear(pose, (V, V), movers, reach, AXLE, V, MoverParams())
    assert cmd != (V, V) and clearance(pose, cmd, movers, reach, AXLE, 1.5) > 0.0


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
