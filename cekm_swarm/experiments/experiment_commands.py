"""``cekm experiment``: the paper's experiments (section 4.1's target reaching and its
circling episodes, section 4.2's obstacles, Fig. 13's tracking) and the project's own
(learning curves, the tracking grid and its power), with the options they declare once.

A command imports its run lazily (numba, scipy, matplotlib), so ``cekm --help`` stays fast.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import click

from ..cli_support import (
    SEED,
    F,
    Finite,
    check_seeds,
    out_dir_options,
    out_file_option,
    prepare_figure_file,
    prepare_out_dir,
    prepare_out_file,
    quiet_option,
    seed_option,
)
from ..errors import CekmError
from ..models.networks import parse_network_name
from .commands import (
    engine_options,
    fields_option,
    load_scenario_file,
    parse_cekm_params,
    parse_team_sizes,
    parse_whole_numbers,
    run_and_report,
    run_circling_cmd,
    run_grid_cmd,
    run_tracking_experiment_cmd,
    run_tracking_power_cmd,
    seeds_of,
    seeds_option,
)
from .field_widths import REPRODUCTION
from .learning_commands import controller_model, learning_experiment_cmd, model_option
from .navigation_figures import plot_fields
from .navigation_run import fields_at
from .obstacle_report import summary_markdown, write_suite
from .obstacle_run import run_suite

MIN_SPEED_UNIT = 1e-6
"""The smallest positive wheel speed unit (m/s) a command takes for the plant."""

MASTER_SEED = 2005
"""The master seed section 4.1's runs take by default."""


def networks_of(value: str, option: str = "--networks") -> tuple[str, ...]:
    """The network names of a comma-separated ``value`` (e.g. ``R15,G9``), each checked;
    a usage error naming ``option`` otherwise."""
    names = tuple(n.strip().upper() for n in value.split(",") if n.strip())
    if not names:
        raise click.BadParameter("give at least one network, e.g. R15", param_hint=f"'{option}'")
    for n in names:
        try:
            parse_network_name(n)
        except CekmError as exc:
            raise click.BadParameter(str(exc), param_hint=f"'{option}'") from None
    return names


network_option = click.option("--network", default="R15", show_default=True,
                              help="The network, e.g. R15, G9, D15, B15.")
"""``--network``: one network (checked by :func:`networks_of`)."""


def master_seed_option(help_text: str = "Master seed.") -> Callable[[F], F]:
    """``--seed`` of section 4.1's runs: the master seed, 2005 unless given."""
    return seed_option(MASTER_SEED, help_text)


def reaching_options(f: F) -> F:
    """The rules of a section 4.1 run that ``target-reaching`` and ``circling`` share: the stop
    rules, the motor's resolution, B15's rule and the plant's quantization."""
    for option in reversed([
        click.option("--stop", "stop_rule", type=click.Choice(["command", "goal"]), default="command",
                     show_default=True,
                     help="When a test target ends: 'command', the paper's (the network's own command is 0 at the "
                          "motor's resolution); 'goal', the project's earlier rule (every network stops at the goal "
                          "state, the sensed distance rounding to 0)."),
        click.option("--train-stop", type=click.Choice(["goal", "command"]), default="goal", show_default=True,
                     help="When a training target ends (the same two rules)."),
        click.option("--motor-resolution", type=Finite(min=0.0, min_open=True, max=0.15), default=0.008,
                     show_default=True,
                     help="The motor's resolution for the 'command' rule (m/s): a command under half of it on both "
                          "wheels is a stop. The Khepera's speed unit is 0.008 (one encoder pulse per 10 ms)."),
        click.option("--bfn", "bfn_rule", type=click.Choice(["paper", "trained-units"]), default="paper",
                     show_default=True,
                     help="B15's rule: 'paper', every unit drives the output and widths approach the nearest "
                          "centre's distance; 'trained-units', only units whose centre has won drive it (the "
                          "project's earlier B15)."),
        click.option("--speed-unit", type=Finite(min=0.0), default=0.0, show_default=True,
                     help="Wheel speeds execute as whole multiples of this (m/s); 0: continuous. The Khepera's is "
                          "0.008."),
        click.option("--target-resolution", type=Finite(min=0.0, max=0.1, max_open=True), default=0.001,
                     show_default=True, help="The target sensor rounds distances to this (m); 0: not rounded."),
    ]):
        f = option(f)
    return f


@click.group("experiment")
def experiment_group() -> None:
    """Reproduce the paper's experiments."""


