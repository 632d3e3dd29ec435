"""A small differential-drive robot simulator that lives in ROS 2, written on PyPI's
``zenoh-ros2-sdk`` (independent of this project's ROS 2 code; it imports nothing of
``cekm_swarm`` nor ``world``): the robots of the ROS 2 plant's end-to-end tests.

``python diffdrive_sim.py HOST:PORT MSG_DIR DOMAIN CONFIG_JSON``; CONFIG_JSON holds
``robots`` ({id: [x, y, theta]}), ``bounds`` [xmin, ymin, xmax, ymax] (walls), ``disc``
[cx, cy, r], ``rate_hz`` (odometry and scan), ``body_radius``, ``beams``; optional
``clock_offset`` (s: ROS time is the wall clock less this), ``publish_clock`` (``/clock``),
``wheel_noise`` (each wheel's speed off by up to this fraction, as the simulated Khepera's),
``axle``, ``seed``, and ``targets`` ([x, y, vx, vy] each: points moving straight, turning
back at the walls, published together as a ``geometry_msgs/msg/PoseArray`` on ``/targets``).

Each robot publishes ``nav_msgs/msg/Odometry`` on ``/<id>/odom`` (frame ``odom``, child
``base_link``) and a ``sensor_msgs/msg/LaserScan`` on ``/<id>/scan`` (frame ``base_scan``,
``beams`` rays over a full turn from -pi, ranges from the robot's centre to the walls,
the disc and the other robots) at ``rate_hz``, and integrates the Twists it receives on
``/<id>/cmd_vel`` (unicycle, 200 Hz; a Twist holds until the next). A robot that would enter
the disc, a wall or another robot is pushed back to its surface and slides along it, as a
rigid body would (each new contact counted).

Stdout: ``READY``, then ``TWIST <id> <monotonic s> <v> <omega>`` per Twist, and on
``quit`` (stdin) ``DONE {json}``: per robot the pose, the smallest clearance to the disc
and to anything, contacts, Twists. Stdin ``goal <id> <x> <y>`` publishes a
``geometry_msgs/msg/PoseStamped`` on ``/<id>/goal_pose``; ``bad <id>`` a burst of bad input on
the robot's topics (printed as ``BAD {json}`` with how many of each kind).
"""

from __future__ import annotations

import json
import math
import struct
import sys
import threading
import time

import numpy as np
import zenoh

router, msg_dir, domain, config = sys.argv[1], sys.argv[2], int(sys.argv[3]), json.loads(sys.argv[4])
host, port = router.rsplit(":", 1)

from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber, ZenohSession, get_message_class, get_registry  # noqa: E402

get_registry(msg_dir)
session = ZenohSession.get_instance(host, int(port))
out_lock = threading.Lock()


def say(*parts: str) -> None:
    with out_lock:
        print(*parts, flush=True)


T = {n: get_message_class(n) for n in (
    "builtin_interfaces/msg/Time", "std_msgs/msg/Header", "geometry_msgs/msg/Point", "geometry_msgs/msg/Quaternion",
    "geometry_msgs/msg/Pose", "geometry_msgs/msg/PoseWithCovariance", "geometry_msgs/msg/Vector3",
    "geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistWithCovariance")}
BOUNDS, DISC = config["bounds"], config["disc"]
RADIUS, BEAMS, RATE = config["body_radius"], config["beams"], config["rate_hz"]
STEP = 0.005
OFFSET = config.get("clock_offset", 0.0)
"""ROS time = wall time - OFFSET: every stamp, and ``/clock`` when ``publish_clock`` (as a simulator's)."""


def stamp(t: float):
    return T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=int((t - int(t)) * 1e9))


def header(t: float, frame: str):
    return T["std_msgs/msg/Header"](stamp=stamp(t), frame_id=frame)


class Robot:
    def __init__(self, rid: str, pose: list[float]) -> None:
        self.id = rid
        self.x, self.y, self.th = pose
        self.v = self.w = 0.0
        self.min_disc = self.min_any = math.inf
        self.contacts = self.twists = 0
        self.touching = False
        ns = f"/{rid}"
        self.odom = ROS2Publisher(f"{ns}/odom", "nav_msgs/msg/Odometry", domain_id=domain, router_ip=host,
                                  router_port=int(port))
        self.scan = ROS2Publisher(f"{ns}/scan", "sensor_msgs/msg/LaserScan", domain_id=domain, router_ip=host,
                                  router_port=int(port))
        self.goal = ROS2Publisher(f"{ns}/goal_pose", "geometry_msgs/msg/PoseStamped", domain_id=domain,
                                  router_ip=host, router_port=int(port))
        self.cmd = ROS2Subscriber(f"{ns}/cmd_vel", "geometry_msgs/msg/Twist", self.on_twist, domain_id=domain,
                                  router_ip=host, router_port=int(port))

    def on_twist(self, msg) -> None:
        with lock:
            self.v, self.w = float(msg.linear.x), float(msg.angular.z)
            self.twists += 1
        say("TWIST", self.id, f"{time.monotonic():.6f}", f"{msg.linear.x:.6f}", f"{msg.angular.z:.6f}")


