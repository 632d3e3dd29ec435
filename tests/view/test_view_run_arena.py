"""``cekm view SCENARIO`` attached to a run of another scenario: it draws the run's arena
(the one its world server serves), saying so in a warning, not the SCENARIO it was given."""

from __future__ import annotations

import json
import subprocess
import sys
import urllib.request

import pytest

from cekm_swarm.runtime.config import free_port
from cekm_swarm.runtime.lines import LineReader
from helpers.launch import LaunchProcess, interrupt

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)


def test_a_view_given_another_scenario_draws_the_runs_arena_with_a_warning(tmp_path):
    port = free_port()
    view = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "view", "crossing", "--http", "0",
                             "--connect", f"tcp/127.0.0.1:{port}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    lines = LineReader(view.stderr)
    run = LaunchProcess("lone_obstacle", tmp_path / "run", "--mode", "lockstep", "--max-time", "1", "--no-plot",
                        port=port)
    said = lines.seen

    def wait_for(text: str) -> str:
        return lines.wait_line(text, 120)

    try:
        url = wait_for("live view on http://").split()[3]
        warning = wait_for("is of arena 'lone_obstacle', not 'crossing': drawing the run's")
        assert warning.startswith("the run "), said
        after = json.loads(urllib.request.urlopen(url + "state.json", timeout=30).read())
        assert after["geometry"]["name"] == "lone_obstacle" and after["arena"] == "lone_obstacle"
        assert [r["id"] for r in after["geometry"]["robots"]] == ["r1"]  # the run's robots, not crossing's
        assert sorted(after["colours"]) == ["r1"]
        assert run.finish(timeout=120) == 0, "\n".join(run.lines[-20:])
    finally:
        run.kill()
        interrupt(view)
