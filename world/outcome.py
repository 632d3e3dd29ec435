"""A world server run's statistics and its outputs: events, deadline misses, progress lines
for the launcher, and at the end ``outcome.json`` (the fields of ``cekm run`` and the
run's own) and ``trajectory.json`` (pose and command per tick)."""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cekm_swarm.jsonfile import dumps as strict_json
from cekm_swarm.runtime.percentiles import Samples, percentile

MISSED_TICKS_KEPT = 200
"""Real time: how many ticks with a deadline miss ``outcome.json`` lists (tick -> robots
that missed it), to tell a start-up hiccup from misses spread over a run."""


def emit(kind: str, doc: dict[str, Any]) -> None:
    """One progress line on stdout for the launcher. When the launcher is gone (the pipe
    is broken: it was killed, and the server is stopping on its parent-death signal),
    the lines go nowhere and the run still ends cleanly: outcome written, log closed."""
    try:
        sys.stdout.write(f"{kind} {json.dumps(doc)}\n")
        sys.stdout.flush()
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # also for the interpreter's last flush
        os.close(devnull)


@dataclass
class RunStats:
    """What happened in a run besides the world's own state."""

    events: list[dict[str, Any]] = field(default_factory=list)
    deadline_misses: int = 0
    missed_ticks: dict[int, int] = field(default_factory=dict)  # tick -> robots that missed it (the first ones)
    command_age: dict[int, int] = field(default_factory=dict)  # real time: ticks old -> commands applied that old
    first_tick_s: float | None = None  # real time: tick 0's readings to its last command
    tick_loop_seconds: float = 0.0  # wall s from the first tick's readings to the last tick
    tick_loop_cpu_end: float | None = None  # the server's CPU s (time.process_time) when the tick loop ended

    def event(self, kind: str, t: float, doc: dict[str, Any]) -> None:
        doc = {"event": kind, "t": t, **doc}
        self.events.append(doc)
        emit("EVENT", doc)

    def applied(self, age_ticks: int) -> None:
        """A robot's command applied at a tick, made ``age_ticks`` ticks before it (0: its own;
        more on a link whose round trip is longer than a tick: docs/faults.md)."""
        self.command_age[age_ticks] = self.command_age.get(age_ticks, 0) + 1

    def missed(self, tick: int) -> None:
        self.deadline_misses += 1
        if tick in self.missed_ticks or len(self.missed_ticks) < MISSED_TICKS_KEPT:
            self.missed_ticks[tick] = self.missed_ticks.get(tick, 0) + 1


def progress_doc(world: Any, episode: Any, robots: list[str], stopped: dict[str, bool],
                 republished: int, misses: int) -> dict[str, Any]:
    """A ``PROGRESS`` line's content: every robot's position (and distance to its goal)."""
    out = {}
    for r in robots:
        x, y, _ = world.pose(r)
        d = episode.to_goal(r)
        to_goal = None if d is None else round(d, 3)
        out[r] = {"x": round(x, 3), "y": round(y, 3), "to_goal": to_goal, "reached": episode.progress[r].reached,
                  "stopped": stopped.get(r, False)}
    return {"t": episode.t, "tick": episode.tick, "robots": out, "republished": republished, "deadline_misses": misses}


def latency_ms(latencies: Samples | list[float]) -> dict[str, Any]:
    """Sense-to-command latency: p50 and p99 in ms (:func:`percentile`; beyond
    ``Samples.exact_max`` samples from its histogram, within half a per cent), and how many."""
    if not len(latencies):
        return {"p50": None, "p99": None, "n": 0}
    if not isinstance(latencies, Samples):
        return {"p50": round(1000 * percentile(latencies, 0.5), 3),
                "p99": round(1000 * percentile(latencies, 0.99), 3), "n": len(latencies)}
    doc: dict[str, Any] = {"p50": round(1000 * latencies.percentile(0.5), 3),
                           "p99": round(1000 * latencies.percentile(0.99), 3), "n": len(latencies)}
    if not latencies.exact:
        doc["histogram"] = f"beyond {latencies.exact_max} samples: bins {100 * latencies.resolution:g} % wide"
    return doc


def write_outputs(out: Path, doc: dict[str, Any], episode: Any) -> None:
    """``outcome.json`` (``doc``) and ``trajectory.json`` (pose and command per tick), each
    whole or not at all (written beside, then renamed: a full disk leaves no half file)."""
    _whole(out / "outcome.json", lambda f: f.write(strict_json(doc)))
    _whole(out / "trajectory.json", lambda f: _write_trajectory(f, episode))


def _whole(path: Path, write: Any) -> None:
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "w") as f:
            write(f)
        tmp.replace(path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise


def _write_trajectory(f: Any, episode: Any) -> None:
    """Robot by robot, column by column: no run-long copy at once (the bytes of ``json.dumps``
    of the whole map)."""
    f.write("{")
    for n, (r, p) in enumerate(episode.progress.items()):
        f.write(("" if n == 0 else ", ") + json.dumps(r) + ": {")
        cols = [(name, p.path.column(j)) for j, name in enumerate(("t", "x", "y", "theta"))]
        cols += [("v_l", p.commands.column(0)), ("v_r", p.commands.column(1)),
                 ("checkpoints", [list(c) for c in p.checkpoints]), ("checkpoint_times", list(p.checkpoint_times))]
        f.write(", ".join(f"{json.dumps(name)}: {json.dumps(col)}" for name, col in cols) + "}")
        del cols
    f.write("}")
