"""``cekm ros2 bridge`` on real Zenoh sessions over loopback, checked with an independent
implementation of ``rmw_zenoh``'s protocol (PyPI's ``zenoh-ros2-sdk``, tests/ros2/ros2_peer.py):
its subscriber receives the robots' odometry and the latched ``/tf_static``, its graph
discovery sees the bridge's node and topics, its Twists drive a robot in a real-time run,
and hostile Twists are dropped and counted while the run goes on. A lockstep run with the
bridge attached equals the run without it bit for bit. Access control keeps a refused
publisher's Twists out."""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh
from ros2_helpers import acl_router as shared_acl_router
from ros2_helpers import bridge_argv, cekm, peer_argv

from cekm_swarm.protocol import Clock, WheelCommand, decode, encode
from cekm_swarm.ros2.interfaces import JAZZY_TYPE_HASHES, interfaces
from cekm_swarm.ros2.wire import Attachment, gid, topic_key
from cekm_swarm.runtime.bridge import wait_matching
from cekm_swarm.runtime.config import (
    client_config,
    free_port,
    open_client,
    open_embedded_router,
)
from cekm_swarm.ticks import tick_time

pytestmark = pytest.mark.slow
IFC = interfaces()
ODOM_HASH = JAZZY_TYPE_HASHES["nav_msgs/msg/Odometry"]


def payload(line: str) -> dict:
    """The JSON of a peer's ``MSG TOPIC {json}`` or ``INFO {json}`` line."""
    return json.loads(line.split(" ", 2)[2] if line.startswith("MSG") else line.split(" ", 1)[1])


def stamp(msg: dict) -> float:
    return msg["header"]["stamp"]["sec"] + msg["header"]["stamp"]["nanosec"] * 1e-9


def odom_x(line: str) -> float:
    return payload(line)["pose"]["pose"]["position"]["x"]


def stop(process, sig=signal.SIGINT, expect: str = "{", timeout: float = 30) -> str:
    process.proc.send_signal(sig)
    return process.expect(expect, timeout)


