"""The experiments' command-line glue: what ``cekm run`` (navigation and tracking),
``cekm experiment target-reaching`` and ``cekm experiment tracking`` (and ``--grid``) do
once click has parsed their options -- load the model, run, write the files (through the
experiments' own modules) and print a summary -- and the parsing of the commands' list
options (team sizes, seeds, numbers). The running, statistics, figure and report modules
import no click and no matplotlib at module level; this module talks to the terminal.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
import typing
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .. import jsonfile
from ..cli_support import F, ScenarioFileError, workers_option
from ..controller.planner import PlanningError
from ..errors import ParameterError, ResultsFileError
from ..models.io import load_model
from ..models.params import TrackingParams
from .engine import ClusterAddressError, check_address, on_cluster
from .field_widths import FIELDS
from .navigation_figures import plot_run
from .navigation_run import planned_checkpoints, run_scenario
from .reaching_report import write_seed, write_seeds_report

if TYPE_CHECKING:
    from .reaching_config import NetworkRun, TargetReachingConfig


def fields_option(default: str | None, what: str) -> Callable[[F], F]:
    """``--fields paper|tuned|learned``: cekm's field widths (:mod:`.field_widths`)."""
    return click.option("--fields", type=click.Choice(FIELDS), default=default, show_default=default is not None,
                        help=f"cekm's field widths: the paper's, today's hand-tuned constants or the learned field "
                             f"policy's (docs/fields.md); {what}.")


