"""The launcher's start of its node processes, without processes: what it says while it
starts many (a note past the measured size, progress every few seconds) and that a stop
during the start ends it."""

from __future__ import annotations

import asyncio
from pathlib import Path
from types import SimpleNamespace

from cekm_swarm.experiments.graph_run import resolve_graph
from cekm_swarm.launch import supervision
from cekm_swarm.launch.supervision import Supervision


class Starter(Supervision):
    """A launcher's supervision side whose processes are not started (recorded instead)."""

    def __init__(self, robots: list[str], report_every: float, stop_after: int | None = None) -> None:
        self.checked = resolve_graph("cekm", None, "navigation")
        self.plan = self.checked.plan(robots, "navigation")
        self.c = SimpleNamespace(mode="lockstep", out=Path("/nonexistent"))
        self.children, self.supervisors, self.lines, self.started = {}, [], [], []
        self.world_proc, self.stopping, self.interrupted, self.failure = None, False, False, None
        self.spec_path, self.run_id, self.wait_report_every = Path("spec.json"), "run", report_every
        self.stop_after = stop_after

    def say(self, text: str) -> None:
        self.lines.append(text)

    async def _spawn(self, child) -> None:
        self.started.append(child.label)
        if self.stop_after is not None and len(self.started) == self.stop_after:
            self.interrupted = True  # Ctrl-C while the nodes start (the world then stops first)

    async def _supervise(self, child) -> None:
        return None


def start(starter: Starter, robots: list[str]) -> None:
    asyncio.run(starter._spawn_modules(SimpleNamespace(name="crowd"), robots, "model.npz", "tcp/127.0.0.1:1"))


def test_a_launch_past_the_measured_size_says_so_and_reports_its_progress(monkeypatch):
    monkeypatch.setattr(supervision, "MEASURED_PROCESSES", 20)
    robots = ["r1", "r2"]
    s = Starter(robots, report_every=0.0)
    start(s, robots)
    assert len(s.started) == 28 and s.lines[0].endswith("starting 28 node processes (lockstep)")
    assert s.lines[1].startswith("note: 28 node processes is more than this runtime has been measured with (20: ")
    assert [line for line in s.lines if line.startswith("started ")][-1] == "started 28 of 28 node processes ..."


def test_a_launch_within_the_measured_size_starts_quietly():
    robots = ["r1"]
    s = Starter(robots, report_every=60.0)
    start(s, robots)
    assert len(s.started) == 14 and len(s.lines) == 1  # one line: what it starts


def test_a_stop_while_the_nodes_start_starts_no_more():
    robots = ["r1", "r2"]
    s = Starter(robots, report_every=60.0, stop_after=5)
    start(s, robots)
    assert len(s.started) == 5 and s.supervisors == []

