"""``cekm model extract``: a learning run's map at any moment of its log, as a model file
``cekm run --model`` takes (docs/learning.md); and the ``learning`` block a launch adds to
its ``outcome.json`` from its log."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from .. import jsonfile
from ..cli_support import F, Finite, out_dir_options, prepare_out_dir, workers_option
from ..errors import CekmError, ModelFormatError
from ..models.io import load_model, save_model
from ..models.networks import IndirectEKM
from ..modules.learner import model_of
from ..runtime import foxglove_view
from ..runtime.lattice_view import add_lattice_channel, write_lattice_log
from ..runtime.map_log import map_at, versions
from .commands import parse_team_sizes, seeds_of, seeds_option
from .learning_run import UNTRAINED, model_of_choice, test_score


def controller_model(path: Path | None):
    """The model a cooperative-EKM controller runs: a file, 'untrained' or the default R15,
    refused unless it is an indirect-mapping EKM (Eq. 1)."""
    model = model_of_choice(path)  # a file, 'untrained' (docs/learning.md), or the default R15
    if not model.kind.startswith("indirect"):
        raise click.UsageError(f"{path}: the controller needs an indirect-mapping EKM (G or R), not {model.kind!r}")
    return model


class ModelChoice(click.ParamType):
    """``--model``: a model file that exists, or the word ``untrained``."""

    name = "FILE|untrained"

    def convert(self, value, param, ctx):
        if value is None or isinstance(value, Path) or value == UNTRAINED:
            return value
        path = Path(value)
        if not path.is_file():
            self.fail(f"{value!r}: no such file (give a model .npz, or 'untrained')", param, ctx)
        return path


MODEL_CHOICE = ModelChoice()

MODEL_HELP = "A trained model (.npz from `cekm train`); default: R15 trained and cached on first use."
MODEL_OR_UNTRAINED_HELP = ("A trained model (.npz from `cekm train`), or 'untrained' (docs/learning.md); default: "
                           "R15 trained and cached on first use.")


def model_option(untrained: bool = False) -> Callable[[F], F]:
    """``--model`` (as ``model_path``): a model file that exists, or with ``untrained`` also
    the word 'untrained' (:data:`MODEL_CHOICE`); none given, the default R15."""
    if untrained:
        return click.option("--model", "model_path", type=MODEL_CHOICE, help=MODEL_OR_UNTRAINED_HELP)
    return click.option("--model", "model_path", type=click.Path(dir_okay=False, exists=True, path_type=Path),
                        help=MODEL_HELP)


@click.group("model")
def model_group() -> None:
    """Models: the maps a learning run learned (docs/learning.md)."""


@model_group.command("extract")
@click.argument("log", type=click.Path(exists=True, path_type=Path))
@click.option("--robot", help="Robot id (default: the first with a map in the log).")
@click.option("--at", "at_time", type=Finite(0.0), help="Sim time (s): the version in force then (default: the last).")
@click.option("--base", "base_model", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="The model the run started from, for its lattice and parameters (default: the run's "
                   "untrained-R15.npz beside the log, else the default R15).")
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The .npz to write (replaced if it exists).")
def extract_cmd(log: Path, robot: str | None, at_time: float | None, base_model: Path | None, out_path: Path) -> None:
    """Write ROBOT's map from a learning run's LOG (run.mcap) as a model file."""
    if robot is None:
        robots = sorted(versions(log))
        if not robots:
            raise click.UsageError(f"{log}: no map versions in this log (was it a --learn run?)")
        robot = robots[0]
    msg = map_at(log, robot, at_time)
    if msg is None:
        raise click.UsageError(f"{log}: no map version of robot {robot!r}" + ("" if at_time is None else
                                                                              f" before t={at_time} s"))
    net = model_of(_base_model(log, base_model), msg)
    save_model(out_path, net, {"extracted_from": str(log), "robot": robot, "version": msg.version,
                               "stamp": msg.stamp, "digest": msg.digest})
    click.echo(f"{robot}: map version {msg.version} (t={msg.stamp:.3f} s, {msg.applied} learning steps, digest "
               f"{msg.digest}); wrote {out_path}")


@model_group.command("lattice")
@click.argument("log", type=click.Path(exists=True, path_type=Path))
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The .mcap to write (replaced if it exists).")
def lattice_cmd(log: Path, out_path: Path) -> None:
    """Write every map version of a learning run's LOG as a Foxglove view of its lattice
    (``/view/lattice/<robot>``; a --learn launch writes them into its run.mcap itself)."""
    try:
        n = write_lattice_log(log, out_path)
    except ImportError as exc:
        raise click.UsageError(str(exc)) from None
    click.echo(f"{n} map versions; wrote {out_path}")


def _base_model(log: Path, base: Path | None):
    from .default_model import default_model  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

    beside = Path(log).parent / "untrained-R15.npz"
    if base is not None:
        return load_model(base)
    return load_model(beside) if beside.is_file() else default_model()


def add_launch_learning(out_dir: Path, outcome: dict[str, Any], model_path) -> dict[str, Any]:
    """A launch's ``learning`` block from its log (each robot's last map version), written
    into ``outcome.json``; {} when the run had no learner."""
    from .default_model import default_model  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

    log = Path(out_dir) / "run.mcap"
    if not log.exists():
        return {}
    seen = versions(log)
    if not seen:
        return {}
    base = load_model(model_path) if model_path is not None else default_model()
    if not isinstance(base, IndirectEKM):
        raise ModelFormatError(model_path or "the default model", None,
                               f"online learning needs an indirect-mapped EKM, not a {type(base).__name__}")
    start = test_score(base)
    nodes = (outcome.get("launcher") or {}).get("nodes") or {}
    block = {}
    for robot in sorted(seen):
        msg = map_at(log, robot)
        assert msg is not None  # the robot has versions in the log (seen)
        block[robot] = {"versions": msg.version, "steps": msg.steps, "updates_applied": msg.applied,
                        "skipped": msg.skipped, "final_digest": msg.digest,
                        "messages_dropped_by_nodes": sum(int(s.get("dropped") or 0) for label, s in nodes.items()
                                                         if label.startswith(robot + "/")),
                        "start": start, "end": test_score(model_of(base, msg))}
    outcome["learning"] = block
    (Path(out_dir) / "outcome.json").write_text(jsonfile.dumps(outcome))

    if foxglove_view.available():  # the maps as Foxglove views (docs/learning.md)

        if log.is_file():  # a channel of the run's own log
            add_lattice_channel(log)
        else:  # a log set (a directory): a file of its own beside it
            write_lattice_log(log, Path(out_dir) / "lattice.mcap")
    return block


@click.command("learning")
@click.option("--teams", default="1,2,4,8", show_default=True, help="Team sizes, comma-separated.")
@seeds_option("1,2")
@click.option("--ticks", default=1600, show_default=True, type=click.IntRange(16, 100_000),
              help="Ticks of 0.128 s per run (about one learning step each per robot).")
@workers_option("Parallel processes (default: one per core).")
@out_dir_options("Directory for results.json and learning.png.")
def learning_experiment_cmd(teams: str, seeds: str, ticks: int, workers: int | None, out_dir: Path,
                            overwrite: bool) -> None:
    """Learning curves through the graph: untrained R15 maps learning online in section 4.1's
    arena, teams of 1-8 robots with and without sharing their (v, c) pairs (docs/learning.md)."""
    from .learning_experiment import LearningConfig, plot_curves, results_doc, run_experiment, summary_table  # noqa: PLC0415 -- lazy: pymunk, world

    try:
        config = LearningConfig(teams=parse_team_sizes(teams), seeds=tuple(seeds_of(seeds)), ticks=ticks,
                                evals=tuple(t for t in LearningConfig.evals if t < ticks) + (ticks,))
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    if not config.seeds:
        raise click.UsageError("--seeds: give at least one seed")
    prepare_out_dir(out_dir, overwrite)
    n_runs = sum((2 if n > 1 else 1) * len(config.seeds) for n in config.teams)
    t0 = time.perf_counter()
    with click.progressbar(length=n_runs, label="runs", show_eta=True) as bar:
        curves = run_experiment(config, out_dir, workers or min(2, os.cpu_count() or 1), lambda c: bar.update(1))
    doc = results_doc(config, curves)
    doc["wall_seconds"] = round(time.perf_counter() - t0, 1)
    (out_dir / "results.json").write_text(jsonfile.dumps(doc))
    plot_curves(config, curves).savefig(out_dir / "learning.png", dpi=120)
    for line in summary_table(doc):
        click.echo(line)
    click.echo(f"wrote {out_dir / 'results.json'}, {out_dir / 'learning.png'} ({doc['wall_seconds']} s)")