def engine_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """A many-run experiment's ``--workers N`` (the local Dask cluster's processes; 1: in
    this process) and ``--cluster tcp://HOST:PORT`` (a running Dask scheduler instead): the
    command runs inside :func:`.engine.on_cluster` (:mod:`.engine`)."""
    def address(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
        try:
            return None if value is None else check_address(value)
        except ClusterAddressError as exc:
            raise click.BadParameter(str(exc)) from None

    @workers_option("Local worker processes (default: one per core; target-reaching: its seeds one after the "
                    "other; 1: in this process).")
    @click.option("--cluster", callback=address, metavar="tcp://HOST:PORT",
                  help="Run on the Dask scheduler at this address instead of a local cluster "
                       "(docs/performance.md, \"Experiments on a cluster\").")
    @functools.wraps(fn)
    def wrapper(*args: Any, cluster: str | None = None, **kwargs: Any) -> Any:
        with on_cluster(cluster):
            return fn(*args, **kwargs)

    return wrapper


def load_scenario_file(name: str) -> Any:
    """The scenario ``name`` (a name under world/scenarios or a .toml path); a bad file
    refused in one line naming it (exit 2)."""
    from world import ScenarioError, load_scenario  # noqa: PLC0415 -- lazy: pymunk, not at cekm --help

    try:
        return load_scenario(name)
    except ScenarioError as exc:
        raise ScenarioFileError(str(exc)) from None


def scenario_kind(scenario: Any) -> str:
    """``"tracking"`` or ``"navigation"``; a bad scenario file for one that is neither."""
    from world import ScenarioError  # noqa: PLC0415 -- lazy: pymunk, not at cekm --help
    from world.tracking import run_kind  # noqa: PLC0415 -- lazy: pymunk, not at cekm --help

    try:
        return run_kind(scenario)
    except ScenarioError as exc:
        raise ScenarioFileError(str(exc)) from None


def refuse_unplannable(scenario) -> None:
    """A ``plan_checkpoints`` scenario whose known walls leave a robot no path: refused in
    one line naming the file and the robot, before anything is written or started."""
    if not scenario.plan_checkpoints:
        return
    try:
        planned_checkpoints(scenario)
    except PlanningError as exc:
        raise ScenarioFileError(str(exc)) from None


def seeds_option(default: str) -> Callable[[F], F]:
    """``--seeds``: seeds as a list and/or ranges (read by :func:`seeds_of`)."""
    return click.option("--seeds", default=default, show_default=True,
                        help="Seeds: a list and/or ranges, e.g. 1-20 or 1,2,7.")


def run_navigation_cmd(scenario, controller: str, model, seed: int | None, max_time: float, out_dir, graph) -> None:
    """``cekm run`` on a navigation scenario: outcome.json and trajectory.png, and each robot's outcome."""
    from world.episode import pushed_out_note  # noqa: PLC0415 -- lazy: pymunk, world

    t0 = time.perf_counter()
    run = run_scenario(scenario, controller, model, seed, max_time, graph=graph)
    doc = {"scenario": scenario.name, "controller": controller, "graph": graph.graph.name, "seed": run.seed,
           "robots": run.outcome,
           "wall_seconds": round(time.perf_counter() - t0, 3)}
    if run.learning:
        doc["learning"] = run.learning
    (out_dir / "outcome.json").write_text(jsonfile.dumps(doc))
    import matplotlib.pyplot as plt  # noqa: PLC0415 -- lazy: matplotlib

    fig = plot_run(run)
    fig.savefig(out_dir / "trajectory.png", dpi=130)
    plt.close(fig)  # a run in a long-lived process (a test, a notebook) leaves no figure open
    for r, o in run.outcome.items():
        c = o["min_clearance_m"]
        clearance = ("nothing within sensor range" if c is None else f"{c * 1000:.0f} mm" if c >= 0.0 else
                     f"{c * 1000:.1f} mm (in contact)")
        click.echo(f"{r}: {'reached' if o['reached'] else 'NOT reached'} in {o['time_s']:.1f} s, path "
                   f"{o['path_length_m']:.2f} m, {o['collisions']} collisions, min clearance {clearance}"
                   f"{pushed_out_note(o)}")
    click.echo(f"wrote {out_dir / 'outcome.json'}, {out_dir / 'trajectory.png'}")


def run_tracking_cmd(scenario, controller: str, model_path, seed: int | None, duration: float | None, out_dir,
                     graph=None, model=None) -> None:
    """``cekm run`` on a tracking scenario: outcome.json (with ``tracking``) and trajectory.png."""
    from .tracking_figures import plot_tracking  # noqa: PLC0415 -- lazy: pymunk, world
    from .tracking_run import DEFAULT_DURATION, outcome_doc, run_tracking  # noqa: PLC0415 -- lazy: pymunk, world

    if model is None and controller == "cekm" and graph is None:
        from .default_model import default_model  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

        model = load_model(model_path) if model_path else default_model()
    t0 = time.perf_counter()
    run = run_tracking(scenario, controller, model, seed, DEFAULT_DURATION if duration is None else duration,
                       graph=graph)
    out = Path(out_dir)
    doc = outcome_doc(run)
    doc["wall_seconds"] = round(time.perf_counter() - t0, 3)
    (out / "outcome.json").write_text(jsonfile.dumps(doc))
    import matplotlib.pyplot as plt

    fig = plot_tracking(run)
    fig.savefig(out / "trajectory.png", dpi=130)
    plt.close(fig)
    from world.tracking import tracking_summary  # noqa: PLC0415 -- lazy: pymunk, world

    click.echo(tracking_summary(run.tracking, sum(run.collisions.values())))
    click.echo(f"wrote {out / 'outcome.json'}, {out / 'trajectory.png'}")


def parse_whole_numbers(text: str, option: str, what: str, low: int, high: int) -> tuple[int, ...]:
    """``option`` given as comma-separated whole numbers (``what``, e.g. "team sizes like
    2,4,8"), each in low..high; a clear usage error otherwise."""
    try:
        values = tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise click.UsageError(f"{option} {text!r}: expected {what}") from None
    if not values or any(n < low or n > high for n in values):
        raise click.UsageError(f"{option} {text!r}: give {what.split(' like ')[0]} between {low} and {high}")
    return values


def parse_team_sizes(text: str) -> tuple[int, ...]:
    """``--robots 2,4,8`` as team sizes; a clear usage error otherwise."""
    return parse_whole_numbers(text, "--robots", "team sizes like 2,4,8", 1, 64)


def _trained_model_path(model_path):
    """``model_path``, else the default model's file (trained and cached on first use):
    the experiments' worker processes load the model from a file."""
    if model_path is not None:
        return model_path
    from .default_model import default_model, default_model_path  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

    default_model()
    return default_model_path()


def run_tracking_experiment_cmd(out_dir, seeds: int, sizes: tuple[int, ...], duration: float, model_path, workers,
                                quiet: bool, first_seed: int = 1) -> None:
    """``cekm experiment tracking`` once its options are checked."""
    from .tracking_report import table_markdown, write_experiment  # noqa: PLC0415 -- lazy: pymunk, world
    from .tracking_run import run_experiment  # noqa: PLC0415 -- lazy: pymunk, world

    model_path = _trained_model_path(model_path)
    t0 = time.perf_counter()
    doc, pictures = run_experiment(sizes, seeds, duration, model_path, workers, progress=not quiet,
                                   first_seed=first_seed)
    doc["wall_seconds"] = round(time.perf_counter() - t0, 1)
    paths = write_experiment(doc, pictures, out_dir)
    click.echo(table_markdown(doc))
    click.echo(f"{doc['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in paths))


def parse_cekm_params(items: tuple[str, ...]) -> dict[str, Any]:
    """``--param NAME=VALUE`` (repeatable): overrides of cekm's TrackingParams, typed by the
    field (a number, an integer, or true/false) and checked by TrackingParams itself; a
    ParameterError names the option and the field."""

    hints = typing.get_type_hints(TrackingParams)
    names = [f.name for f in dataclasses.fields(TrackingParams)]
    out: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name, text = name.strip(), text.strip()
        if not sep or not name or not text:
            raise ParameterError(f"--param {item!r}: expected NAME=VALUE, e.g. assign_lead_s=0.5")
        if name not in hints:
            raise ParameterError(f"--param {name!r}: cekm's TrackingParams has no such field; "
                                 f"one of {', '.join(names)}")
        kind = hints[name]
        try:
            if kind is bool:
                if text.lower() not in ("true", "false"):
                    raise ValueError
                value: Any = text.lower() == "true"
            elif kind is int:
                value = int(text)
            else:
                value = float(text)
        except ValueError:
            raise ParameterError(f"--param {name}: expected {'true or false' if kind is bool else kind.__name__}, "
                                 f"got {text!r}") from None
        if name in out:
            raise ParameterError(f"--param {name}: given twice")
        out[name] = value
    try:
        TrackingParams(**out)  # its own checks, naming the field
    except ParameterError as exc:
        raise ParameterError(f"--param: {exc}") from None
    return out


def run_grid_cmd(out_dir, quick: bool, seeds: list[int], duration: float, model_path, workers, quiet: bool,
                 cekm_params: dict[str, Any] | None = None) -> None:
    """``cekm experiment tracking --grid`` once its options are checked; ``cekm_params``:
    overrides of cekm's TrackingParams (``--param``), recorded in results.json."""
    from .grid_report import grid_doc, summary, tables_markdown, write_grid  # noqa: PLC0415 -- lazy: numba, pymunk, scipy, world

    model_path = _trained_model_path(model_path)
    tparams = TrackingParams(**cekm_params) if cekm_params else None
    doc = grid_doc(quick, seeds, duration, model_path, workers, progress=not quiet, tparams=tparams, out_dir=out_dir)
    doc["cekm_params"] = dict(cekm_params or {})
    paths = write_grid(doc, out_dir)
    click.echo(tables_markdown(doc).split("\n\n")[1])
    click.echo(summary(doc) + f"; {doc['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in paths))


def run_tracking_power_cmd(results: Path, seeds: tuple[int, ...], reps: int) -> None:
    """``cekm experiment tracking-power``: the bootstrap of a grid's results.json, printed."""
    from .grid_power import power_markdown, seeds_power  # noqa: PLC0415 -- lazy: pymunk, world

    try:
        doc = json.loads(Path(results).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ResultsFileError(f"{results}: not a readable JSON file ({exc})") from None
    if not isinstance(doc, dict):
        raise ResultsFileError(f"{results}: expected a JSON object (a tracking grid's results.json)")
    click.echo(power_markdown(seeds_power(doc, seeds, reps, source=str(results)), str(results)))


def parse_floats(text: str, name: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise ParameterError(f"--{name}: expected comma-separated numbers in metres, got {text!r}") from None
    if not values:
        raise ParameterError(f"--{name}: give at least one value")
    return values


def seeds_of(text: str) -> Sequence[int]:
    """Seeds from "1,2,5" or ranges "1-20" (inclusive), mixed: "1-5,9"; each seed once (the
    runs' statistics take the seeds as independent), every range with both ends."""
    out: list[int] = []
    for part in (v.strip() for v in text.split(",")):
        if not part:
            continue
        a, dash, b = part.partition("-")
        if dash and not b.strip():
            raise ParameterError(f"--seeds: range {part!r} has no end (e.g. 1-20)")
        try:
            lo, hi = int(a), int(b if dash else a)
        except ValueError:
            raise ParameterError(f"--seeds: expected comma-separated integers or ranges like 1-20, "
                                 f"got {text!r}") from None
        if hi < lo:
            raise ParameterError(f"--seeds: range {part!r} runs backwards")
        out.extend(range(lo, hi + 1))
    if len(set(out)) < len(out):
        twice = sorted(s for s, n in Counter(out).items() if n > 1)
        shown = ", ".join(map(str, twice[:5])) + (", ..." if len(twice) > 5 else "")
        raise ParameterError(f"--seeds: {'seed' if len(twice) == 1 else 'seeds'} {shown} given twice in {text!r} "
                             f"(each seed is one independent run)")
    return tuple(out)


def run_and_report(config: TargetReachingConfig, out_dir: Path, master_seeds: int = 1, progress: bool = True,
                   echo: Callable[[str], None] = print, workers: int | None = None) -> None:
    """``cekm experiment target-reaching``: one master seed into out_dir (with the trained
    models), or several, each into out_dir/seed-S, and their summary into out_dir."""
    from .reaching_run import run_experiment, run_master_seeds  # noqa: PLC0415 -- lazy: numba, scipy, tqdm
    from .reaching_stats import headline_orderings  # noqa: PLC0415 -- lazy: numba, scipy

    out_dir = Path(out_dir)
    if master_seeds == 1:
        results, runs = run_experiment(config, progress=progress)
        written = write_seed(config, results, runs, out_dir, models=True)
        echo((out_dir / "tables.md").read_text().split("### Table 2")[0].rstrip())
        echo("")
        for claim, holds in headline_orderings(results).items():
            echo(f"  {'holds' if holds else 'DOES NOT HOLD'}: {claim}")
        echo(f"\n{results['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in written))
        return

    def on_seed(seed: int, results: dict, runs: list[NetworkRun]) -> None:
        write_seed(dataclasses.replace(config, seed=seed), results, runs, out_dir / f"seed-{seed}", models=False)
        holds = sum(bool(v) for v in headline_orderings(results).values())
        echo(f"master seed {seed}: {results['wall_seconds']:.1f} s, {holds} of {len(headline_orderings(results))} "
             f"headline orderings hold; wrote {out_dir / f'seed-{seed}'}")

    summary, _ = run_master_seeds(config, master_seeds, progress, on_seed, workers)
    written = write_seeds_report(summary, out_dir)
    echo("")
    echo(written[1].read_text().rstrip())
    echo(f"\n{summary['wall_seconds']:.1f} s; wrote " + ", ".join(str(p) for p in written))


def run_circling_cmd(out_dir: Path, **settings) -> None:
    """``cekm experiment circling``: one episode drawn, and what drove it printed."""
    from .circling import run_circling  # noqa: PLC0415 -- lazy: numba, scipy, tqdm
    from .streams import Schedule  # noqa: PLC0415 -- lazy: numba, scipy

    schedule = Schedule()  # circling trains and tests by the paper's schedule but for its steps
    target, steps = settings.get("target"), settings.get("steps", schedule.steps)
    if target is not None and not 1 <= target <= schedule.test_targets:  # checked before the training, not after
        raise click.BadParameter(f"{target}: a test target from 1 to {schedule.test_targets}", param_hint="'--target'")
    if steps % schedule.test_interval:  # circling has no --test-interval: name only --steps
        raise click.BadParameter(f"{steps}: training steps must be a multiple of {schedule.test_interval:,}",
                                 param_hint="'--steps'")
    found = run_circling(out_dir, **settings)
    if found is None:
        raise click.ClickException(f"{settings['network']} seed {settings['seed']} trial {settings['trial']}: "
                                   f"no test target ended by the budget (give --target or --pick farthest-stop)")
    e = found.summary["episode"]
    click.echo(f"{found.title}\n  targets ended by the budget: {found.summary['targets_ended_by_budget']}; this one: "
               f"{e['steps']} steps, closest {e['closest_mm']:.2f} mm, final {e['final_distance_mm']:.2f} mm")
    for w in e["winners"][:4]:
        click.echo(f"  neuron {w['neuron']} (alpha {w['w_alpha_rad']:+.2f} rad, d {w['w_d_mm']:.1f} mm): {w['steps']} "
                   f"steps, command {w['command_mm_s_mean']} mm/s, exact {w['kinematic_mm_s_mean']}, executed "
                   f"{w['executed_mm_s_mean']}")
    if e["sensed_alpha_error_rad_within_5_mm"]:
        click.echo(f"  sensed alpha within 5 mm of the target: median error "
                   f"{e['sensed_alpha_error_rad_within_5_mm']['median']:.3f} rad")
    click.echo(f"  wrote {found.png}, {found.json}")