robots = {rid: Robot(rid, pose) for rid, pose in config["robots"].items()}
lock = threading.Lock()


def clearance(x: float, y: float, me: str) -> tuple[float, float]:
    """(surface distance to the disc, to anything) of a robot centred at (x, y)."""
    disc = math.hypot(x - DISC[0], y - DISC[1]) - DISC[2] - RADIUS
    walls = min(x - BOUNDS[0], BOUNDS[2] - x, y - BOUNDS[1], BOUNDS[3] - y) - RADIUS
    others = [math.hypot(x - o.x, y - o.y) - 2 * RADIUS for o in robots.values() if o.id != me]
    return disc, min([disc, walls] + others)


def slide(x: float, y: float, me: str) -> tuple[float, float]:
    """A robot that would enter something is pushed back to its surface (it slides along it,
    as a rigid body does), and kept inside the walls."""
    for cx, cy, r in [(DISC[0], DISC[1], DISC[2])] + [(o.x, o.y, RADIUS) for o in robots.values() if o.id != me]:
        d = math.hypot(x - cx, y - cy)
        if 0 < d < r + RADIUS:
            x, y = cx + (x - cx) * (r + RADIUS) / d, cy + (y - cy) * (r + RADIUS) / d
    return (min(max(x, BOUNDS[0] + RADIUS), BOUNDS[2] - RADIUS), min(max(y, BOUNDS[1] + RADIUS), BOUNDS[3] - RADIUS))


def ray(x: float, y: float, a: float, me: str) -> float:
    """Distance from (x, y) along direction a to the walls, the disc or another robot."""
    c, s = math.cos(a), math.sin(a)
    best = math.inf
    for (bound, d) in ((BOUNDS[0], c), (BOUNDS[2], c)):
        if abs(d) > 1e-12 and (t := (bound - x) / d) > 0:
            best = min(best, t)
    for (bound, d) in ((BOUNDS[1], s), (BOUNDS[3], s)):
        if abs(d) > 1e-12 and (t := (bound - y) / d) > 0:
            best = min(best, t)
    circles = [(DISC[0], DISC[1], DISC[2])] + [(o.x, o.y, RADIUS) for o in robots.values() if o.id != me]
    for cx, cy, r in circles:
        fx, fy = x - cx, y - cy
        b = fx * c + fy * s
        disc = b * b - (fx * fx + fy * fy - r * r)
        if disc >= 0 and (t := -b - math.sqrt(disc)) > 0:
            best = min(best, t)
    return best


def publish(r: Robot, now: float) -> None:
    with lock:
        x, y, th, v, w = r.x, r.y, r.th, r.v, r.w
    pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                       orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(th / 2),
                                                                                     w=math.cos(th / 2)))
    twist = T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=v, y=0.0, z=0.0),
                                         angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=w))
    r.odom.publish(header=header(now, "odom"), child_frame_id="base_link",
                   pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                   twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)))
    inc = 2 * math.pi / BEAMS
    ranges = np.array([ray(x, y, th - math.pi + i * inc, r.id) for i in range(BEAMS)], dtype=np.float32)
    r.scan.publish(header=header(now, "base_scan"), angle_min=-math.pi, angle_max=-math.pi + inc * (BEAMS - 1),
                   angle_increment=inc, time_increment=0.0, scan_time=1.0 / RATE, range_min=0.005, range_max=5.0,
                   ranges=ranges, intensities=np.zeros(0, dtype=np.float32))


def raw(pub, data: bytes) -> None:
    """Put ``data`` on a publisher's key with its attachment (bytes that need not be its type),
    with congestion control BLOCK: every one arrives (the SDK's publisher may drop under load)."""
    att = struct.pack("<qqB", pub.sequence_number, time.time_ns(), 16) + pub.publisher_gid
    pub.sequence_number += 1
    session.session.put(pub.keyexpr, data, attachment=att, congestion_control=zenoh.CongestionControl.BLOCK)


