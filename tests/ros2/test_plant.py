"""The ROS 2 plant's pure parts: robot messages -> the graph's sense readings, wheel
commands -> Twists, the robot description, and bad input refused with its reason."""

import math

import numpy as np
import pytest

from cekm_swarm.robot import RobotBody
from cekm_swarm.ros2 import plant as P
from cekm_swarm.ros2.interfaces import interfaces

IFC = interfaces()
DESC = P.RobotDescription()
NOW = 100.0


def header(frame, t=NOW):
    sec = int(t)
    return IFC.make("std_msgs/msg/Header", frame_id=frame,
                    stamp=IFC.make("builtin_interfaces/msg/Time", sec=sec, nanosec=int(round((t - sec) * 1e9))))


def odom_cdr(x=1.0, y=2.0, yaw=0.5, frame="odom", child="base_link", t=NOW, q=None):
    q = q or (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    pose = IFC.make("geometry_msgs/msg/Pose", position=IFC.make("geometry_msgs/msg/Point", x=x, y=y, z=0.0),
                    orientation=IFC.make("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3]))
    m = IFC.make(P.ODOMETRY, header=header(frame, t), child_frame_id=child,
                 pose=IFC.make("geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=np.zeros(36)))
    return IFC.cdr(m, P.ODOMETRY)


def scan_cdr(ranges, a0=-math.pi, inc=None, frame="base_scan", t=NOW, a1=None, rmax=3.5):
    ranges = np.asarray(ranges, dtype=np.float32)
    inc = inc if inc is not None else 2 * math.pi / len(ranges)
    a1 = a1 if a1 is not None else a0 + inc * (len(ranges) - 1)
    m = IFC.make(P.LASER_SCAN, header=header(frame, t), angle_min=a0, angle_max=a1, angle_increment=inc,
                 range_min=0.01, range_max=rmax, ranges=ranges)
    return IFC.cdr(m, P.LASER_SCAN)


def test_odometry_gives_the_pose_and_yaw():
    o = P.decode_odometry(IFC, odom_cdr(1.0, 2.0, 0.5), DESC, "r1", NOW)
    assert (o.x, o.y) == (1.0, 2.0) and o.theta == pytest.approx(0.5) and o.stamp == pytest.approx(NOW)
    o = P.decode_odometry(IFC, odom_cdr(frame="r1/odom", child="r1/base_link"), DESC, "r1", NOW)  # namespaced frames
    assert o.x == 1.0


@pytest.mark.parametrize("kwargs, reason", [
    ({"x": float("nan")}, P.NOT_FINITE),
    ({"q": (0.0, 0.0, 0.0, 0.0)}, P.NOT_FINITE),
    ({"q": (float("nan"), 0.0, 0.0, 1.0)}, P.NOT_FINITE),
    ({"frame": "world"}, P.UNKNOWN_FRAME),
    ({"child": "r2/base_link"}, P.UNKNOWN_FRAME),
    ({"t": NOW - 2.0}, P.STALE),
    ({"t": 0.0}, P.STALE),
    ({"t": NOW + 5.0}, P.AHEAD),
])
def test_bad_odometry_is_refused_with_its_reason(kwargs, reason):
    with pytest.raises(P.Refused) as e:
        P.decode_odometry(IFC, odom_cdr(**kwargs), DESC, "r1", NOW)
    assert e.value.reason == reason


@pytest.mark.parametrize("payload", [b"", b"\x00\x01\x00\x00", b"\x07" * 40, b"\x00\x01\x00\x00" + b"\xff" * 13,
                                     odom_cdr()[:-9]])
def test_malformed_cdr_is_refused(payload):
    with pytest.raises(P.Refused) as e:
        P.decode_odometry(IFC, payload, DESC, "r1", NOW)
    assert e.value.reason == P.MALFORMED
    with pytest.raises(P.Refused):
        P.decode_scan(IFC, payload, DESC, "r1", NOW)


def test_the_scan_is_sampled_at_the_sensor_directions():
    """360 beams from -180 deg; beam i looks at -180 + i deg: the reading of sensor j
    (direction 30 j deg) is the beam at that direction, from the robot's centre."""
    ranges = np.full(360, np.inf)
    ranges[180] = 0.10  # straight ahead: sensor 0
    ranges[270] = 0.15  # 90 deg left: sensor 3
    ranges[0] = 0.05  # behind: sensor 6 (180 deg)
    ranges[150] = 0.5  # -30 deg: sensor 11, beyond 0.03 + 0.17 m: nothing seen
    ranges[210] = float("nan")  # 30 deg: sensor 1, no answer
    scan = P.decode_scan(IFC, scan_cdr(ranges), DESC, "r1", NOW)
    d = P.scan_readings(scan, DESC.body)
    assert len(d) == 12
    assert d[0] == pytest.approx(0.10) and d[3] == pytest.approx(0.15) and d[6] == pytest.approx(0.05)
    assert d[11] is None and d[1] is None and d[2] is None
    assert P.scan_readings(scan, RobotBody(sensor_range=0.5))[11] == pytest.approx(0.5)


def test_a_scan_from_zero_to_a_full_turn_wraps():
    ranges = np.full(360, np.inf)
    ranges[359] = 0.1  # 359 deg = -1 deg
    ranges[180] = 0.12  # 180 deg
    scan = P.decode_scan(IFC, scan_cdr(ranges, a0=0.0), DESC, "r1", NOW)
    d = P.scan_readings(scan, DESC.body)
    assert d[6] == pytest.approx(0.12) and d[0] is None  # sensor 0 at 0 deg: beam 0 (inf)


@pytest.mark.parametrize("kwargs, reason", [
    ({"ranges": np.ones(100), "inc": 2 * math.pi / 360}, P.WRONG_LENGTH),  # 100 ranges, angles say 360
    ({"ranges": np.ones(360), "frame": "camera"}, P.UNKNOWN_FRAME),
    ({"ranges": np.ones(360), "t": NOW - 1.0}, P.STALE),
    ({"ranges": np.ones(360), "inc": float("nan")}, P.NOT_FINITE),
    ({"ranges": np.ones(91), "a0": -math.pi / 4, "inc": math.pi / 180}, P.NOT_COVERED),  # a 90-deg scan
])
def test_bad_scans_are_refused_with_their_reason(kwargs, reason):
    ranges = kwargs.pop("ranges")
    if "inc" in kwargs and math.isfinite(kwargs["inc"]) and len(ranges) == 100:
        kwargs["a1"] = -math.pi + kwargs["inc"] * 359
    with pytest.raises(P.Refused) as e:
        P.decode_scan(IFC, scan_cdr(ranges, **kwargs), DESC, "r1", NOW)
    assert e.value.reason == reason


def test_range_messages_are_from_the_surface():
    def rng(r, frame="r1/range_3", t=NOW):
        return IFC.cdr(IFC.make(P.RANGE, header=header(frame, t), min_range=0.0, max_range=0.17, range=r), P.RANGE)
    assert P.decode_range(IFC, rng(0.1), DESC, "r1", 3, NOW)[1] == pytest.approx(0.13)
    assert P.decode_range(IFC, rng(float("inf")), DESC, "r1", 3, NOW)[1] is None
    assert P.decode_range(IFC, rng(0.5), DESC, "r1", 3, NOW)[1] is None
    with pytest.raises(P.Refused, match="unknown frame"):
        P.decode_range(IFC, rng(0.1, "r1/range_4"), DESC, "r1", 3, NOW)
    with pytest.raises(P.Refused, match="NaN"):
        P.decode_range(IFC, rng(float("nan")), DESC, "r1", 3, NOW)


def test_goal_pose_and_clock():
    pose = IFC.make("geometry_msgs/msg/Pose", position=IFC.make("geometry_msgs/msg/Point", x=1.5, y=-0.5, z=0.0),
                    orientation=IFC.make("geometry_msgs/msg/Quaternion", w=1.0))
    goal = IFC.cdr(IFC.make(P.POSE_STAMPED, header=header("map"), pose=pose), P.POSE_STAMPED)
    assert P.decode_goal(IFC, goal, DESC, "r1") == (1.5, -0.5)
    clock = IFC.cdr(
        IFC.make(P.CLOCK, clock=IFC.make("builtin_interfaces/msg/Time", sec=12, nanosec=500_000_000)), P.CLOCK
    )
    assert P.decode_clock(IFC, clock) == 12.5


def test_target_reading_is_the_goal_in_the_robots_frame():
    o = P.Odom(0.0, 1.0, 1.0, math.pi / 2, 0.0, 0.0)
    alpha, d, visible = P.target_reading(o, (1.0, 2.0))  # straight ahead, 1 m
    assert alpha == pytest.approx(0.0, abs=1e-12) and d == pytest.approx(1.0) and visible
    alpha, d, _ = P.target_reading(o, (0.0, 1.0))  # to the left (x decreasing when facing +y)
    assert alpha == pytest.approx(math.pi / 2)
    assert P.target_reading(o, (1.0004, 1.0)) == (0.0, 0.0, True)  # within half a millimetre: the goal state
    assert P.target_reading(o, (5.0, 1.0), target_range=2.0)[2] is False


def test_twist_of_wheels_uses_the_declared_axle_and_clips():
    body = RobotBody()
    v, w = P.twist_of(0.1, 0.12, body)
    assert v == pytest.approx(0.11) and w == pytest.approx(0.02 / body.axle)
    v, w = P.twist_of(1.0, 1.0, body)
    assert v == pytest.approx(body.v_max) and w == 0.0
    msg = IFC.from_cdr(P.twist_cdr(IFC, 0.11, 0.4), P.TWIST)
    assert (msg.linear.x, msg.angular.z, msg.linear.y) == (pytest.approx(0.11), pytest.approx(0.4), 0.0)


def test_description_file_and_body_check(tmp_path):
    f = tmp_path / "bot.toml"
    f.write_text('axle = 0.3\nmax_wheel_speed = 0.5\nsensor_angles_deg = [0, 90, 180, -90]\nsensors = "range"\n')
    desc = P.load_description(f)
    assert desc.body.axle == 0.3 and desc.body.v_max == 0.5 and desc.sensors == "range"
    assert desc.body.sensors == 4 and desc.body.sensor_angles[2] == pytest.approx(math.pi)
    assert desc.body.body_radius == RobotBody().body_radius  # the rest from the default
    assert P.RobotDescription.from_dict(desc.to_dict()) == desc
    with pytest.raises(P.DescriptionError, match=r"bot.toml: the robot's body differs .*axle 0.3 m \(the model's: "
                                                 r"0.053 m\).*4 distance sensors"):
        P.check_body(desc.body, RobotBody(), str(f))
    P.check_body(RobotBody(), RobotBody(), "the same body")  # no error
    for text, what in [("axel = 1", "unknown key 'axel'"), ("axle = -1", "axle = -1"), ("axle = 'x'", "axle"),
                       ("sensors = 'sonar'", "sensors = 'sonar'"), ("sensor_angles_deg = [400]", "sensor_angles_deg"),
                       ("axle = ", "not a TOML")]:
        f.write_text(text)
        with pytest.raises(P.DescriptionError, match=what):
            P.load_description(f)
    with pytest.raises(P.DescriptionError, match="cannot read"):
        P.load_description(tmp_path / "missing.toml")


def test_targets_of_a_tracking_run():
    def poses(*xy, frame="odom"):
        ps = [IFC.make("geometry_msgs/msg/Pose", position=IFC.make("geometry_msgs/msg/Point", x=x, y=y, z=0.0),
                       orientation=IFC.make("geometry_msgs/msg/Quaternion", w=1.0)) for x, y in xy]
        return IFC.cdr(IFC.make(P.POSE_ARRAY, header=header(frame), poses=ps), P.POSE_ARRAY)
    targets = P.decode_targets(IFC, poses((1.0, 1.0), (3.0, 0.0)), DESC, ["t1", "t2"], NOW)
    assert targets == {"t1": (1.0, 1.0), "t2": (3.0, 0.0)}
    seen = P.targets_seen(P.Odom(NOW, 1.0, 0.5, 0.0, 0.0, 0.0), targets, 0.6)
    assert list(seen) == ["t1"] and seen["t1"][0] == pytest.approx(math.pi / 2) and seen["t1"][1] == pytest.approx(0.5)
    for payload, reason in [(poses((1.0, 1.0)), P.WRONG_LENGTH), (poses((1.0, 1.0), (float("nan"), 0.0)), P.NOT_FINITE),
                            (poses((1.0, 1.0), (2.0, 2.0), frame="r1/base_link"), P.UNKNOWN_FRAME)]:
        with pytest.raises(P.Refused) as e:
            P.decode_targets(IFC, payload, DESC, ["t1", "t2"], NOW)
        assert e.value.reason == reason
