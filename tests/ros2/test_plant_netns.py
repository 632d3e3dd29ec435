"""Two ROS 2 robots, each on its own host, driven by command fusion through the ROS 2 plant:
three Linux network namespaces (as tests/runtime/test_multihost_netns.py builds them). The
world host runs ``cekm launch --plant ros2 --robots none`` (the plant, hosting the router on
0.0.0.0); each robot's host runs its robot's nodes (``--no-world --robots rN``) and its
simulated body (``diffdrive_sim.py``), joining the router by its address on the link. r1's
simulator publishes ``/clock`` (ROS time 1000 s behind the wall clock) and both stamp their
messages with it: the plant must take its time from ``/clock``, or every message is stale.

Needs root and iproute2; skipped with the reason otherwise."""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import pytest

from cekm_swarm.runtime.netns import Hosts, namespaces_unavailable
from helpers.netns_hosts import ROBOTS, WORLD_ADDR

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SIM = Path(__file__).with_name("diffdrive_sim.py")
REPO = Path(__file__).resolve().parents[2]
PORT = 7447
OFFSET = 1000.0
STARTS = {"r1": [0.5, 0.6, 0.0], "r2": [1.5, 1.4, math.pi]}
GOALS = {"r1": (1.5, 0.6), "r2": (0.5, 1.4)}
DISCS = {"r1": [1.0, 0.6, 0.05], "r2": [1.0, 1.4, 0.05]}
SCENARIO = """\
name = "two_ros2_hosts"
description = "two robots, each on its own host, each past a disc 0.1 m across to a goal 1 m away"

[arena]
bounds = [0.0, 0.0, 2.0, 2.0]
""" + "".join(f"""
[[robots]]
id = "{r}"
start = {STARTS[r]}
goal = "g{r}"

[[targets]]
id = "g{r}"
position = {list(GOALS[r])}

[[obstacles]]
id = "d{r}"
shape = "disc"
center = {DISCS[r][:2]}
radius = {DISCS[r][2]}
""" for r in ROBOTS)


@pytest.fixture
def hosts():
    reason = namespaces_unavailable()
    if reason:
        pytest.skip(reason)
    h = Hosts(ROBOTS)
    try:
        yield h
    finally:
        h.remove()


def test_command_fusion_drives_two_ros2_robots_each_on_its_own_host_to_their_goals(hosts, msg_dir, tmp_path):
    assert ROBOTS == ("r1", "r2")
    scenario = tmp_path / "two_hosts.toml"
    scenario.write_text(SCENARIO)
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    cekm = [sys.executable, "-m", "cekm_swarm", "launch", str(scenario), "--plant", "ros2", "--controller", "fusion",
            "--no-plot", "--max-time", "60"]
    world = hosts.start("world", [*cekm, "--robots", "none", "--listen", "0.0.0.0", "--port", str(PORT),
                                  "--out", str(tmp_path / "world")], env, REPO)
    world.wait_line("hosts the embedded Zenoh router", timeout=120)
    nodes, sims = {}, {}
    for r in ROBOTS:
        ep = f"tcp/{WORLD_ADDR[r]}:{PORT}"
        nodes[r] = hosts.start(r, [*cekm, "--no-world", "--robots", r, "--connect", ep, "--out", str(tmp_path / r)],
                               env, REPO)
        config = {"robots": {r: STARTS[r]}, "bounds": [0.0, 0.0, 2.0, 2.0], "disc": DISCS[r], "rate_hz": 15,
                  "body_radius": 0.03, "beams": 360, "clock_offset": OFFSET, "publish_clock": r == "r1",
                  "wheel_noise": 0.1, "seed": int(r[1:])}
        sims[r] = hosts.start(r, [sys.executable, str(SIM), ep.removeprefix("tcp/"), str(msg_dir), "0",
                                  json.dumps(config)], env, REPO, stdin=True)
    for r in ROBOTS:
        sims[r].wait_line("READY", timeout=120)
    assert world.finish(timeout=240) == 0, "\n".join(world.lines[-40:])
    for r in ROBOTS:
        assert nodes[r].finish(timeout=60) == 0, "\n".join(nodes[r].lines[-20:])
        sims[r].proc.stdin.write("quit\n")
        sims[r].proc.stdin.flush()
    done = {r: json.loads(sims[r].wait_line("DONE", timeout=30).split(" ", 1)[1])[r] for r in ROBOTS}
    outcome = json.loads((tmp_path / "world" / "outcome.json").read_text())
    assert outcome["time_source"] == "ros /clock"
    for r in ROBOTS:
        assert outcome["robots"][r]["reached"], outcome["robots"]
        assert math.dist((done[r]["x"], done[r]["y"]), GOALS[r]) <= 0.04
        # fusion's avoider sees only ahead: it may graze the disc (as in the simulated world: 5 of 7
        # seeds of lone_obstacle), but it gets past it
        assert done[r]["contacts"] <= 2 and done[r]["min_clearance"] > -0.002
        logs = {p.name.split("-")[0] for p in (tmp_path / r / "logs").glob("*-*.log")}
        assert logs == {r}, logs  # each robot host ran its own robot's nodes only
    # (messages that came before the first /clock were judged on the wall clock: stale, and dropped)
    dropped = outcome["ros_dropped"]
    assert all(set(by) == {"stale stamp"} for by in dropped.values()), dropped
    assert outcome["launcher"]["modules"] == 0
    print(f"two hosts, fusion: contacts {[done[r]['contacts'] for r in ROBOTS]}; sense-to-command "
          f"{outcome['sense_to_command_ms']}, scan-to-Twist {outcome['scan_to_twist_ms']}")