@experiment_group.command("target-reaching")
@out_dir_options("Directory for results.json, tables.md and the figures.")
@click.option("--networks", default="B15,D15,G9,G12,G15,R15", show_default=True,
              help="Comma-separated networks: B (basis functions), D (direct EKM), G (indirect EKM, gradient "
                   "descent), R (indirect EKM, recursive least squares) and the lattice side.")
@click.option("--trials", default=5, show_default=True, type=click.IntRange(1, 1000))
@click.option("--steps", default=100_000, show_default=True, type=click.IntRange(1))
@click.option("--test-interval", default=10_000, show_default=True, type=click.IntRange(1))
@click.option("--targets", "test_targets", default=50, show_default=True, type=click.IntRange(1),
              help="Test targets per test.")
@master_seed_option("Master seed (the first, with --master-seeds).")
@click.option("--master-seeds", default=1, show_default=True, type=click.IntRange(1, 100),
              help="Run K independent master seeds (seed, seed+1, ...): each into OUT/seed-S, and OUT/summary.md "
                   "with 95 % intervals and how often each headline ordering holds.")
@reaching_options
@quiet_option
@engine_options
def target_reaching(out_dir: Path, overwrite: bool, networks: str, trials: int, steps: int, test_interval: int,
                    test_targets: int, seed: int, master_seeds: int, stop_rule: str, train_stop: str,
                    motor_resolution: float, bfn_rule: str, speed_unit: float, target_resolution: float,
                    quiet: bool, workers: int | None) -> None:
    """Reproduce section 4.1: Tables 1-4 and Figures 5-7 (obstacle-free target reaching)."""
    from .arena import Arena  # noqa: PLC0415 -- lazy: numba and scipy, not at cekm --help
    from .reaching_config import TargetReachingConfig  # noqa: PLC0415 -- lazy: numba and scipy
    from .stopping import StopRule  # noqa: PLC0415 -- lazy: numba and scipy
    from .streams import Schedule  # noqa: PLC0415 -- lazy: numba and scipy

    if steps % test_interval:
        raise click.UsageError(f"--steps ({steps}) must be a multiple of --test-interval ({test_interval})")
    last = seed + master_seeds - 1  # the seeds run are seed .. seed + K - 1, each a seed
    if SEED.max is not None and last > SEED.max:
        raise click.BadParameter(f"{seed} with --master-seeds {master_seeds} runs seeds up to {last}, "
                                 f"past {SEED.max}", param_hint="'--seed'")
    try:
        arena = Arena(speed_unit=speed_unit, target_resolution=target_resolution)
        schedule = Schedule(steps=steps, test_interval=test_interval, test_targets=test_targets)
        config = TargetReachingConfig(networks=networks_of(networks), trials=trials, seed=seed, arena=arena,
                                      stop=StopRule(stop_rule, motor_resolution),
                                      train_stop=StopRule(train_stop, motor_resolution), bfn_rule=bfn_rule,
                                      schedule=schedule)
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    prepare_out_dir(out_dir, overwrite)
    run_and_report(config, out_dir, master_seeds, progress=not quiet, echo=click.echo, workers=workers)


@experiment_group.command("circling")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory for the episode's PNG and JSON (other episodes' files there are kept).")
@network_option
@master_seed_option()
@click.option("--trial", default=1, show_default=True, type=click.IntRange(1), help="Trial, from 1.")
@click.option("--target", type=click.IntRange(1), default=None,
              help="Test target, from 1 (default: chosen by --pick).")
@click.option("--pick", type=click.Choice(["budget", "farthest-stop"]), default="budget", show_default=True,
              help="Without --target: the first target ended by the budget, or the one that stopped farthest away.")
@reaching_options
@click.option("--steps", default=100_000, show_default=True, type=click.IntRange(10_000),
              help="Training steps (a multiple of 10,000).")
def circling(out_dir: Path, network: str, seed: int, trial: int, target: int | None, pick: str, stop_rule: str,
             train_stop: str, motor_resolution: float, bfn_rule: str, speed_unit: float, target_resolution: float,
             steps: int) -> None:
    """Why a robot circles a target instead of stopping: one test episode of section 4.1,
    step by step (its path, the winners and their commands beside the exact ones)."""
    run_circling_cmd(out_dir, network=networks_of(network, "--network")[0], seed=seed, trial=trial, target=target,
                     pick=pick, stop_rule=stop_rule, train_stop=train_stop, motor_resolution=motor_resolution,
                     speed_unit=speed_unit, target_resolution=target_resolution, bfn=bfn_rule, steps=steps)


