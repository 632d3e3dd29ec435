"""Access control for a ROS 2 plant run (docs/ros2.md, "Driving a ROS 2 robot"): a Zenoh
router with the rules the docs list, where only the plant's identity may publish a
``cmd_vel``. A ROS 2 participant of robot r2 (allowed to publish r2's odometry and scan)
that publishes Twists on ``/r1/cmd_vel`` is refused by the router: r1 gets the plant's
Twists and none of its."""

from __future__ import annotations

import threading
import time

import pytest
import zenoh
from ros2_helpers import acl_router

from cekm_swarm.ros2.interfaces import interfaces
from cekm_swarm.ros2.plant import ODOMETRY, TWIST, twist_cdr
from cekm_swarm.ros2.wire import topic_key
from cekm_swarm.runtime.bridge import wait_matching
from cekm_swarm.runtime.config import client_config, free_port

pytestmark = pytest.mark.slow  # starts a router and sessions on loopback

IFC = interfaces()
USERS = ("plant", "robot-r1", "robot-r2")
ROS = ["0/**", "@ros2_lv/**"]


def robot_rules(r: str) -> list[tuple[str, str, list[str], list[str]]]:
    """A robot's ROS 2 participant: it publishes its own sensors and takes its own cmd_vel."""
    return [(f"{r}-sensors", "ingress", ["put"], [f"0/{r}/odom/**", f"0/{r}/scan/**", f"0/{r}/range_$*/**",
                                                   f"0/{r}/goal_pose/**", "0/clock/**"]),
            (f"{r}-listen", "ingress", ["declare_subscriber"], [f"0/{r}/cmd_vel/**"]),
            (f"{r}-commands-in", "egress", ["put"], [f"0/{r}/cmd_vel/**"])]


RULES = [
    ("declarations-out", "egress", ["declare_subscriber", "declare_queryable", "declare_liveliness_subscriber",
                                    "liveliness_token"], ROS),
    ("ros-graph", "ingress", ["liveliness_token", "declare_liveliness_subscriber", "liveliness_query"],
     ["@ros2_lv/**"]),
    ("plant-commands", "ingress", ["put"], ["0/*/cmd_vel/**"]),
    ("plant-listen", "ingress", ["declare_subscriber"], ["0/**"]),
    ("plant-sensors-in", "egress", ["put"], ["0/*/odom/**", "0/*/scan/**", "0/*/range_$*/**", "0/*/goal_pose/**",
                                              "0/clock/**"]),
    *robot_rules("r1"), *robot_rules("r2"),
]
POLICIES = {"plant": ["declarations-out", "ros-graph", "plant-commands", "plant-listen", "plant-sensors-in"],
            **{f"robot-{r}": ["declarations-out", "ros-graph", f"{r}-sensors", f"{r}-listen", f"{r}-commands-in"]
               for r in ("r1", "r2")}}


def test_only_the_plant_may_publish_a_robots_cmd_vel(tmp_path):
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    router = acl_router(tmp_path, port, RULES, POLICIES)
    s = {u: zenoh.open(client_config(ep, user=u, password=f"pw-{u}")) for u in USERS}
    try:
        cmd_vel = topic_key(0, "/r1/cmd_vel", TWIST, IFC.hash(TWIST))
        got: list[float] = []
        seen = threading.Condition()

        def on_twist(sample: zenoh.Sample) -> None:
            with seen:
                got.append(IFC.from_cdr(sample.payload.to_bytes(), TWIST).linear.x)
                seen.notify_all()

        sub = s["robot-r1"].declare_subscriber(cmd_vel, on_twist)
        plant = s["plant"].declare_publisher(cmd_vel)
        intruder = s["robot-r2"].declare_publisher(cmd_vel)
        # the robot's own odometry reaches the plant; r2 cannot publish r1's odometry either
        odom = topic_key(0, "/r1/odom", ODOMETRY, IFC.hash(ODOMETRY))
        odoms: list[str] = []
        s["plant"].declare_subscriber(odom, lambda sample: odoms.append(str(sample.key_expr)))
        assert wait_matching(plant, 30) and wait_matching(intruder, 30)  # both know r1 listens
        payload = IFC.cdr(IFC.make(ODOMETRY), ODOMETRY)
        speeds = [0.01 * i for i in range(1, 6)]
        sent = 0
        for v in speeds:  # each of the plant's Twists until it reached r1 (the last one a sentinel)
            for _ in range(6):
                intruder.put(twist_cdr(IFC, 0.15, 0.0))  # a valid Twist the router refuses to take
                s["robot-r2"].put(odom, payload)
            deadline = time.monotonic() + 30
            with seen:
                while v not in got:
                    assert time.monotonic() < deadline, f"no Twist of {v} m/s reached r1"
                    plant.put(twist_cdr(IFC, v, 0.0))
                    sent += 1
                    seen.wait(timeout=0.5)
        s["robot-r1"].put(odom, payload)
        deadline = time.monotonic() + 30
        while not odoms:
            assert time.monotonic() < deadline, "r1's own odometry did not reach the plant"
            time.sleep(0.05)
        sub.undeclare()
    finally:
        for x in s.values():
            x.close()
        router.close()
    assert 0.15 not in got and len(got) == sent and sorted(set(got)) == speeds  # none of r2's 30 Twists
    assert len(odoms) == 1  # r1's own, none of the 30 r2 published on r1's topic
