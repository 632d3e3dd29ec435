"""The world server's settings, declared once: its command line (a click command, as every
``cekm`` command is), the frozen :class:`WorldConfig` the server runs from, and the argv
the launcher starts it with all come from :data:`WORLD_OPTIONS`; the checks of what they
name (``--checkpoints``, the run spec) refuse a bad value in one line before anything
starts."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import click

from cekm_swarm.cli_support import SEED, Finite
from cekm_swarm.graph.runspec import RunSpec
from cekm_swarm.graph.spec import GraphError
from cekm_swarm.protocol import DEFAULT_ROOT, KeySpaceError, validate_run_id
from cekm_swarm.runtime.config import DEFAULT_ENDPOINT
from cekm_swarm.runtime.wait import DEFAULT_WAIT

from .deadman import DEADMAN_S
from .recorder import RECORD_MODES

REPUBLISH_S = 1.0
DEFAULT_MAX_TIME = 600.0


@dataclass(frozen=True)
class WorldConfig:
    """The world server's settings (one field per option of :data:`WORLD_OPTIONS`)."""

    scenario: str
    out: str
    spec: str | None = None
    connect: str = DEFAULT_ENDPOINT
    listen: str | None = None
    zenoh_config: str | None = None
    wait_router: float = DEFAULT_WAIT
    wait_modules: float = 0.0
    root: str = DEFAULT_ROOT
    run_id: str | None = None
    mode: str = "realtime"
    seed: int | None = None
    max_time: float = DEFAULT_MAX_TIME
    checkpoints: str | None = None
    deadman: float = DEADMAN_S
    deadline_ticks: int = 0
    republish: float = REPUBLISH_S
    match_timeout: float = 20.0
    progress_every: float = 1.0
    log_level: str = "INFO"
    max_log_size: int | None = None
    max_log_duration: float | None = None
    record: str = "full"


def _run_id(ctx: Any, param: Any, value: str | None) -> str | None:
    if value is None:
        return None
    try:
        return validate_run_id(value)
    except KeySpaceError as exc:
        raise click.BadParameter(str(exc)) from None


RUN_FILES = ("outcome.json", "trajectory.json", "run.mcap", "run_0.mcap", "run.truncated.mcap")


def earlier_run_files(out: Path) -> list[str]:
    """The world's own outputs already in ``out`` (an earlier run's, which a new run would
    replace while leaving that run's other files beside them)."""
    return [name for name in RUN_FILES if (out / name).exists()]


def _out(ctx: Any, param: Any, value: str | None) -> str | None:
    held = earlier_run_files(Path(value)) if value is not None else []
    if held:
        raise click.BadParameter(f"{value} already holds a run ({', '.join(held)}): choose another directory, "
                                 f"or remove them (cekm launch --overwrite clears its own)")
    return value


WORLD_OPTIONS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("spec", {"help": "the run spec (cekm launch writes OUT/run-spec.json): the controller's graph, from which the "
                      "world takes the nodes it waits for, the readings it publishes and the keys it records "
                      "(default: every reading of the scenario's task, commands on cmd/wheels)"}),
    ("connect", {"default": DEFAULT_ENDPOINT, "show_default": True, "help": "join this router as a client"}),
    ("listen", {"metavar": "tcp/HOST:PORT",
                "help": "host the router here (the embedded default) instead of joining one"}),
    ("zenoh_config", {"help": "Zenoh client config file (credentials, TLS; see deploy/)"}),
    ("wait_router", {"type": Finite(0.0), "default": DEFAULT_WAIT, "show_default": True, "metavar": "S",
                     "help": "with --connect: while nothing accepts connections there, wait up to S s for the "
                             "router, saying so (0: fail at once); Ctrl-C or SIGTERM ends the wait"}),
    ("wait_modules", {"type": Finite(0.0), "default": 0.0, "metavar": "S",
                      "help": "hold tick 0 until every robot's nodes are alive, at most S s (0: do not wait)"}),
    ("root", {"default": DEFAULT_ROOT, "show_default": True}),
    ("run_id", {"callback": _run_id, "help": "the launch's run id: the world's token carries it, and it waits only "
                                             "for nodes of this run"}),
    ("out", {"required": True, "callback": _out,
             "help": "directory for run.mcap, outcome.json, trajectory.json (refused if it "
                     "already holds a run's: the launcher gives it a cleared one)"}),
    ("mode", {"type": click.Choice(["realtime", "lockstep"]), "default": "realtime", "show_default": True}),
    ("seed", {"type": SEED}),
    ("max_time", {"type": Finite(0.0, min_open=True), "default": DEFAULT_MAX_TIME, "show_default": True}),
    ("checkpoints", {"help": "JSON {robot: [[x, y], ...]} or a file holding it"}),
    ("deadman", {"type": Finite(0.0, min_open=True), "default": DEADMAN_S, "show_default": True,
                 "help": "s without commands before a robot is stopped"}),
    ("deadline_ticks", {"type": click.IntRange(0, 64), "default": 0, "show_default": True, "metavar": "N",
                        "help": "real time: a robot's command for tick k is on time until the end of tick k+N; a "
                                "robot-tick whose applied command is older is a deadline miss (a link whose round "
                                "trip exceeds a tick wants more: docs/faults.md)"}),
    ("republish", {"type": Finite(0.0, min_open=True), "default": REPUBLISH_S, "show_default": True,
                   "help": "lockstep: s before re-publishing a tick"}),
    ("match_timeout", {"type": Finite(0.0), "default": 20.0, "show_default": True}),
    ("progress_every", {"type": Finite(0.0, min_open=True), "default": 1.0, "show_default": True,
                        "help": "wall s between PROGRESS lines"}),
    ("log_level", {"type": click.Choice(["DEBUG", "INFO", "WARNING", "ERROR"], case_sensitive=False),
                   "default": "INFO", "show_default": True}),
    ("max_log_size", {"type": click.IntRange(1), "metavar": "BYTES",
                      "help": "split the log into a set: run_0.mcap, run_1.mcap, ... of at most this many bytes each"}),
    ("max_log_duration", {"type": Finite(0.0, min_open=True), "metavar": "S",
                          "help": "split the log into a set: a new file every S s of sim time"}),
    ("record", {"type": click.Choice(RECORD_MODES), "default": "full", "show_default": True,
                "help": "what the log holds: full (every key and view) or lean (for long runs: docs/tools.md)"}),
)
"""The world server's options (besides the SCENARIO argument): its command line, the
launcher's argv and :class:`WorldConfig` come from here."""