@experiment_group.command("obstacles")
@seeds_option("1-20")
@click.option("--speed-unit", type=Finite(min=0.0, max=0.05),
              help="Wheel speed unit of the plant (m/s) for every run, 0 = continuous (default: each scenario's).")
@click.option("--max-time", default=300.0, show_default=True, type=Finite(min=1.0),
              help="Sim seconds before a robot counts as trapped.")
@fields_option(REPRODUCTION, "the paper's method has constant ones")
@model_option()
@engine_options
@out_dir_options("Directory for outcomes.json and the figures.")
def obstacles(seeds: str, speed_unit: float | None, max_time: float, fields: str, model_path: Path | None,
              workers: int | None, out_dir: Path, overwrite: bool) -> None:
    """Reproduce section 4.2 (Figs. 8, 10-12): cooperative EKMs and command fusion over seeds."""
    from .default_model import default_model, default_model_path  # noqa: PLC0415 -- lazy: numba and scipy

    try:
        seed_list = tuple(seeds_of(seeds))
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    if not seed_list:
        raise click.UsageError("--seeds: give at least one seed")
    check_seeds(seed_list)
    if speed_unit is not None and 0.0 < speed_unit < MIN_SPEED_UNIT:
        # the plant divides its top speed by the unit: a denormal unit overflowed in every worker
        raise click.BadParameter(f"{speed_unit!r}: give 0 (continuous) or at least {MIN_SPEED_UNIT} m/s",
                                 param_hint="'--speed-unit'")
    controller_model(model_path)
    prepare_out_dir(out_dir, overwrite)
    if model_path is None:
        default_model()
        model_path = default_model_path()
    doc, pictures = run_suite(seed_list, model_path, max_time, workers, speed_unit=speed_unit, fields=fields)
    paths = write_suite(doc, pictures, out_dir)
    click.echo(summary_markdown(doc))
    click.echo("wrote " + ", ".join(str(p) for p in paths))


@experiment_group.command("tracking")
@out_dir_options("Directory for results.json, tables.md and the figures.")
@click.option("--seeds", type=click.IntRange(2, 1000), help="N seeds per team size, from --first-seed (default 10; "
              "--grid: 10 per cell, --quick 2).")
@click.option("--robots", default="2,4,8", show_default=True, help="Team sizes, comma-separated.")
@click.option("--duration", type=Finite(min=1.0), help="Sim seconds per run (default 60; --grid --quick 8).")
@model_option()
@engine_options
@quiet_option
@click.option("--grid", is_flag=True, help="The scenario grid instead (team size, targets per robot, target speed, "
              "sensing range, obstacles; docs/tracking.md): results.json, tables.md, grid.png.")
@click.option("--quick", is_flag=True, help="With --grid: a small grid (CI).")
@click.option("--reference", is_flag=True, help="With --grid: the reference grid, 40 seeds x 120 s a cell (about 60 "
              "minutes on 2 cores; the default, 10 x 60 s, is the quick look).")
@click.option("--first-seed", default=1, show_default=True, type=click.IntRange(0),
              help="Seeds first-seed .. first-seed + N - 1 (the grid's default held-out 1-10; its tuning used "
                   "1001-1099).")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE",
              help="With --grid: one of cekm's TrackingParams for this run (repeatable), e.g. assign_lead_s=0.5; "
                   "recorded in results.json. How the defaults were tuned (docs/tracking.md).")
def tracking_experiment(out_dir: Path, overwrite: bool, seeds: int | None, robots: str, duration: float | None,
                        model_path: Path | None, workers: int | None, quiet: bool, grid: bool, quick: bool,
                        first_seed: int, params: tuple[str, ...], reference: bool = False) -> None:
    """Multi-robot tracking (Fig. 13): cooperative EKMs, A-CMOMMT, K-means (local and global) and static robots
    on the same seeds; with --grid, over the scenario grid."""
    if (quick or reference) and not grid:
        raise click.UsageError(f"{'--quick' if quick else '--reference'} goes with --grid")
    if params and not grid:
        raise click.UsageError("--param goes with --grid")
    controller_model(model_path)
    if grid:
        from .grid_report import grid_size  # noqa: PLC0415 -- lazy: numba and scipy

        cekm_params = parse_cekm_params(params)  # before anything is written
        try:
            n, run_s = grid_size(quick, reference, seeds, duration)
        except ValueError as exc:
            raise click.UsageError(str(exc)) from None
        prepare_out_dir(out_dir, overwrite)
        run_grid_cmd(out_dir, quick, list(range(first_seed, first_seed + n)), run_s, model_path, workers,
                     quiet, cekm_params)
        return
    sizes = parse_team_sizes(robots)
    prepare_out_dir(out_dir, overwrite)
    run_tracking_experiment_cmd(out_dir, seeds if seeds is not None else 10, sizes,
                                duration if duration is not None else 60.0, model_path, workers, quiet, first_seed)


