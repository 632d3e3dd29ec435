"""``cekm view SCENARIO`` attached to a run of another scenario: it draws the run's arena
(the one its world server serves), saying so in a warning, not the SCENARIO it was given.

The run is split as on two hosts: a world-only launcher, whose lockstep world holds tick 0
until the robot's modules are alive, and the robot's launcher, started only once the view
has drawn the run's arena. So the view attaches before the run begins whatever the
machine's speed (a whole run of one launcher can end within a second of its router
coming up, before a view retrying to connect gets there)."""

from __future__ import annotations

import json
import subprocess
import sys
import urllib.request

import pytest

from cekm_swarm.runtime.lines import LineReader
from helpers.launch import LaunchProcess, interrupt

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)


def test_a_view_given_another_scenario_draws_the_runs_arena_with_a_warning(tmp_path):
    common = ("--mode", "lockstep", "--max-time", "1", "--no-plot")
    world = LaunchProcess("lone_obstacle", tmp_path / "world-host", "--robots", "none", *common)
    view = robots = None
    try:
        world.wait_line("serving the model", timeout=60)
        endpoint = f"tcp/127.0.0.1:{world.port}"
        view = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "view", "crossing", "--http", "0",
                                 "--connect", endpoint],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
        lines = LineReader(view.stderr)
        said = lines.seen
        url = lines.wait_line("live view on http://", 120).split()[3]
        warning = lines.wait_line("is of arena 'lone_obstacle', not 'crossing': drawing the run's", 120)
        assert warning.startswith("the run "), said
        after = json.loads(urllib.request.urlopen(url + "state.json", timeout=30).read())
        assert after["geometry"]["name"] == "lone_obstacle" and after["arena"] == "lone_obstacle"
        assert [r["id"] for r in after["geometry"]["robots"]] == ["r1"]  # the run's robots, not crossing's
        assert sorted(after["colours"]) == ["r1"]
        robots = LaunchProcess("lone_obstacle", tmp_path / "robot-host", "--robots", "r1", "--no-world",
                               "--connect", endpoint, *common)
        assert world.finish(timeout=120) == 0, "\n".join(world.lines)
        assert robots.finish(timeout=60) == 0, "\n".join(robots.lines)
        assert world.outcome()["robots"]["r1"]["path_length_m"] > 0  # the run the view watched did run
    finally:
        world.kill()
        if robots is not None:
            robots.kill()
        if view is not None:
            interrupt(view)