assert {n for n, _ in WORLD_OPTIONS} | {"scenario"} == {f.name for f in fields(WorldConfig)}


def flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def world_options(f: Any) -> Any:
    """Decorate a click command with SCENARIO and every option of :data:`WORLD_OPTIONS`."""
    for name, kw in reversed(WORLD_OPTIONS):
        f = click.option(flag(name), name, **kw)(f)
    return click.argument("scenario")(f)


def server_argv(**values: Any) -> list[str]:
    """The command line that starts the world server with ``values`` (names of
    :class:`WorldConfig`; None leaves an option out). An unknown or missing one is a
    TypeError here, in the launcher, not a process that dies on start-up."""
    known = {f.name for f in fields(WorldConfig)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise TypeError(f"the world server has no option {flag(unknown[0])}")
    for name in ("scenario", "out"):
        if values.get(name) is None:
            raise TypeError(f"the world server needs {name if name == 'scenario' else flag(name)}")
    argv = [sys.executable, "-m", "world.server", str(values["scenario"])]
    for name, _ in WORLD_OPTIONS:
        v = values.get(name)
        if v is not None:
            argv += [flag(name), str(v)]
    return argv


def parse_argv(argv: list[str]) -> WorldConfig:
    """The :class:`WorldConfig` of a world server command line (``argv`` without the
    program), as the server parses it; a bad one raises click's UsageError."""

    @click.command()
    @world_options
    def parse(**values: Any) -> WorldConfig:
        return WorldConfig(**values)

    return parse.main(args=list(argv), standalone_mode=False)


class CheckpointsError(ValueError):
    """``--checkpoints`` is unreadable or malformed; the message names what is wrong."""


def parse_checkpoints(value: str, robots: list[str]) -> dict[str, list[tuple[float, float]]]:
    """``--checkpoints``: JSON ``{robot: [[x, y], ...]}``, or the path of a file holding it.
    Raises :class:`CheckpointsError` naming what is wrong (the file, the robot, the entry)."""
    where = "--checkpoints"
    raw = value
    if not value.lstrip().startswith("{"):
        where = f"--checkpoints {value}"
        try:
            raw = Path(value).read_text()
        except OSError as exc:
            raise CheckpointsError(f"{where}: cannot read it ({exc.strerror or exc})") from None
    try:
        doc = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise CheckpointsError(f"{where}: not JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise CheckpointsError(f"{where}: must be a JSON object {{robot: [[x, y], ...]}}, got {type(doc).__name__}")
    out: dict[str, list[tuple[float, float]]] = {}
    for robot, cps in doc.items():
        if robot not in robots:
            raise CheckpointsError(f"{where}: no robot {robot!r} in the scenario (robots: {', '.join(robots)})")
        if not isinstance(cps, list) or not cps:
            raise CheckpointsError(f"{where}: {robot}: must be a non-empty list of [x, y]")
        for i, c in enumerate(cps):
            if not (isinstance(c, list) and len(c) == 2
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in c)):
                raise CheckpointsError(f"{where}: {robot}[{i}]: must be [x, y] with finite numbers, got {c!r}")
        out[robot] = [(float(c[0]), float(c[1])) for c in cps]
    return out


def load_run_graph(path: str | None, scenario: Any, robots: list[str], task: str, root: str,
                   run_id: str | None) -> tuple[Any, Any]:
    """The run spec at ``path`` and its plan for this run (None, None without one),
    refused with a one-line GraphError when it does not fit the scenario (another team,
    task or key root)."""
    if not path:
        return None, None
    spec = RunSpec.read(path)
    if tuple(spec.team) != tuple(robots):
        raise GraphError(path, "team", f"the run spec is for robots {', '.join(spec.team)}, the scenario "
                                       f"{scenario.name!r} has {', '.join(robots)}")
    if spec.task != task:
        raise GraphError(path, "task", f"the run spec is for a {spec.task} run, {scenario.name!r} is a {task} scenario")
    if spec.root != root:
        raise GraphError(path, "root", f"the run spec's key root is {spec.root!r}, the world's {root!r}")
    spec = spec.with_(run_id=run_id)
    return spec, spec.plan()