@experiment_group.command("tracking-power")
@click.argument("results", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--seeds", default="10,15,20,30,40,60", show_default=True, help="The seed counts a cell to estimate.")
@click.option("--reps", default=1000, show_default=True, type=click.IntRange(1), help="Bootstrap replicates per count.")
def tracking_power(results: Path, seeds: str, reps: int) -> None:
    """How many seeds a cell the tracking grid needs: a bootstrap of a grid's RESULTS (its results.json) at
    other seed counts, by the acceptance's bar (above both baselines, and Welch-significant against each)."""
    run_tracking_power_cmd(results, parse_whole_numbers(seeds, "--seeds", "seed counts like 10,20,40", 2, 100_000),
                           reps)


experiment_group.add_command(learning_experiment_cmd)  # docs/learning.md


@click.command("train")
@network_option
@click.option("--steps", default=100_000, show_default=True, type=click.IntRange(1))
@master_seed_option()
@out_file_option("The .npz model file to write (replaced if it exists).")
@quiet_option
def train_cmd(network: str, steps: int, seed: int, out_path: Path, quiet: bool) -> None:
    """Train one network by self-organized learning in the obstacle-free arena and save it."""
    from ..models.io import save_model  # noqa: PLC0415 -- lazy: not at cekm --help
    from .training import train_network  # noqa: PLC0415 -- lazy: numba and scipy, not at cekm --help

    (name,) = networks_of(network, "--network")
    prepare_out_file(out_path)
    t0 = time.perf_counter()
    net, score = train_network(name, steps, seed, progress=not quiet)
    save_model(out_path, net, {"network": name, "steps": steps, "seed": seed, "initial_M": "random",
                               "test_after_training": score})
    click.echo(f"{name}: {steps:,} steps in {time.perf_counter() - t0:.1f} s; test after training: "
               f"E {score['E_mm']:.2f} mm, T {score['T_s_per_m']:.1f} s/m, D {score['D']:.3f}, "
               f"P(5) {score['P5']:.2f}; saved {out_path}")


@click.command("fields")
@click.argument("scenario")
@click.option("--at", "at_time", type=Finite(0.0, 600.0), required=True,
              help="Sim time (s) of the snapshot, at most 600 (the longest run).")
@model_option()
@seed_option()
@click.option("--robot", help="Robot id (default: the first).")
@fields_option(None, "default: cekm's own (learned for navigation; Fig. 4 is the paper's method: --fields tuned)")
@out_file_option("The PNG to write (replaced if it exists).")
def fields_cmd(scenario: str, at_time: float, model_path: Path | None, seed: int | None, robot: str | None,
               fields: str | None, out_path: Path) -> None:
    """Draw the activity maps of the paper's Fig 4 at sim time --at.

    The target field, three obstacle fields, the combined obstacle fields and the
    integrated activity of the cooperative EKM, with the robot's situation.
    """
    from world.tracking import is_tracking  # noqa: PLC0415 -- lazy: pymunk, not at cekm --help

    sc = load_scenario_file(scenario)
    if is_tracking(sc):
        raise click.UsageError(f"cekm fields draws a navigation controller's fields; tracking is not supported: "
                               f"{sc.name} is a tracking scenario (its robots have no goal)")
    robots = [r.id for r in sc.robots]
    if robot is not None and robot not in robots:
        raise click.BadParameter(f"{sc.name} has no robot {robot!r} (robots: {', '.join(robots)})",
                                 param_hint="'--robot'")
    prepare_figure_file(out_path)  # before the model, which may first be trained
    model = controller_model(model_path)
    f = fields_at(sc, model, at_time, seed, robot, fields)
    plot_fields(f).savefig(out_path, dpi=110)
    x, y, th = f["pose"]
    k = f["k"]
    motor = "none (the robot stops)" if k is None else f"{k} at w = ({f['w'][k, 0]:.2f} rad, {f['w'][k, 1]:.3f} m)"
    click.echo(f"t = {f['time']:.3f} s, {f['robot']} at ({x:.3f}, {y:.3f}, {th:.2f} rad): target winner "
               f"{f['s']}, motor winner {motor}, command ({f['command'][0]:.3f}, {f['command'][1]:.3f}) m/s; "
               f"wrote {out_path}")