def test_teleop_in_a_real_time_run_and_hostile_twists(processes, msg_dir, tmp_path):
    ep = f"tcp/127.0.0.1:{free_port()}"
    bridge = processes(bridge_argv(ep, "--teleop", "r1"))  # it waits for the router
    world = processes([sys.executable, "-m", "world.server", "crossing", "--listen", ep, "--mode", "realtime",
                       "--out", str(tmp_path / "run"), "--max-time", "300", "--match-timeout", "2"])
    world.expect("START", 60)
    peer = processes(peer_argv(ep, msg_dir))
    peer.expect("READY", 60)

    # the independent subscriber receives r1's odometry, on the key it computed itself
    peer.send("sub /r1/odom nav_msgs/msg/Odometry")
    assert peer.expect("SUB").split()[2] == f"0/r1/odom/nav_msgs::msg::dds_::Odometry_/{ODOM_HASH}"
    first = payload(peer.expect("MSG /r1/odom", 30))
    assert (first["header"]["frame_id"], first["child_frame_id"]) == ("map", "r1/base_link")
    x0, y0 = first["pose"]["pose"]["position"]["x"], first["pose"]["pose"]["position"]["y"]
    assert (x0, y0) == (0.3, 1.0)  # crossing's r1 starts there, standing (no module drives it)

    # its graph discovery (ros2 topic info -v) sees the bridge's publisher and its teleop subscription
    peer.send("info /r1/odom")
    (pub,) = payload(peer.expect("INFO"))["publishers"]
    assert (pub["node_name"], pub["topic_type"], pub["type_hash"], pub["qos"]) == (
        "cekm_bridge", "nav_msgs/msg/Odometry", ODOM_HASH, "::,10:,:,:,,")
    peer.send("info /r1/cmd_vel")
    assert [s["node_name"] for s in payload(peer.expect("INFO"))["subscribers"]] == ["cekm_bridge"]

    # a late subscriber with transient-local durability gets /tf_static from the bridge's cache
    peer.send("sub /tf_static tf2_msgs/msg/TFMessage latched")
    static = payload(peer.expect("MSG /tf_static", 30))
    assert len(static["transforms"]) == 36 and static["transforms"][0]["header"]["frame_id"] == "r1/base_link"

    # the scene: the bridge fetched the run's geometry from the world (the walls), and the robots
    peer.send("sub /world/markers visualization_msgs/msg/MarkerArray")
    peer.expect(
        "MSG /world/markers", 30, where=lambda line: {m["ns"] for m in payload(line)["markers"]} == {"walls", "discs"}
    )
    peer.expect("MSG /world/markers", 30, where=lambda line: "robots" in {m["ns"] for m in payload(line)["markers"]})

    # hostile Twists, from the same publisher as the good ones below (so they arrive first)
    peer.send("pub /r1/cmd_vel geometry_msgs/msg/Twist")
    peer.expect("PUB")
    hostile = {"not finite": ["nan 0 0 0 0 0", "0 0 0 0 0 inf", "-inf 0 0 0 0 0"],
               "out of range": ["1e300 0 0 0 0 0", "0.5 0 0 0 0 0", "0 0 0 0 0 100"]}
    for values in hostile["not finite"] + hostile["out of range"]:
        peer.send(f"twist /r1/cmd_vel {values}")
    string_cdr = IFC.cdr(IFC.make("std_msgs/msg/String", data="drive"), "std_msgs/msg/String").hex()
    wrong = [string_cdr, "00", "ff" * 52, "0001000000" + "00" * 50]  # another type, garbage, bad header, 55 bytes
    for raw in wrong:
        peer.send(f"raw /r1/cmd_vel {raw}")
    peer.send("raw /r1/cmd_vel")  # an empty payload
    hostile["not a CDR Twist"] = wrong + [""]

    # good Twists every 50 ms until the independent subscriber sees r1 0.05 m further
    done = threading.Event()
    sent = [0]

    def drive() -> None:
        while not done.is_set():
            peer.send("twist /r1/cmd_vel 0.1 0 0 0 0 0")
            sent[0] += 1
            done.wait(0.05)

    driver = threading.Thread(target=drive)
    driver.start()
    try:
        moved = peer.expect("MSG /r1/odom", 30, where=lambda line: odom_x(line) >= x0 + 0.05)
    finally:
        done.set()
        driver.join()
    assert payload(moved)["twist"]["twist"]["linear"]["x"] > 0.05  # executed speed, 0.1 m/s +- 10 % noise

    # the Twists stopped: the world's dead-man stops r1 (a dead-man stop after the drive, not the one
    # of the start, when nothing drove r1), and its odometry says so
    t_moved = stamp(payload(moved))

    def stopped_after_drive(line: str) -> bool:
        doc = json.loads(line.split(" ", 1)[1])
        return doc.get("event") == "deadman" and doc.get("robot") == "r1" and doc["t"] > t_moved

    event = json.loads(world.expect("EVENT", 10, where=stopped_after_drive).split(" ", 1)[1])
    assert event["limit_s"] == 0.5
    after = payload(peer.expect("MSG /r1/odom", 10, where=lambda line: stamp(payload(line)) > event["t"]
                                and payload(line)["twist"]["twist"]["linear"]["x"] == 0.0))
    later = payload(peer.expect("MSG /r1/odom", 10, where=lambda line: stamp(payload(line)) > stamp(after) + 0.25))
    assert later["pose"]["pose"] == after["pose"]["pose"] and later["twist"]["twist"]["linear"]["x"] == 0.0

    report = json.loads(stop(bridge))
    assert report["twists"] == sum(map(len, hostile.values())) + sent[0]
    assert report["twists_refused"] == {reason: len(v) for reason, v in hostile.items()}
    assert 1 <= report["wheel_commands"] <= sent[0] and report["errors"] == 0 and report["dropped"] == 0
    assert report["published"] > report["received"] / 2 and report["too_large"] == 0
    done_line = json.loads(stop(world, signal.SIGTERM, "DONE").split(" ", 1)[1])
    traj = json.loads((tmp_path / "run" / "trajectory.json").read_text())
    r1 = traj["r1"]
    assert set(zip(r1["v_l"], r1["v_r"], strict=True)) == {
        (0.0, 0.0),
        (0.1, 0.1),
    }  # nothing hostile ever reached the wheels
    assert max(r1["x"]) >= x0 + 0.05
    still = [i for i, t in enumerate(r1["t"][:len(r1["v_l"])]) if stamp(after) - 1e-6 <= t < stamp(later)]
    assert len(still) >= 2 and all(r1["v_l"][i] == r1["v_r"][i] == 0.0 for i in still)  # stopped for good
    assert all(set(traj[r]["v_l"] + traj[r]["v_r"]) == {0.0} for r in ("r2", "r3"))
    assert done_line["sim_seconds"] > event["t"]  # the run went on past the hostile Twists and the stop


