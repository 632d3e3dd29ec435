"""``cekm launch --plant ros2`` against robots the project does not simulate: the
differential-drive simulator of ``diffdrive_sim.py`` (written on ``zenoh-ros2-sdk``, no
``world/``), publishing Odometry and a LaserScan of walls and one disc at 15 Hz and
integrating the Twists it gets. Every wait is on a line or a condition, with a generous bound."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SIM = Path(__file__).with_name("diffdrive_sim.py")
TO_GOAL = re.compile(r"r1 \([^)]*\) (\d+\.\d+) m to goal")  # the launch's progress line for r1
BODY = 0.03  # the Khepera's radius: the model's body (tests/ros2/test_plant.py checks a different one is refused)
LONE = {"robots": {"r1": [0.5, 1.0, 0.0]}, "bounds": [0.0, 0.0, 2.0, 2.0], "disc": [1.0, 1.0, 0.05], "rate_hz": 15,
        "body_radius": BODY, "beams": 360}


def sim_argv(endpoint: str, msg_dir: Path, config: dict) -> list[str]:
    return [sys.executable, str(SIM), endpoint.removeprefix("tcp/"), str(msg_dir), "0", json.dumps(config)]


def launch_argv(*args: str) -> list[str]:
    return [sys.executable, "-m", "cekm_swarm", "launch", *args, "--plant", "ros2", "--no-plot"]


def twists(lines: list[str], robot: str = "r1") -> list[tuple[float, float, float]]:
    """The (monotonic s, v, omega) of every Twist the simulator took for ``robot``."""
    return [(float(p[2]), float(p[3]), float(p[4])) for p in (x.split() for x in lines)
            if p[0] == "TWIST" and p[1] == robot]


def test_cekm_drives_a_ros2_robot_past_the_disc_through_bad_input_and_a_killed_motor_node(processes, msg_dir,
                                                                                           tmp_path):
    from cekm_swarm.runtime.config import free_port

    port, out = free_port(), tmp_path / "run"
    ep = f"tcp/127.0.0.1:{port}"
    launch = processes(launch_argv("lone_obstacle", "--port", str(port), "--out", str(out), "--max-time", "60"))
    launch.expect("", timeout=180, where=lambda s: "hosts the embedded Zenoh router" in s)
    sim = processes(sim_argv(ep, msg_dir, LONE))
    sim.expect("READY", timeout=60)
    launch.expect("", timeout=120, where=lambda s: "world started ticking" in s)
    sim.send("goal r1 1.7 1.0")  # Nav2's goal_pose: the goal moves 0.2 m further, behind the disc still
    sim.expect("GOAL", timeout=30)
    launch.expect("", timeout=30, where=lambda s: "goal: r1's goal is now (1.70, 1.00)" in s)
    sim.send("bad r1")  # NaN poses, an unknown frame, stale stamps, a short scan, 10,000 malformed payloads
    bad = json.loads(sim.expect("BAD", timeout=120).split(" ", 1)[1])
    # past the disc (its centre is 0.7 m from the goal; under 0.6 m to go the robot is clear of it): the
    # dead-man's coasting on the last Twist then tests the stop, not the avoidance
    launch.expect("", timeout=90, where=lambda s: (m := TO_GOAL.search(s)) is not None and float(m[1]) < 0.6)
    # SIGKILL the motor node, and its restart at once: the supervisor's back-off doubles (0.5 s), so
    # the commands stop for longer than the dead-man limit whatever the machine's speed
    motor = json.loads((out / "pids.json").read_text())["r1/motor"]
    killed = time.monotonic()  # (read before the signal: what the kill causes can reach the simulator first)
    os.kill(motor, signal.SIGKILL)
    restarted = launch.expect("", timeout=60, where=lambda s: "module r1/motor restarted" in s)
    os.kill(int(restarted.split("pid ")[1].rstrip(")")), signal.SIGKILL)
    launch.expect("", timeout=30, where=lambda s: ": deadman" in s)
    assert launch.proc.wait(timeout=180) == 0, "\n".join(launch.seen[-30:])
    sim.send("quit")
    done = json.loads(sim.expect("DONE", timeout=30).split(" ", 1)[1])["r1"]
    outcome = json.loads((out / "outcome.json").read_text())
    r1 = outcome["robots"]["r1"]
    # past the disc to its goal, never touching the disc or anything else
    assert r1["reached"] and r1["goal"] == [1.7, 1.0] and math.hypot(done["x"] - 1.7, done["y"] - 1.0) <= 0.04
    assert done["contacts"] == 0 and done["min_disc_clearance"] > 0.0 and done["min_clearance"] > 0.0, done
    # every bad message dropped and counted by topic and reason; the run went on
    dropped = outcome["ros_dropped"]
    assert dropped["/r1/odom"] == {"not finite": bad["nan_odom"], "unknown frame": bad["unknown_frame_odom"]}
    scan = dropped["/r1/scan"]
    assert scan["stale stamp"] == bad["stale_scan"] and scan["scan of the wrong length"] == bad["wrong_length_scan"]
    assert sum(scan.values()) == bad["stale_scan"] + bad["wrong_length_scan"] + bad["garbage_scan"]
    assert scan["malformed CDR"] >= bad["garbage_scan"] - 10  # (random bytes that happen to parse: another reason)
    # the dead-man: a zero Twist within the limit of the last command, then the restarted motor drove on
    deadman = [e for e in outcome["events"] if e["event"] == "deadman"]  # (one per kill when a restart is slow)
    assert 1 <= len(deadman) <= 2 and all(e["robot"] == "r1" and e["silent_s"] <= e["limit_s"] == 0.5 for e in deadman)
    seen = twists(sim.seen)
    after = [tw for tw in seen if tw[0] > killed]
    first_zero = next(i for i, tw in enumerate(after) if tw[1] == 0.0 and tw[2] == 0.0)
    assert any(v != 0.0 for _, v, _ in after[first_zero:]), "the robot never moved again after the dead-man"
    assert outcome["launcher"]["restarts"] == {"r1/motor": 2}
    # the end: a zero Twist last; the log holds what the plant took and sent
    assert seen[-1][1:] == (0.0, 0.0)
    from mcap.reader import make_reader

    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic: summary.statistics.channel_message_counts.get(c.id, 0) for c in summary.channels.values()}
    assert topics["ros2/r1/cmd_vel"] == r1["twists"] and topics["ros2/r1/scan"] > 50 and topics["cekm/world/state"] > 50
    assert topics["cekm/r1/cmd/wheels"] > 50 and topics["cekm/r1/sense/range/0"] > 50


TRACKING = {"robots": {"r1": [1.42, 1.0, math.pi / 2], "r2": [1.58, 1.0, math.pi / 2]}, "bounds": [0.0, 0.0, 3.0, 2.0],
            "disc": [2.8, 1.8, 0.05], "rate_hz": 15, "body_radius": BODY, "beams": 360,
            "targets": [[1.3, 1.2, -0.0188, 0.0067], [1.3, 0.8, -0.0188, -0.0067], [1.7, 1.0, 0.02, 0.0]]}
"""The ``tracking`` scenario's start: its three targets on /targets, two drifting west, one east."""


