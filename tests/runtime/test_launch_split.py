"""Two launchers as on two hosts (here both on loopback): one runs the router and the world
server only, the other joins it and runs the robot's module processes only. The run is the
same as in one process, bit for bit."""

from __future__ import annotations

import json

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.navigation import run_scenario
from world import load_scenario

from test_launch_support import LaunchProcess

SEED = 2


def test_world_host_and_robot_host(tmp_path):
    model = default_model(progress=False)
    common = ("--mode", "lockstep", "--seed", str(SEED), "--max-time", "40", "--model", str(default_model_path()))
    world = LaunchProcess("lone_obstacle", tmp_path / "world-host", "--robots", "none", "--no-plot", *common)
    robots = None
    try:
        world.wait_line("embedded Zenoh router", timeout=60)
        robots = LaunchProcess("lone_obstacle", tmp_path / "robot-host", "--robots", "r1", "--no-world",
                               "--connect", f"tcp/127.0.0.1:{world.port}", *common)
        robots.wait_line("waiting for the world server", timeout=90)
        assert world.finish(timeout=120) == 0, "\n".join(world.lines)
        assert robots.finish(timeout=60) == 0, "\n".join(robots.lines)
    finally:
        world.kill()
        if robots is not None:
            robots.kill()
    assert any("the world server has ended" in line for line in robots.lines)
    assert not (tmp_path / "robot-host" / "outcome.json").exists()
    outcome = world.outcome()
    assert outcome["launcher"]["modules"] == 0  # no module process on the world host
    ref = run_scenario(load_scenario("lone_obstacle"), "cekm", model, SEED, max_time=40)
    traj = json.loads((world.out / "trajectory.json").read_text())["r1"]
    assert outcome["robots"]["r1"]["reached"]
    assert traj["x"] == ref.logs["r1"].x and traj["v_l"] == ref.logs["r1"].v_l