def bad(r: Robot) -> None:
    """A burst of bad input: NaN poses, unknown frames, stale stamps, scans of the wrong
    length, and 10,000 payloads that are not CDR of the type."""
    now = time.time() - OFFSET
    counts = {"nan_odom": 5, "unknown_frame_odom": 5, "stale_scan": 5, "wrong_length_scan": 5, "garbage_scan": 10_000}
    nan = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=float("nan"), y=0.0, z=0.0),
                                      orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    zero = T["geometry_msgs/msg/Twist"](linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                                        angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0))
    for _ in range(5):
        r.odom.publish(header=header(now, "odom"), child_frame_id="base_link",
                       pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=nan, covariance=np.zeros(36)),
                       twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=zero, covariance=np.zeros(36)))
        r.odom.publish(header=header(now, "world"), child_frame_id="base_link",
                       pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=nan, covariance=np.zeros(36)),
                       twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=zero, covariance=np.zeros(36)))
        for t, n in ((now - 30.0, BEAMS), (now, BEAMS // 2)):  # stale; wrong length
            inc = 2 * math.pi / BEAMS
            r.scan.publish(header=header(t, "base_scan"), angle_min=-math.pi, angle_max=-math.pi + inc * (BEAMS - 1),
                           angle_increment=inc, time_increment=0.0, scan_time=0.1, range_min=0.005, range_max=5.0,
                           ranges=np.ones(n, dtype=np.float32), intensities=np.zeros(0, dtype=np.float32))
    rng = np.random.default_rng(7)
    for i in range(10_000):
        raw(
            r.scan,
            rng.bytes(int(rng.integers(0, 200)))
            if i % 2
            else b"\x00\x01\x00\x00" + rng.bytes(int(rng.integers(0, 60))),
        )
    say("BAD", json.dumps(counts))


AXLE, NOISE = config.get("axle", 0.053), config.get("wheel_noise", 0.0)
SLIP_EVERY = 0.032
"""Each wheel's speed is off by a factor 1 + U(-NOISE, NOISE), drawn every 32 ms (wheel slip)."""


def physics() -> None:
    nxt = time.monotonic()
    slip_rng, slip, slip_at = np.random.default_rng(config.get("seed", 1)), {}, -1.0
    while not done.is_set():
        nxt += STEP
        if nxt - slip_at >= SLIP_EVERY:
            slip_at = nxt
            slip = {r: 1.0 + slip_rng.uniform(-NOISE, NOISE, 2) for r in robots}
        with lock:
            for r in robots.values():
                v_l, v_r = (r.v - r.w * AXLE / 2) * slip[r.id][0], (r.v + r.w * AXLE / 2) * slip[r.id][1]
                v, w = (v_l + v_r) / 2, (v_r - v_l) / AXLE
                nx = r.x + v * math.cos(r.th) * STEP
                ny = r.y + v * math.sin(r.th) * STEP
                r.th = math.atan2(math.sin(r.th + w * STEP), math.cos(r.th + w * STEP))
                disc, any_ = clearance(nx, ny, r.id)
                touching = bool(any_ < 0)
                r.contacts += touching and not r.touching  # a new contact
                r.touching = touching
                r.x, r.y = slide(nx, ny, r.id) if touching else (nx, ny)
                r.min_disc, r.min_any = min(r.min_disc, disc), min(r.min_any, any_)
        time.sleep(max(0.0, nxt - time.monotonic()))


TARGETS = [list(map(float, t)) for t in config.get("targets", [])]  # [x, y, vx, vy]: points moving straight
TARGET_PUB = None if not TARGETS else ROS2Publisher("/targets", "geometry_msgs/msg/PoseArray", domain_id=domain,
                                                    router_ip=host, router_port=int(port))


def publish_targets(now: float, dt: float) -> None:
    """The targets move on (turning back at the walls) and go out as one PoseArray in ``odom``."""
    for t in TARGETS:
        for i in (0, 1):
            t[i] += t[i + 2] * dt
            if not BOUNDS[i] < t[i] < BOUNDS[i + 2]:
                t[i + 2] = -t[i + 2]
    TARGET_PUB.publish(header=header(now, "odom"), poses=[T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)) for x, y, _, _ in TARGETS])


def sensors() -> None:
    nxt = time.monotonic()
    while not done.is_set():
        nxt += 1.0 / RATE
        now = time.time() - OFFSET
        for r in robots.values():
            publish(r, now)
        if TARGETS:
            publish_targets(now, 1.0 / RATE)
        time.sleep(max(0.0, nxt - time.monotonic()))


def clock() -> None:
    """``/clock`` at 100 Hz, as Gazebo or Webots publish their simulation time."""
    pub = ROS2Publisher("/clock", "rosgraph_msgs/msg/Clock", domain_id=domain, router_ip=host, router_port=int(port))
    while not done.wait(0.01):
        pub.publish(clock=stamp(time.time() - OFFSET))
    pub.close()


done = threading.Event()
threads = [threading.Thread(target=f, daemon=True) for f in (physics, sensors)]
if config.get("publish_clock"):
    threads.append(threading.Thread(target=clock, daemon=True))
for th_ in threads:
    th_.start()
say("READY")
for line in sys.stdin:
    cmd, *args = line.split()
    if cmd == "quit":
        break
    if cmd == "bad":
        bad(robots[args[0]])
    if cmd == "goal":  # goal r1 x y: a goal pose as Nav2 sends it
        robots[args[0]].goal.publish(header=header(time.time() - OFFSET, "map"), pose=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(args[1]), y=float(args[2]), z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
        say("GOAL", args[0])
done.set()
for th_ in threads:
    th_.join(timeout=5)
say("DONE", json.dumps({r.id: {"x": r.x, "y": r.y, "theta": r.th, "min_disc_clearance": r.min_disc,
                               "min_clearance": r.min_any, "contacts": r.contacts, "twists": r.twists}
                        for r in robots.values()}))
for r in robots.values():
    r.odom.close()
    r.scan.close()
    r.goal.close()
    r.cmd.close()
session.close()
