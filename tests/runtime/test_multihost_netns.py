"""A run over three "hosts": Linux network namespaces, each with its own network stack,
joined by veth pairs. The world host runs the Zenoh router of deploy/tls/router.json5
(mutual TLS, access control) and deploy/launch-hosts.sh's world launcher; robot r1's and
robot r2's hosts each run launch-hosts.sh for their robot, joining the router by its
address on their link. Each host logs in with its own deploy/tls/ config and
certificate. Once the world ticks, r1's link is cut for 2 s (shorter than Zenoh's 10 s
lease: the TLS connection survives, TCP retransmits). The lockstep outcome still equals
the one-process run bit for bit.

Topology (addresses exist only inside these namespaces; nothing leaves the machine):

    r1 host 10.199.1.2 --veth-- 10.199.1.1 world host 10.199.2.1 --veth-- 10.199.2.2 r2 host

Needs root and iproute2; skipped with the reason otherwise. Every namespace (and so its
links) is removed afterwards, and any process still in one is killed, even on failure."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.experiments.navigation_run import run_scenario
from cekm_swarm.runtime.netns import Hosts, namespaces_unavailable
from helpers.netns_hosts import ROBOT_ADDR, ROBOTS, WORLD_ADDR
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
SEED = 2
MAX_TIME = 30.0
OUTAGE = 2.0

SCENARIO = """\
name = "two_hosts"
description = "two robots, each on its own host, each past a disc to a goal 0.8 m away"
seed = 5

[arena]
bounds = [0.0, 0.0, 2.0, 2.0]

[[robots]]
id = "r1"
start = [0.4, 0.6, 0.0]
goal = "g1"

[[robots]]
id = "r2"
start = [1.6, 1.4, 3.141592653589793]
goal = "g2"

[[targets]]
id = "g1"
position = [1.2, 0.6]

[[targets]]
id = "g2"
position = [0.8, 1.4]

[[obstacles]]
id = "d1"
shape = "disc"
center = [0.8, 0.62]
radius = 0.05

[[obstacles]]
id = "d2"
shape = "disc"
center = [1.2, 1.38]
radius = 0.05
"""


@pytest.fixture
def hosts():
    reason = namespaces_unavailable(need_openssl=True)
    if reason:
        pytest.skip(reason)
    h = Hosts(ROBOTS)
    assert h.world_addr == WORLD_ADDR and h.robot_addr == ROBOT_ADDR
    try:
        yield h
    finally:
        h.remove()
    assert not h.left_over()


ROUTER = ("import sys; from cekm_swarm.runtime.config import load_config, open_session; "
          "s = open_session(load_config(sys.argv[1]), 'TLS router'); print('router ready', flush=True); "
          "sys.stdin.read(); s.close()")


def test_world_host_and_two_robot_hosts_in_network_namespaces_over_mutual_tls(hosts, tmp_path):
    model = default_model(progress=False)
    run = tmp_path / "run"
    run.mkdir()
    certs = subprocess.run([str(DEPLOY / "make-certs.sh"), str(run / "certs"), *WORLD_ADDR.values()],
                           capture_output=True, text=True, timeout=60,
                           env=dict(os.environ, HOSTS="world r1 r2"))
    assert certs.returncode == 0, certs.stderr
    scenario = run / "two_hosts.toml"
    scenario.write_text(SCENARIO)
    bindir = str(Path(sys.executable).parent)  # where the cekm console script lives
    base = dict(os.environ, PYTHONUNBUFFERED="1", PATH=bindir + os.pathsep + os.environ.get("PATH", ""),
                SCENARIO=str(scenario), MODE="lockstep", LINK="tls")
    opts = ["--seed", str(SEED), "--max-time", str(MAX_TIME)]
    t0 = time.monotonic()
    # The router as shipped (tls/0.0.0.0:7447; certs/ relative to its working directory).
    router = hosts.start("world", [sys.executable, "-c", ROUTER, str(DEPLOY / "tls" / "router.json5")], base, run,
                         stdin=True)
    router.wait_line("router ready", timeout=60)
    world = hosts.start("world", [str(DEPLOY / "launch-hosts.sh"), "world", WORLD_ADDR["r1"], "--no-plot", *opts],
                        dict(base, OUT=str(run / "world-host"), ZENOH_CONFIG=str(DEPLOY / "tls" / "world.json5")), run)
    world.wait_line("serving the model", timeout=90)
    robots = {r: hosts.start(r, [str(DEPLOY / "launch-hosts.sh"), r, WORLD_ADDR[r], *opts],
                             dict(base, OUT=str(run / "host"), ZENOH_CONFIG=str(DEPLOY / "tls" / f"robot-{r}.json5")),
                             run) for r in ROBOTS}
    world.wait_line("world started ticking", timeout=120)
    t_cut = time.monotonic()
    hosts.link("r1", up=False)
    time.sleep(OUTAGE)
    hosts.link("r1", up=True)
    t_up = time.monotonic()
    assert world.finish(timeout=240) == 0, "\n".join(world.lines)
    wall = time.monotonic() - t0
    for p in robots.values():
        assert p.finish(timeout=60) == 0, "\n".join(p.lines)
        assert any("the world server has ended" in line for line in p.lines), "\n".join(p.lines[-20:])
    outcome = json.loads((run / "world-host" / "outcome.json").read_text())
    assert outcome["launcher"]["modules"] == 0 and outcome["dropped_messages"] == 0
    ref = run_scenario(load_scenario(scenario), "cekm", model, SEED, max_time=MAX_TIME)
    traj = json.loads((run / "world-host" / "trajectory.json").read_text())
    for r in ROBOTS:
        assert outcome["robots"][r]["reached"]
        assert traj[r]["x"] == ref.logs[r].x and traj[r]["y"] == ref.logs[r].y and traj[r]["v_l"] == ref.logs[r].v_l
        # Each robot host ran its own robot's modules (one log each, OUT/logs/ROBOT-MODULE.log) and no other's.
        logs = {p.name.split("-")[0] for p in (run / f"host-{r}" / "logs").glob("*-*.log")}
        assert logs == {r}, logs
    # The cut hit the run: the lockstep world waited for r1 (and republished its readings).
    assert any("republish: waiting for r1" in line for line in world.lines), "\n".join(world.lines)
    for line in world.lines:
        if "modules alive after" in line or "world done" in line:
            print(line)
    print(f"three-namespace TLS run: {wall:.1f} s wall from router start to the world's end; "
          f"r1's link down {t_up - t_cut:.1f} s")