def test_a_lockstep_run_with_the_bridge_attached_equals_the_run_without_it(processes, crossing_run, tmp_path):
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    router = open_embedded_router(port)
    watcher = open_client(ep)
    try:
        node_up = threading.Event()
        tokens: list[str] = []

        def on_token(sample: zenoh.Sample) -> None:
            tokens.append(str(sample.key_expr))
            if str(sample.key_expr).endswith("/NN/%/%/cekm_bridge"):
                node_up.set()

        lv = watcher.liveliness().declare_subscriber("@ros2_lv/0/**", on_token, history=True)
        odom: list[zenoh.Sample] = []
        got_all = threading.Event()
        ticks = json.loads((crossing_run / "outcome.json").read_text())["ticks"]

        def on_odom(sample: zenoh.Sample) -> None:
            odom.append(sample)
            if len(odom) == ticks + 1:
                got_all.set()

        sub = watcher.declare_subscriber(topic_key(0, "/r1/odom", "nav_msgs/msg/Odometry", ODOM_HASH), on_odom)
        bridge = processes(bridge_argv(ep))
        assert node_up.wait(60), "the bridge's node never appeared in the ROS graph"
        r = cekm("launch", "crossing", "--mode", "lockstep", "--connect", ep, "--out", str(tmp_path / "run"))
        assert r.returncode == 0, r.stderr[-3000:]
        assert got_all.wait(60), f"{len(odom)} of {ticks + 1} odometry messages"
        report = json.loads(stop(bridge))
        lv.undeclare()
        sub.undeclare()
    finally:
        watcher.close()
        router.close()
    for name in ("trajectory.json",):
        assert (tmp_path / "run" / name).read_bytes() == (crossing_run / name).read_bytes()
    with_bridge = json.loads((tmp_path / "run" / "outcome.json").read_text())
    without = json.loads((crossing_run / "outcome.json").read_text())
    assert with_bridge["robots"] == without["robots"] and with_bridge["ticks"] == without["ticks"]
    # the bridge took in the whole run: what the world recorded of it (its own and the nodes' messages)
    assert report["received"] >= with_bridge["recorded_messages"] > 2000
    assert report["dropped"] == 0 and report["errors"] == 0
    # every odometry message: CDR of the right type, the 33-byte attachment numbered from 1, the
    # GID that rmw_zenoh derives from the publisher's own liveliness token
    (token,) = {t for t in tokens if "/MP/" in t and "%r1%odom" in t}  # declared, then undeclared at the end
    attachments = [Attachment.decode(s.attachment.to_bytes()) for s in odom]
    assert [a.sequence for a in attachments] == list(range(1, ticks + 2))
    assert {a.gid for a in attachments} == {gid(token)}
    last = IFC.from_cdr(odom[-1].payload.to_bytes(), "nav_msgs/msg/Odometry")
    traj = json.loads((crossing_run / "trajectory.json").read_text())["r1"]
    assert (last.pose.pose.position.x, last.pose.pose.position.y) == (traj["x"][-1], traj["y"][-1])




