"""The ``cekm`` command line."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from .cli_support import (
    SEED,
    FileRefused,
    Finite,
    ScenarioFileError,
    check_seeds,
    out_dir_options,
    prepare_figure_file,
    prepare_out_dir,
    prepare_out_file,
    refuse_unplannable,
    run_cli,
)
from .errors import CekmError
from .experiments.commands import engine_options
from .experiments.learning_commands import MODEL_CHOICE, controller_model, learning_experiment_cmd
from .experiments.sweep_commands import sweep

MIN_SPEED_UNIT = 1e-6
"""The smallest positive wheel speed unit (m/s) a command takes for the plant."""


def _networks(value: str, option: str = "--networks") -> tuple[str, ...]:
    from .models.networks import parse_network_name

    names = tuple(n.strip().upper() for n in value.split(",") if n.strip())
    if not names:
        raise click.BadParameter("give at least one network, e.g. R15", param_hint=f"'{option}'")
    for n in names:
        try:
            parse_network_name(n)
        except CekmError as exc:
            raise click.BadParameter(str(exc), param_hint=f"'{option}'") from None
    return names


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="cekm-swarm")
def main() -> None:
    """Cooperative Extended Kohonen Maps: models, the paper's experiments, a multi-robot runtime."""


@main.group()
def experiment() -> None:
    """Reproduce the paper's experiments."""


experiment.add_command(learning_experiment_cmd)  # docs/learning.md


@experiment.command("target-reaching")
@out_dir_options("Directory for results.json, tables.md and the figures.")
@click.option("--networks", default="B15,D15,G9,G12,G15,R15", show_default=True,
              help="Comma-separated networks: B (basis functions), D (direct EKM), G (indirect EKM, gradient "
                   "descent), R (indirect EKM, recursive least squares) and the lattice side.")
@click.option("--trials", default=5, show_default=True, type=click.IntRange(1, 1000))
@click.option("--steps", default=100_000, show_default=True, type=click.IntRange(1))
@click.option("--test-interval", default=10_000, show_default=True, type=click.IntRange(1))
@click.option("--targets", "test_targets", default=50, show_default=True, type=click.IntRange(1),
              help="Test targets per test.")
@click.option("--seed", default=2005, show_default=True, type=SEED, help="Master seed (the first, with --master-seeds).")
@click.option("--master-seeds", default=1, show_default=True, type=click.IntRange(1, 100),
              help="Run K independent master seeds (seed, seed+1, ...): each into OUT/seed-S, and OUT/summary.md "
                   "with 95 % intervals and how often each headline ordering holds.")
@click.option("--stop", "stop_rule", type=click.Choice(["command", "goal"]), default="command", show_default=True,
              help="When a test target ends: 'command', the paper's (the network's own command is 0 at the motor's "
                   "resolution); 'goal', the project's earlier rule (every network stops at the goal state, the "
                   "sensed distance rounding to 0).")
@click.option("--train-stop", type=click.Choice(["goal", "command"]), default="goal", show_default=True,
              help="When a training target ends (the same two rules).")
@click.option("--motor-resolution", type=Finite(min=0.0, min_open=True, max=0.15), default=0.008,
              show_default=True, help="The motor's resolution for the 'command' rule (m/s): a command under half of it "
                                      "on both wheels is a stop. The Khepera's speed unit is 0.008 (one encoder pulse "
                                      "per 10 ms).")
@click.option("--bfn", "bfn_rule", type=click.Choice(["paper", "trained-units"]), default="paper", show_default=True,
              help="B15's rule: 'paper', every unit drives the output and widths approach the nearest centre's "
                   "distance; 'trained-units', only units whose centre has won drive it (the project's earlier B15).")
@click.option("--speed-unit", type=Finite(min=0.0), default=0.0, show_default=True,
              help="Wheel speeds execute as whole multiples of this (m/s); 0: continuous. The Khepera's is 0.008.")
