"""A user's node that fails, through ``cekm launch`` with real processes: in lockstep the
launch ends at once with the node's one line (it waited forever before, the world
re-publishing its tick); in real time the run goes on and the launch names the node and
its failures at the end and in outcome.json. And a node due every tick that reads only a
reading sent every other tick runs every tick, in lockstep without a stall and equal to
``cekm run``, in real time without a deadline miss."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model_path
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow

FAILING = '''
from dataclasses import dataclass

from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import SenseTarget, WheelCommand


class Failing(Node):
    """Drives toward the target reading; from t >= at its step raises (a bug in the node)."""

    inputs = {"reading": In(SenseTarget)}
    outputs = {"command": Out(WheelCommand)}

    @dataclass(frozen=True)
    class Params:
        at: float = 0.5

    def step(self, t, inputs):
        if t >= self.params.at:
            raise RuntimeError(f"boom in the user's step at t={t:.3f}")  # a text of its own each tick
        r = inputs["reading"]
        turn = 0.0 if r is None else 0.02 * r.alpha
        return {"command": WheelCommand(t, self.ctx.sender, 0.05 - turn, 0.05 + turn, 0)}


class ReadingMotor(Failing):
    """The same without the bug."""

    @dataclass(frozen=True)
    class Params:
        at: float = 1e9
'''


def graph(folder: Path, program: str) -> Path:
    (folder / "mine.py").write_text(textwrap.dedent(FAILING))
    path = folder / f"{program.lower()}.toml"
    path.write_text(textwrap.dedent(f'''
        [graph]
        controller = "{program.lower()}"
        task = "navigation"
        answer = "cmd/wheels"

        [[node]]
        name = "motor"
        program = "mine:{program}"
        every = 1
        inputs = {{ reading = "sense/target" }}
        outputs = {{ command = "cmd/wheels" }}
        '''))
    return path


def launch(tmp_path: Path, graph_file: Path, mode: str, max_time: str, out: str) -> tuple[LaunchProcess, int]:
    """``cekm launch lone_obstacle`` with the graph, run to its end: the process and its exit code."""
    run = LaunchProcess("lone_obstacle", tmp_path / out, "--graph", str(graph_file), "--mode", mode, "--max-time",
                        max_time, "--model", str(default_model_path()), "--no-plot", cwd=tmp_path)
    try:
        return run, run.finish(timeout=120)
    finally:
        run.kill()


def test_lockstep_ends_with_the_failing_nodes_line(tmp_path):
    run, code = launch(tmp_path, graph(tmp_path, "Failing"), "lockstep", "20", "ls")
    assert code == 1, "\n".join(run.lines[-20:])  # the run failed (not bad input)
    last = run.lines[-1]
    assert last.startswith("cekm: failed: r1/motor: its step at t=0.512 s failed: RuntimeError: boom in the user's "
                           "step at t=0.512 "
                           "(mine.py:"), last
    assert "lockstep the run cannot go on" in last
    assert not any("republish" in line for line in run.lines), "the world waited for the failed node"


def test_realtime_goes_on_and_names_the_failures(tmp_path):
    run, code = launch(tmp_path, graph(tmp_path, "Failing"), "realtime", "3", "rt")
    assert code == 0, "\n".join(run.lines[-20:])
    failures = run.outcome()["launcher"]["nodes"]["r1/motor"]["step_failures"]
    # one group, however its texts differ: grouped by where it was raised, named by its first text and line
    assert len(failures) == 1 and failures[list(failures)[0]] >= 10, failures
    assert re.fullmatch(r"RuntimeError: boom in the user's step at t=0\.\d{3} \(mine\.py:\d+\)", list(failures)[0])
    assert any(line.split("] ", 1)[-1].startswith("node r1/motor: ") and "runs failed" in line
               for line in run.lines), "\n".join(run.lines[-20:])


def test_a_node_read_by_an_every_other_tick_reading_runs_every_tick(tmp_path):
    g = graph(tmp_path, "ReadingMotor")
    ref = subprocess.run([sys.executable, "-m", "cekm_swarm", "run", "lone_obstacle", "--graph", str(g), "--max-time",
                          "10", "--out", str(tmp_path / "run")], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert ref.returncode == 0, ref.stderr
    run, code = launch(tmp_path, g, "lockstep", "10", "ls")
    assert code == 0, "\n".join(run.lines[-20:])
    assert not any("republish" in line for line in run.lines), "the world waited for the node's odd ticks"
    a, b = json.loads((tmp_path / "run" / "outcome.json").read_text()), run.outcome()
    assert a["robots"] == b["robots"]  # time, path length, clearance, final distance: bit for bit
    rt, code = launch(tmp_path, g, "realtime", "5", "rt")
    assert code == 0, "\n".join(rt.lines[-20:])
    assert rt.outcome()["deadline_misses"] == 0
