"""A `cekm view` started before a real-time launch on the same port sees the run: the view
waits for the launch's router, subscribes as soon as it is up, and its event stream then
carries every robot of the run, under the run's id and graph, with sim time going on.
(Reported once as a view that showed nothing in one of four tries; see docs/live-view.md.)"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import urllib.request

import pytest
from test_view_browser import Stream

from cekm_swarm.experiments.default_model import default_model_path
from cekm_swarm.runtime.config import free_port
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow  # starts a launch and a view (tests/process_guard.py)


def test_a_view_started_before_a_real_time_launch_sees_every_robot_of_the_run(tmp_path):
    port = free_port()
    view = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "view", "tracking-crowd", "--http", "0",
                             "--connect", f"tcp/127.0.0.1:{port}", "--model", str(default_model_path())],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    run = None
    try:
        assert view.stderr is not None
        assert view.stderr.readline().startswith("waiting for the router"), "the view did not wait for the router"
        run = LaunchProcess("tracking-crowd", tmp_path / "run", "--mode", "realtime", "--max-time", "8", "--no-plot",
                            "--model", str(default_model_path()), port=port)
        said = view.stderr.readline()
        assert said.startswith("live view on http://"), said
        url = said.split()[3]
        stream = Stream(url + "events")
        run_id = run.wait_line("run id", timeout=60).split("run id")[1].split()[0]
        tick = stream.wait(lambda t: t["run"] == run_id and len(t["robots"]) == 6 and (t["time"] or 0) >= 2.0, 120,
                           "the run's six robots at sim time 2 s")
        later = stream.wait(lambda t: (t["time"] or 0) >= tick["time"] + 1.0, 60, "sim time going on")
        assert set(later["robots"]) == {f"r{i}" for i in range(1, 7)}
        state = json.loads(urllib.request.urlopen(url + "state.json", timeout=30).read())
        assert state["run"] == run_id and state["graph"] == "cekm-tracking (cekm)"
        assert run.finish(timeout=120) == 0, "\n".join(run.lines[-20:])
    finally:
        view.terminate()
        view.wait(10)
        if run is not None:
            run.kill()
