"""The documented user module (docs/modules.md, docs/examples/): a graph of the user's own
-- their obstacle avoidance in place of the 12 obstacle modules, and a command log -- runs
through `cekm launch --graph`, is listed by `cekm node list`, is recorded in run.mcap, and
in lockstep equals `cekm run --graph` bit for bit."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model_path
from cekm_swarm.protocol import ObstacleField, decode
from cekm_swarm.runtime.mcap_log import read_messages
from helpers.launch import LaunchProcess

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


@pytest.fixture
def user_graph(tmp_path):
    """The example copied where a user would keep it: the graph file and its module side by side."""
    folder = tmp_path / "mine"
    folder.mkdir()
    for name in ("nearest.toml", "nearest_obstacle.py"):
        shutil.copy(EXAMPLES / name, folder / name)
    return folder / "nearest.toml"


def cekm(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cekm_swarm", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.slow
def test_the_documented_user_graph_runs_is_listed_and_recorded(user_graph, tmp_path):
    out = tmp_path / "rt"
    run = LaunchProcess("lone_obstacle", out, "--graph", str(user_graph), "--mode", "realtime", "--max-time", "6",
                        "--model", str(default_model_path()), "--no-plot", cwd=tmp_path)
    try:
        run.wait_line("world started ticking", timeout=120)
        listed = cekm("node", "list", "--connect", f"tcp/127.0.0.1:{run.port}", cwd=tmp_path)
        code = run.finish(timeout=120)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines[-30:])
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    assert lines[0] == "graph nearest (controller nearest): 4 nodes per robot", listed.stdout
    assert any(line.startswith("r1") and "4/4 nodes alive" in line for line in lines), listed.stdout
    fields = [decode(m.topic, m.data) for m in read_messages(out / "run.mcap", topics=["cekm/r1/avoid/nearest"])]
    assert len(fields) > 20 and all(isinstance(f, ObstacleField) and f.sender == "r1/nearest" for f in fields)
    assert any(f.winner is not None for f in fields)  # the disc was seen
    log = (tmp_path / "r1-commands.csv").read_text().splitlines()  # the log node's file, where it was launched
    assert log[0] == "t,v_l,v_r" and len(log) > 20


@pytest.mark.slow
def test_the_documented_user_graph_in_lockstep_equals_cekm_run(user_graph, tmp_path):
    run = cekm("run", "lone_obstacle", "--graph", str(user_graph), "--out", str(tmp_path / "run"), cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    launch = LaunchProcess("lone_obstacle", tmp_path / "launch", "--graph", str(user_graph), "--mode", "lockstep",
                           "--model", str(default_model_path()), "--no-plot", cwd=tmp_path)
    try:
        assert launch.finish(timeout=180) == 0, "\n".join(launch.lines[-30:])
    finally:
        launch.kill()
    a = json.loads((tmp_path / "run" / "outcome.json").read_text())
    b = launch.outcome()
    assert a["graph"] == b["graph"] == "nearest" and a["robots"] == b["robots"]
    assert a["robots"]["r1"]["reached"]