def acl_router(tmp_path: Path, port: int) -> zenoh.Session:
    """A router with access control: what the bridge needs (docs/ros2.md lists it), a teleop
    identity allowed to publish /r1/cmd_vel, and an intruder allowed to publish nothing."""
    ros = ["0/**", "@ros2_lv/**"]
    rules = [
        ("declarations-out", "egress", ["declare_subscriber", "declare_queryable", "declare_liveliness_subscriber",
                                        "liveliness_token"], ["cekm/**"] + ros),
        ("run-receive", "egress", ["put", "delete"], ["cekm/**"]),
        ("clock-publish", "ingress", ["put"], ["cekm/world/clock"]),
        ("bridge-listen", "ingress", ["declare_subscriber"], ["cekm/**", "0/*/cmd_vel/**"]),
        ("bridge-command", "ingress", ["put"], ["cekm/r1/cmd/wheels"]),
        ("bridge-ros-publish", "ingress", ["put", "liveliness_token", "declare_queryable"], ros + ["0/**/@adv/**"]),
        ("bridge-cache-queries", "egress", ["query"], ["0/**/@adv/**"]),
        ("bridge-cache-replies", "ingress", ["reply"], ["0/**/@adv/**"]),
        ("bridge-geometry", "ingress", ["query"], ["cekm/world/geometry"]),
        ("bridge-geometry-reply", "egress", ["reply"], ["cekm/world/geometry"]),
        ("bridge-twists-in", "egress", ["put"], ["0/*/cmd_vel/**"]),
        ("teleop-publish", "ingress", ["put"], ["0/r1/cmd_vel/**"]),
        ("observer-listen", "ingress", ["declare_subscriber"], ["cekm/**"]),
    ]
    policies = {"world": ["declarations-out", "clock-publish"],
                "bridge": ["declarations-out", "run-receive", "bridge-listen", "bridge-command", "bridge-ros-publish",
                           "bridge-cache-queries", "bridge-cache-replies", "bridge-geometry", "bridge-geometry-reply",
                           "bridge-twists-in"],
                "teleop": ["declarations-out", "teleop-publish"],
                "intruder": ["declarations-out"],
                "observer": ["declarations-out", "run-receive", "observer-listen"]}
    return shared_acl_router(tmp_path, port, rules, policies)


