"""A launch under another key root (``--root run2``): its log says so in its ``cekm``
metadata, and ``cekm log cat`` decodes it under that root without being told."""

from __future__ import annotations

import pytest
from mcap.reader import make_reader

from cekm_swarm.cli import main
from cekm_swarm.cli_support import run_cli
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow


def test_a_launch_under_another_root_writes_it_in_its_log(tmp_path, capsys):
    launch = LaunchProcess("lone_obstacle", tmp_path / "run", "--root", "run2", "--mode", "lockstep",
                           "--max-time", "1", "--no-plot")
    try:
        assert launch.finish(timeout=120) == 0, "\n".join(launch.lines)
    finally:
        launch.kill()
    log = tmp_path / "run" / "run.mcap"
    with open(log, "rb") as f:
        meta = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    assert meta["cekm"]["root"] == "run2"
    capsys.readouterr()
    assert run_cli(main, ["log", "cat", str(log), "--topics", "run2/world/clock"]) == 0
    out, err = capsys.readouterr()
    assert "run2/world/clock: world/clock t=0.128" in out and "MALFORMED" not in out + err