def test_tracking_targets_from_ros2_then_ctrl_c_stops_the_robots_with_a_zero_twist(processes, msg_dir, tmp_path):
    """The cekm tracking graph, its targets from ``/targets``: the robots part (one west, one
    east, as the targets do); Ctrl-C then leaves each robot stopped."""
    from cekm_swarm.runtime.config import free_port

    port, out = free_port(), tmp_path / "run"
    launch = processes(launch_argv("tracking", "--port", str(port), "--out", str(out)))
    launch.expect("", timeout=180, where=lambda s: "hosts the embedded Zenoh router" in s)
    sim = processes(sim_argv(f"tcp/127.0.0.1:{port}", msg_dir, TRACKING))
    sim.expect("READY", timeout=60)

    def apart(line: str) -> float:  # "t=  3.07 s  r1 (1.30, 1.00)  r2 (1.70, 1.00)": how far apart in x
        xs = [float(x.split(",")[0]) for x in line.split("(")[1:3]]
        return xs[1] - xs[0]

    launch.expect("", timeout=120, where=lambda s: " t=" in s and " r2 (" in s and apart(s) >= 0.4)  # from 0.16 m
    interrupted = time.monotonic()  # (before the signal: the launcher's zero Twist can reach the simulator
    launch.proc.send_signal(signal.SIGINT)  # before this process runs again, as a CI run here showed)
    assert launch.proc.wait(timeout=60) == 130, "\n".join(launch.seen[-20:])
    sim.send("quit")
    done = json.loads(sim.expect("DONE", timeout=30).split(" ", 1)[1])
    assert done["r1"]["x"] < 1.42 - 0.1 and done["r2"]["x"] > 1.58 + 0.1  # west and east, with the targets
    for r in ("r1", "r2"):
        seen = twists(sim.seen, r)
        assert seen[-1][1:] == (0.0, 0.0) and seen[-1][0] > interrupted  # the last Twist, after Ctrl-C, stops it
    outcome = json.loads((out / "outcome.json").read_text())
    assert outcome["aborted"] and outcome["ros_dropped"] == {} and outcome["ros_received"]["/targets"] > 10