@click.option("--target-resolution", type=Finite(min=0.0, max=0.1, max_open=True), default=0.001,
              show_default=True, help="The target sensor rounds distances to this (m); 0: not rounded.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@engine_options
def target_reaching(out_dir: Path, overwrite: bool, networks: str, trials: int, steps: int, test_interval: int,
                    test_targets: int, seed: int, master_seeds: int, stop_rule: str, train_stop: str,
                    motor_resolution: float,
                    bfn_rule: str, speed_unit: float, target_resolution: float, quiet: bool, workers: int | None) -> None:
    """Reproduce section 4.1: Tables 1-4 and Figures 5-7 (obstacle-free target reaching)."""
    from .experiments.arena import Arena
    from .experiments.commands import run_and_report
    from .experiments.reaching_run import TargetReachingConfig
    from .experiments.stopping import StopRule
    from .experiments.streams import Schedule

    if steps % test_interval:
        raise click.UsageError(f"--steps ({steps}) must be a multiple of --test-interval ({test_interval})")
    if seed + master_seeds - 1 > SEED.max:  # the seeds run are seed .. seed + K - 1, each a seed
        raise click.BadParameter(f"{seed} with --master-seeds {master_seeds} runs seeds up to {seed + master_seeds - 1}"
                                 f", past {SEED.max}", param_hint="'--seed'")
    try:
        arena = Arena(speed_unit=speed_unit, target_resolution=target_resolution)
        config = TargetReachingConfig(networks=_networks(networks), trials=trials, seed=seed, arena=arena,
                                      stop=StopRule(stop_rule, motor_resolution),
                                      train_stop=StopRule(train_stop, motor_resolution), bfn_rule=bfn_rule,
                                      schedule=Schedule(steps=steps, test_interval=test_interval, test_targets=test_targets))
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    prepare_out_dir(out_dir, overwrite)
    run_and_report(config, out_dir, master_seeds, progress=not quiet, echo=click.echo, workers=workers)


@experiment.command("circling")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Directory for the episode's PNG and JSON (other episodes' files there are kept).")
@click.option("--network", default="R15", show_default=True, help="The network, e.g. R15, G9, D15, B15.")
@click.option("--seed", default=2005, show_default=True, type=SEED, help="Master seed.")
@click.option("--trial", default=1, show_default=True, type=click.IntRange(1), help="Trial, from 1.")
@click.option("--target", type=click.IntRange(1), default=None,
              help="Test target, from 1 (default: chosen by --pick).")
@click.option("--pick", type=click.Choice(["budget", "farthest-stop"]), default="budget", show_default=True,
              help="Without --target: the first target ended by the budget, or the one that stopped farthest away.")
@click.option("--stop", "stop_rule", type=click.Choice(["command", "goal"]), default="command", show_default=True,
              help="The test's stop rule (as in target-reaching).")
@click.option("--train-stop", type=click.Choice(["goal", "command"]), default="goal", show_default=True,
              help="Training's stop rule.")
@click.option("--motor-resolution", type=Finite(min=0.0, min_open=True, max=0.15), default=0.008,
              show_default=True, help="The motor's resolution for the 'command' rule (m/s).")
@click.option("--speed-unit", type=Finite(min=0.0), default=0.0, show_default=True,
              help="Wheel speeds execute as whole multiples of this (m/s); 0: continuous.")
@click.option("--target-resolution", type=Finite(min=0.0, max=0.1, max_open=True), default=0.001,
              show_default=True, help="The target sensor rounds distances to this (m); 0: not rounded.")
@click.option("--bfn", "bfn_rule", type=click.Choice(["paper", "trained-units"]), default="paper", show_default=True,
              help="B15's rule (as in target-reaching).")
@click.option("--steps", default=100_000, show_default=True, type=click.IntRange(10_000),
              help="Training steps (a multiple of 10,000).")
def circling(out_dir: Path, network: str, seed: int, trial: int, target: int | None, pick: str, stop_rule: str,
             train_stop: str, motor_resolution: float, speed_unit: float, target_resolution: float, bfn_rule: str,
             steps: int) -> None:
    """Why a robot circles a target instead of stopping: one test episode of section 4.1,
    step by step (its path, the winners and their commands beside the exact ones)."""
    from .experiments.commands import run_circling_cmd

    run_circling_cmd(out_dir, network=_networks(network, "--network")[0], seed=seed, trial=trial, target=target,
                     pick=pick,
                     stop_rule=stop_rule, train_stop=train_stop, motor_resolution=motor_resolution,
                     speed_unit=speed_unit, target_resolution=target_resolution, bfn=bfn_rule, steps=steps)


@experiment.command("obstacles")
@click.option("--seeds", default="1-20", show_default=True, help="Seeds: a list and/or ranges, e.g. 1-20 or 1,2,7.")
@click.option("--speed-unit", type=Finite(min=0.0, max=0.05),
              help="Wheel speed unit of the plant (m/s) for every run, 0 = continuous (default: each scenario's).")
