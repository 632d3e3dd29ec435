"""Two launchers as on two hosts (here both on loopback): one runs the world server only,
the other joins it and runs the robot's module processes only, fetching the model from the
world host's launcher. The run is the same as in one process, bit for bit, both on the
embedded router and through deploy/router.json5's access control with each host logged in
under its own identity (deploy/world.json5, deploy/robot-r1.json5)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.navigation_run import run_scenario
from cekm_swarm.runtime.config import free_port, load_config, open_session
from helpers.launch import LaunchProcess
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SEED = 2


DEPLOY = Path(__file__).resolve().parents[2] / "deploy"


@pytest.fixture
def acl_router(tmp_path):
    """deploy/router.json5 (access control, user/password) on a free loopback port."""
    creds = tmp_path / "credentials.txt"
    shutil.copy(DEPLOY / "credentials.example.txt", creds)
    port = free_port()
    router = open_session(
        load_config(
            DEPLOY / "router.json5",
            {"listen/endpoints": [f"tcp/127.0.0.1:{port}"], "transport/auth/usrpwd/dictionary_file": str(creds)},
        ),
        "ACL router",
    )
    yield f"tcp/127.0.0.1:{port}"
    router.close()


def split_run(tmp_path, world_args: tuple[str, ...], robot_args: tuple[str, ...], connect: str | None) -> dict:
    """World host and robot host; returns the world host's outcome after checking both ended well."""
    common = ("--mode", "lockstep", "--seed", str(SEED), "--max-time", "40")
    world = LaunchProcess("lone_obstacle", tmp_path / "world-host", "--robots", "none", "--no-plot",
                          "--model", str(default_model_path()), *common, *world_args)
    robots = None
    try:
        endpoint = connect or f"tcp/127.0.0.1:{world.port}"
        world.wait_line("serving the model", timeout=60)
        robots = LaunchProcess("lone_obstacle", tmp_path / "robot-host", "--robots", "r1", "--no-world",
                               "--connect", endpoint, "--model-from-zenoh", *common, *robot_args)
        robots.wait_line("waiting for the world server", timeout=90)
        assert world.finish(timeout=120) == 0, "\n".join(world.lines)
        assert robots.finish(timeout=60) == 0, "\n".join(robots.lines)
    finally:
        world.kill()
        if robots is not None:
            robots.kill()
    assert any("the world server has ended" in line for line in robots.lines)
    # the world said it ended (its 'ended' token): no wait for a router that went with it
    assert not any("lost the Zenoh router" in line for line in robots.lines), "\n".join(robots.lines)
    # the robot host took the run id from the world server's token: one run on both hosts
    run_ids = [[line.rsplit("run id ", 1)[1] for line in host.lines if "] run id " in line] for host in (world, robots)]
    assert run_ids[0] == run_ids[1] and len(run_ids[0]) == 1
    assert not (tmp_path / "robot-host" / "outcome.json").exists()
    outcome = world.outcome()
    assert outcome["launcher"]["modules"] == 0  # no module process on the world host
    model = default_model(progress=False)
    ref = run_scenario(load_scenario("lone_obstacle"), "cekm", model, SEED, max_time=40)
    traj = json.loads((world.out / "trajectory.json").read_text())["r1"]
    assert outcome["robots"]["r1"]["reached"]
    assert traj["x"] == ref.logs["r1"].x and traj["v_l"] == ref.logs["r1"].v_l
    return outcome


def test_world_host_and_robot_host(tmp_path):
    default_model(progress=False)
    split_run(tmp_path, (), (), None)


def test_split_launch_through_access_control_with_credentials(tmp_path, acl_router):
    default_model(progress=False)
    outcome = split_run(tmp_path, ("--connect", acl_router, "--config", str(DEPLOY / "world.json5")),
                        ("--config", str(DEPLOY / "robot-r1.json5")), acl_router)
    assert outcome["dropped_messages"] == 0


def test_a_wrong_password_stops_the_launch_with_a_clear_error(tmp_path, acl_router):
    bad = tmp_path / "bad.json5"
    bad.write_text((DEPLOY / "robot-r1.json5").read_text().replace("change-me-r1", "wrong"))
    p = LaunchProcess("lone_obstacle", tmp_path / "out", "--robots", "r1", "--no-world", "--connect", acl_router,
                      "--config", str(bad), "--model", str(default_model_path()))
    code = p.finish(timeout=60)
    assert code == 1
    failed = [line for line in p.lines if line.startswith("cekm: failed: ")]
    assert len(failed) == 1 and "cannot open client session" in failed[0], "\n".join(p.lines[-20:])
    assert f"authentication failed for user 'r1' at {acl_router}" in failed[0]
    assert not any("Traceback" in line for line in p.lines)