def test_access_control_keeps_a_refused_publishers_twists_out(processes, tmp_path):
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    router = acl_router(tmp_path, port)
    sessions = {u: zenoh.open(client_config(ep, user=u, password=f"pw-{u}")) for u in ("world", "teleop", "intruder",
                                                                                        "observer")}
    (tmp_path / "bridge.json5").write_text(json.dumps({"mode": "client", "transport": {
        "auth": {"usrpwd": {"user": "bridge", "password": "pw-bridge"}}}}))
    ticking = threading.Event()
    try:
        commands: list[WheelCommand] = []
        seen = threading.Condition()

        def on_command(sample: zenoh.Sample) -> None:
            with seen:
                commands.append(decode("cekm/r1/cmd/wheels", sample.payload.to_bytes()))
                seen.notify_all()

        sub = sessions["observer"].declare_subscriber("cekm/r1/cmd/wheels", on_command)
        bridge = processes(bridge_argv(ep, "--config", str(tmp_path / "bridge.json5"), "--teleop", "r1"))

        def clock() -> None:  # the world's clock, which teleop stamps its commands with
            pub = sessions["world"].declare_publisher("cekm/world/clock")
            k = 0
            while not ticking.wait(0.128):
                pub.put(encode(Clock(tick_time(k), "world", k)))
                k += 1

        threading.Thread(target=clock, daemon=True).start()
        key = topic_key(0, "/r1/cmd_vel", "geometry_msgs/msg/Twist", JAZZY_TYPE_HASHES["geometry_msgs/msg/Twist"])

        def twist(v: float) -> bytes:
            vec = lambda x: IFC.make("geometry_msgs/msg/Vector3", x=x, y=0.0, z=0.0)  # noqa: E731
            return IFC.cdr(
                IFC.make("geometry_msgs/msg/Twist", linear=vec(v), angular=vec(0.0)), "geometry_msgs/msg/Twist"
            )

        intruder = sessions["intruder"].declare_publisher(key)
        teleop = sessions["teleop"].declare_publisher(key)
        assert wait_matching(intruder, 30) and wait_matching(teleop, 30)  # both know the bridge listens
        speeds = [0.01 * i for i in range(1, 7)]
        sent = 0
        for v in speeds:  # each good Twist until it came out as r1's wheel command (the last one a sentinel)
            for _ in range(5):
                intruder.put(twist(0.15))  # a valid Twist, which the router refuses to take
            deadline = time.monotonic() + 30
            with seen:
                while not any(c.v_l == v for c in commands):
                    assert time.monotonic() < deadline, f"no wheel command for {v} m/s"
                    teleop.put(twist(v))
                    sent += 1
                    seen.wait(timeout=0.5)
        report = json.loads(stop(bridge))
        sub.undeclare()
    finally:
        ticking.set()
        for s in sessions.values():
            s.close()
        router.close()
    assert {c.v_l for c in commands} == set(speeds) and all(c.v_l == c.v_r for c in commands)
    assert all(c.sender == "r1/ros2-teleop" and math.isclose(c.stamp / 0.128, round(c.stamp / 0.128)) for c in commands)
    # the bridge saw exactly the teleop identity's Twists (all of them: the sentinel came out last,
    # and one publisher's puts arrive in order), none of the intruder's 30
    assert report["twists"] == sent and report["wheel_commands"] == len(commands)
    assert set(report["twists_refused"]) <= {"no world clock yet"}


def test_a_scene_bigger_than_the_routers_limit_goes_out_in_parts():
    """Every router of the runtime drops a message over 32 KB: the bridge splits a big
    marker array so that every marker arrives."""
    from cekm_swarm.protocol import WorldState
    from cekm_swarm.ros2.bridge import Bridge
    from cekm_swarm.runtime.config import MAX_MESSAGE_BYTES

    port = free_port()
    router = open_embedded_router(port)
    s = open_client(f"tcp/127.0.0.1:{port}")
    try:
        parts: list[bytes] = []
        markers = [0]
        enough = threading.Event()
        walls = [{"vertices": [[0.01 * i, 0.0], [0.01 * i + 0.005, 0.0], [0.01 * i + 0.005, 1.0], [0.01 * i, 1.0]]}
                 for i in range(400)]

        def on_markers(sample: zenoh.Sample) -> None:
            data = sample.payload.to_bytes()
            parts.append(data)
            markers[0] += len(IFC.from_cdr(data, "visualization_msgs/msg/MarkerArray").markers)
            if markers[0] >= len(walls):
                enough.set()

        sub = s.declare_subscriber("0/world/markers/**", on_markers)
        bridge = Bridge(s)
        bridge.mapper.set_geometry({"walls": walls})
        state = WorldState(0.0, "world", {}, {}, {})
        bridge.handle_run_sample("cekm/world/state", encode(state), 0.0)
        assert enough.wait(10), f"{markers[0]} of {len(walls)} wall markers arrived"
        assert len(parts) > 1 and all(len(p) <= MAX_MESSAGE_BYTES - 33 for p in parts)
        assert sum(len(p) for p in parts) > MAX_MESSAGE_BYTES  # one message would have been dropped
        assert bridge.stats.too_large == 0
        sub.undeclare()
        bridge.close()
    finally:
        s.close()
        router.close()