@click.option("--max-time", default=300.0, show_default=True, type=Finite(min=1.0),
              help="Sim seconds before a robot counts as trapped.")
@click.option("--model", "model_path", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@engine_options
@out_dir_options("Directory for outcomes.json and the figures.")
def obstacles(seeds: str, speed_unit: float | None, max_time: float, model_path: Path | None, workers: int | None,
              out_dir: Path, overwrite: bool) -> None:
    """Reproduce section 4.2 (Figs. 8, 10-12): cooperative EKMs and command fusion over seeds."""
    from .experiments.commands import seeds_of
    from .experiments.default_model import default_model, default_model_path
    from .experiments.obstacle_report import summary_markdown, write_suite
    from .experiments.obstacle_run import run_suite

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
    doc, pictures = run_suite(seed_list, model_path, max_time, workers, speed_unit=speed_unit)
    paths = write_suite(doc, pictures, out_dir)
    click.echo(summary_markdown(doc))
    click.echo("wrote " + ", ".join(str(p) for p in paths))


@experiment.command("tracking")
@out_dir_options("Directory for results.json, tables.md and the figures.")
@click.option("--seeds", type=click.IntRange(2, 1000), help="N seeds per team size, from --first-seed (default 10; "
              "--grid: 10 per cell, --quick 2).")
@click.option("--robots", default="2,4,8", show_default=True, help="Team sizes, comma-separated.")
@click.option("--duration", type=Finite(min=1.0), help="Sim seconds per run (default 60; --grid --quick 8).")
@click.option("--model", "model_path", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@engine_options
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--grid", is_flag=True, help="The scenario grid instead (team size, targets per robot, target speed, "
              "sensing range, obstacles; docs/tracking.md): results.json, tables.md, grid.png.")
@click.option("--quick", is_flag=True, help="With --grid: a small grid (CI).")
@click.option("--first-seed", default=1, show_default=True, type=click.IntRange(0),
              help="Seeds first-seed .. first-seed + N - 1 (the grid's default held-out 1-10; its tuning used 1001-1099).")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE",
              help="With --grid: one of cekm's TrackingParams for this run (repeatable), e.g. assign_lead_s=0.5; "
                   "recorded in results.json. How the defaults were tuned (docs/tracking.md).")
def tracking_experiment(out_dir: Path, overwrite: bool, seeds: int | None, robots: str, duration: float | None,
                        model_path: Path | None, workers: int | None, quiet: bool, grid: bool, quick: bool,
                        first_seed: int, params: tuple[str, ...]) -> None:
    """Multi-robot tracking (Fig. 13): cooperative EKMs, A-CMOMMT, K-means (local and global) and static robots
    on the same seeds; with --grid, over the scenario grid."""
    if quick and not grid:
        raise click.UsageError("--quick goes with --grid")
    if params and not grid:
        raise click.UsageError("--param goes with --grid")
    controller_model(model_path)
    if grid:
        from .experiments.commands import parse_cekm_params, run_grid_cmd
        from .experiments.grid_report import DEFAULT_DURATION, DEFAULT_SEEDS

        cekm_params = parse_cekm_params(params)  # before anything is written
        n = seeds if seeds is not None else (2 if quick else DEFAULT_SEEDS[1])
        prepare_out_dir(out_dir, overwrite)
        run_grid_cmd(out_dir, quick, list(range(first_seed, first_seed + n)),
                     duration if duration is not None else (8.0 if quick else DEFAULT_DURATION), model_path, workers,
                     quiet, cekm_params)
        return
    from .experiments.commands import parse_team_sizes, run_tracking_experiment_cmd

    sizes = parse_team_sizes(robots)
    prepare_out_dir(out_dir, overwrite)
    run_tracking_experiment_cmd(out_dir, seeds if seeds is not None else 10, sizes,
                                duration if duration is not None else 60.0, model_path, workers, quiet, first_seed)


@experiment.command("tracking-power")
@click.argument("results", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--seeds", default="10,15,20,30,40,60", show_default=True, help="The seed counts a cell to estimate.")
@click.option("--reps", default=1000, show_default=True, type=click.IntRange(1), help="Bootstrap replicates per count.")
def tracking_power(results: Path, seeds: str, reps: int) -> None:
    """How many seeds a cell the tracking grid needs: a bootstrap of a grid's RESULTS (its results.json) at
    other seed counts, by the acceptance's bar (above both baselines, and Welch-significant against each)."""
    from .experiments.commands import parse_whole_numbers, run_tracking_power_cmd

    run_tracking_power_cmd(results, parse_whole_numbers(seeds, "--seeds", "seed counts like 10,20,40", 2, 100_000),
                           reps)


@main.command()
@click.option("--network", default="R15", show_default=True, help="Network name, e.g. R15 or G12.")
@click.option("--steps", default=100_000, show_default=True, type=click.IntRange(1))
@click.option("--seed", default=2005, show_default=True, type=SEED)
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The .npz model file to write (replaced if it exists).")
@click.option("--quiet", is_flag=True)
def train(network: str, steps: int, seed: int, out_path: Path, quiet: bool) -> None:
    """Train one network by self-organized learning in the obstacle-free arena and save it."""
    from .experiments.training import train_network
    from .models.io import save_model

    (name,) = _networks(network, "--network")
    prepare_out_file(out_path)
    t0 = time.perf_counter()
    net, score = train_network(name, steps, seed, progress=not quiet)
    save_model(out_path, net, {"network": name, "steps": steps, "seed": seed, "initial_M": "random",
                               "test_after_training": score})
    click.echo(f"{name}: {steps:,} steps in {time.perf_counter() - t0:.1f} s; test after training: "
               f"E {score['E_mm']:.2f} mm, T {score['T_s_per_m']:.1f} s/m, D {score['D']:.3f}, "
               f"P(5) {score['P5']:.2f}; saved {out_path}")


def _load_scenario(name: str):
    from world import ScenarioError, load_scenario

    try:
        return load_scenario(name)
    except ScenarioError as exc:
        raise ScenarioFileError(str(exc)) from None


def _run_kind(scenario) -> str:
    """``"tracking"`` or ``"navigation"``; a usage error for a scenario that is neither."""
    from world import ScenarioError
    from world.tracking import run_kind

    try:
        return run_kind(scenario)
    except ScenarioError as exc:
        raise ScenarioFileError(str(exc)) from None


@main.command("run")
@click.argument("scenario")
@click.option("--controller", default="cekm", show_default=True, metavar="NAME",
              help="The controller whose graph runs (cekm graph list): cekm, fusion or stay for navigation; cekm, "
                   "acmommt, kmeans, kmeans-global or stay for tracking.")
@click.option("--graph", "graph_file", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Run a graph file of your own instead (docs/modules.md).")
@click.option("--model", "model_path", type=MODEL_CHOICE,
              help="A trained model (.npz from `cekm train`) or 'untrained'; default: R15 trained, cached.")
@click.option("--learn", is_flag=True, help="The robots' maps learn online as they move (docs/learning.md).")
@click.option("--seed", type=SEED, help="World seed (default: the scenario's).")
@click.option("--max-time", type=Finite(min=0.2),  # as cekm launch takes it, so every launch has its cekm run
              help="Sim seconds before a robot counts as trapped (default 600); for a tracking scenario, the "
                   "run's length (default 120).")
@click.option("--fields", type=click.Choice(["paper", "tuned", "learned"]), help="cekm's field widths: the paper's, "
              "today's hand-tuned (the default) or the learned field policy's (docs/fields.md).")
@out_dir_options("Directory for outcome.json and trajectory.png.")
def run_cmd(scenario: str, controller: str, graph_file: Path | None, model_path: Path | None, learn: bool,
            seed: int | None, max_time: float | None, fields: str | None, out_dir: Path, overwrite: bool) -> None:
    """Run SCENARIO (a name under world/scenarios or a .toml path) in one process, no Zenoh:
    the controller's graph, every node in this process, by the rule a lockstep launch
    follows (so `cekm launch --mode lockstep` gives the same run).

    A scenario with targets whose robots have no goal is a tracking scenario (Fig. 13)."""
    from .experiments.commands import run_navigation_cmd
    from .experiments.graph_run import default_max_time, resolve_graph, with_params
    from .experiments.learning_run import learning_controller, learning_params
    from .graph.spec import GraphError
    from .tune.graphs import with_fields

    sc = _load_scenario(scenario)
    task = _run_kind(sc)
    refuse_unplannable(sc)
    controller = learning_controller(controller, graph_file) if learn else controller
    try:
        checked = resolve_graph(controller, None if graph_file is None else str(graph_file), task)
        checked = with_fields(checked, fields, task)
        checked.plan([r.id for r in sc.robots], task)
    except GraphError as exc:
        raise FileRefused(str(exc)) from None
    checked = with_params(checked, learning_params(model_path) if learn else None)
    controller = checked.graph.controller
    model = controller_model(model_path) if checked.uses_model else None
    if task == "tracking":
        from .experiments.commands import run_tracking_cmd

        prepare_out_dir(out_dir, overwrite)
        run_tracking_cmd(sc, controller, model_path, seed, max_time, out_dir, graph=checked, model=model)
        return
    max_time = default_max_time(task) if max_time is None else max_time
    prepare_out_dir(out_dir, overwrite)
    run_navigation_cmd(sc, controller, model, seed, max_time, out_dir, graph=checked)


@main.command()
@click.argument("scenario")
@click.option("--at", "at_time", type=Finite(0.0, 600.0), required=True,
              help="Sim time (s) of the snapshot, at most 600 (the longest run).")
@click.option("--model", "model_path", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--seed", type=SEED, help="World seed (default: the scenario's).")
@click.option("--robot", help="Robot id (default: the first).")
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The PNG to write (replaced if it exists).")
def fields(scenario: str, at_time: float, model_path: Path | None, seed: int | None, robot: str | None,
           out_path: Path) -> None:
    """Draw the activity maps of the paper's Fig 4 at sim time --at.

    The target field, three obstacle fields, the combined obstacle fields and the
    integrated activity of the cooperative EKM, with the robot's situation.
    """
    from world.tracking import is_tracking

    from .experiments.navigation_figures import plot_fields
    from .experiments.navigation_run import fields_at

    sc = _load_scenario(scenario)
    if is_tracking(sc):
        raise click.UsageError(f"cekm fields draws a navigation controller's fields; tracking is not supported: "
                               f"{sc.name} is a tracking scenario (its robots have no goal)")
    robots = [r.id for r in sc.robots]
    if robot is not None and robot not in robots:
        raise click.BadParameter(f"{sc.name} has no robot {robot!r} (robots: {', '.join(robots)})",
                                 param_hint="'--robot'")
    prepare_figure_file(out_path)  # before the model, which may first be trained
    model = controller_model(model_path)
    f = fields_at(sc, model, at_time, seed, robot)
    plot_fields(f).savefig(out_path, dpi=110)
    x, y, th = f["pose"]
    k = f["k"]
    motor = "none (the robot stops)" if k is None else f"{k} at w = ({f['w'][k, 0]:.2f} rad, {f['w'][k, 1]:.3f} m)"
    click.echo(f"t = {f['time']:.3f} s, {f['robot']} at ({x:.3f}, {y:.3f}, {th:.2f} rad): target winner "
               f"{f['s']}, motor winner {motor}, command ({f['command'][0]:.3f}, {f['command'][1]:.3f}) m/s; "
               f"wrote {out_path}")


def _register_runtime_commands() -> None:
    from .runtime.commands import COMMANDS

    for command in COMMANDS:
        main.add_command(command)


_register_runtime_commands()


def _register_launch_commands() -> None:
    from .launch.commands import COMMANDS

    for command in COMMANDS:
        main.add_command(command)


_register_launch_commands()


def _register_view_command() -> None:
    from .node.graph_commands import graph_group
    from .view.command import view_cmd

    main.add_command(view_cmd)
    main.add_command(graph_group)
    from .runtime.param_commands import param_group  # cekm param list|get|set

    main.add_command(param_group)


_register_view_command()


def _register_ros2_commands() -> None:
    from .ros2.commands import COMMANDS, export_cmd

    log = main.commands["log"]  # `cekm log` with `export` beside the runtime's own commands (its group untouched)
    main.add_command(click.Group(log.name, commands={**log.commands, "export": export_cmd}, help=log.help))
    for command in COMMANDS:
        main.add_command(command)


_register_ros2_commands()
from .tune.commands import tune_group  # noqa: E402  (cekm tune, docs/fields.md)

main.add_command(tune_group)
main.add_command(sweep)  # cekm sweep concave (Fig. 9)


def run_cli_args(argv: list[str]) -> int:
    """The ``cekm`` command with ``argv``, its outcome as an exit code (one line on error)."""
    return run_cli(main, argv)


def run() -> None:  # pragma: no cover - the console entry (cekm_swarm.cli_support.run_cli is tested)
    sys.exit(run_cli(main))
