"""A client of the embedded router that goes silent without closing (a ``cekm topic
echo 'cekm/**'`` stopped with Ctrl-Z: SIGSTOP) must not stall a real-time run: its
socket fills, its lease (10 s) expires and the router drops it while routing goes on.
With Zenoh on a single thread in the world server's router this froze every robot's
traffic for 10 s at the lease's expiry and the dead-man stopped the robot; the run here
lasts past that point (about 20 s of real time)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SCENARIO = """
name = "long_run"
description = "one robot, a long open trip: the run outlasts a stopped client's lease"
seed = 1

[arena]
bounds = [0.0, 0.0, 2.4, 1.0]

[[robots]]
id = "r1"
start = [0.2, 0.5, 0.0]
goal = "g"

[[targets]]
id = "g"
position = [2.1, 0.5]
"""
LEASE_S = 10.0  # Zenoh's default transport lease


def test_a_stopped_subscriber_does_not_stall_the_run(tmp_path):
    default_model(progress=False)
    scenario = tmp_path / "long_run.toml"
    scenario.write_text(SCENARIO)
    run = LaunchProcess(str(scenario), tmp_path / "run", "--mode", "realtime", "--max-time", "40", "--no-plot",
                        "--model", str(default_model_path()))
    echo = None
    try:
        run.wait_line("world started ticking", timeout=90)
        echo = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "topic", "echo", "cekm/**", "--connect",
                                 f"tcp/127.0.0.1:{run.port}"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                text=True)
        assert echo.stdout.readline(), "topic echo printed nothing"  # subscribed and receiving
        os.kill(echo.pid, signal.SIGSTOP)  # Ctrl-Z: its socket is never read again
        stopped_at = float(run.wait_line(" t=", timeout=20).split("t=")[1].split()[0])
        code = run.finish(timeout=120)
    finally:
        run.kill()
        if echo is not None:
            echo.kill()
            echo.wait(10)
    assert code == 0, "\n".join(run.lines[-30:])
    outcome = run.outcome()
    assert outcome["sim_seconds"] > stopped_at + LEASE_S + 2, "the run ended before the stopped client's lease"
    deadman = [e for e in outcome["events"] if e["event"] == "deadman"]
    assert not deadman, deadman
    assert outcome["robots"]["r1"]["reached"]
