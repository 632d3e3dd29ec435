"""A world host whose robots' hosts are not all started says every few seconds which
robots it still waits for, and at the timeout ends with one line naming them; the world
records why it stopped (the missing nodes, not a signal)."""

from __future__ import annotations

import json

import pytest

from cekm_swarm.launch.errors import LaunchError
from cekm_swarm.launch.launcher import LaunchConfig, Launcher
from cekm_swarm.runtime.config import free_port


@pytest.mark.slow
def test_a_missing_robot_host_is_named_while_waiting_and_at_the_timeout(tmp_path):
    out = tmp_path / "out"
    said: list[str] = []
    config = LaunchConfig("crossing", out, mode="lockstep", port=free_port(), robots=(), plot=False, max_time=2.0,
                          alive_timeout=4.0)  # no robot host at all: r1, r2 and r3 are missing
    launcher = Launcher(config, echo=said.append)
    launcher.wait_report_every = 1.0
    with pytest.raises(LaunchError) as err:
        launcher.launch()
    waiting = [s for s in said if "] waiting for r1 (" in s]
    assert waiting, said
    assert "r2 (all 14 nodes not alive)" in waiting[0] and "r3 (all 14 nodes not alive)" in waiting[0], waiting
    assert str(err.value).startswith("not alive after 4 s: r1 (all 14 nodes not alive), r2 ("), err.value
    assert len(str(err.value)) < 200
    stopped = [e for e in json.loads((out / "outcome.json").read_text())["events"] if e.get("event") == "stopped"]
    assert stopped and stopped[0].get("reason", stopped[0]) != "signal", stopped
    assert "modules missing" in json.dumps(stopped), stopped
