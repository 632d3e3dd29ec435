"""`cekm launch` with a log set (--max-log-duration) and with a lean recording (--record
lean): the same run (lockstep: the same trajectory to the bit), a different log."""

from __future__ import annotations

import json

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.runtime.mcap_log import MSGPACK, log_info, read_messages
from helpers.launch import LaunchProcess


def _launch(out, *args):
    default_model(progress=False)
    run = LaunchProcess("lone_obstacle", out, "--mode", "lockstep", "--model", str(default_model_path()), *args)
    try:
        code = run.finish(timeout=180)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    return run


pytestmark = pytest.mark.slow  # launches and child processes


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return {name: _launch(tmp_path_factory.mktemp(name), *args) for name, args in
            (("full", ()), ("split", ("--max-log-duration", "4")), ("lean", ("--record", "lean")))}


def test_a_launch_writes_a_log_set_read_as_one_log(runs):
    split, full = runs["split"], runs["full"]
    outcome = split.outcome()
    files = outcome["log"]["files"]
    assert len(files) >= 3 and files == [f"run_{k}.mcap" for k in range(len(files))]
    assert not (split.out / "run.mcap").exists() and (split.out / "trajectory.png").is_file()
    assert any(f"run_0.mcap .. run_{len(files) - 1}.mcap ({len(files)} files)" in line for line in split.lines)
    info = log_info(split.out)
    assert info.complete and len(info.files) == len(files)
    msgpack = sum(1 for _ in read_messages(split.out, encodings=(MSGPACK,)))
    assert msgpack == outcome["recorded_messages"] == full.outcome()["recorded_messages"]
    assert json.loads((split.out / "trajectory.json").read_text()) == json.loads((full.out / "trajectory.json")
                                                                                  .read_text())


def test_a_lean_log_keeps_the_worlds_messages_and_the_commands_only(runs):
    lean, full = runs["lean"], runs["full"]
    assert lean.outcome()["robots"] == full.outcome()["robots"]  # the same run
    assert (lean.out / "trajectory.json").read_text() == (full.out / "trajectory.json").read_text()
    lean_info, full_info = log_info(lean.out / "run.mcap"), log_info(full.out / "run.mcap")
    counts = {c.topic: c.count for c in lean_info.channels}
    full_counts = {c.topic: c.count for c in full_info.channels}
    assert not [t for t in counts if "/field/" in t]
    for topic in ("cekm/world/state", "cekm/world/clock", "cekm/r1/cmd/wheels", "cekm/r1/sense/range/0"):
        assert counts[topic] == full_counts[topic], topic
    ticks = full_counts["cekm/world/clock"]
    assert counts["/view/tf"] == pytest.approx(ticks / 8, abs=2)
    assert lean.outcome()["log"]["record"] == "lean" and lean.outcome()["log"]["left_out"] > 0
    assert lean_info.size_bytes < full_info.size_bytes / 2
