"""The ``cekm`` command line: the top-level group and, in one list, every command it holds.

Each command group declares its own commands and options in its own module; this one
registers them (:data:`COMMANDS`) and holds ``cekm run``, the in-process run that joins
the experiments, the graphs and the tuned fields.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from .cli_support import FileRefused, Finite, out_dir_options, prepare_out_dir, run_cli, seed_option
from .experiments.commands import (
    fields_option,
    load_scenario_file,
    refuse_unplannable,
    run_navigation_cmd,
    run_tracking_cmd,
    scenario_kind,
)
from .experiments.experiment_commands import experiment_group, fields_cmd, train_cmd
from .experiments.graph_run import default_max_time, resolve_graph, with_params
from .experiments.learning_commands import controller_model, model_group, model_option
from .experiments.learning_run import learning_controller, learning_params
from .experiments.sweep_commands import sweep
from .graph.spec import GraphError
from .interrupts import restore_sigint
from .launch.commands import launch_cmd, plot_cmd
from .node.graph_commands import graph_group
from .ros2.commands import export_cmd, ros2_group
from .runtime.commands import monitor, node, topic
from .runtime.log_commands import log_cat_cmd, log_group, log_info_cmd, log_recover_cmd, record_cmd, replay_cmd
from .runtime.param_commands import param_group
from .tune.commands import tune_group
from .view.command import view_cmd


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="cekm-swarm")
def main() -> None:
    """Cooperative Extended Kohonen Maps: models, the paper's experiments, a multi-robot runtime."""


@click.command("run")
@click.argument("scenario")
@click.option("--controller", default="cekm", show_default=True, metavar="NAME",
              help="The controller whose graph runs (cekm graph list): cekm, cekm-tuned, fusion or stay for "
                   "navigation; cekm, acmommt, kmeans, kmeans-global or stay for tracking.")
@click.option("--graph", "graph_file", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Run a graph file of your own instead (docs/modules.md).")
@model_option(untrained=True)
@click.option("--learn", is_flag=True, help="The robots' maps learn online as they move (docs/learning.md).")
@seed_option()
@click.option("--max-time", type=Finite(min=0.2),  # as cekm launch takes it, so every launch has its cekm run
              help="Sim seconds before a robot counts as trapped (default 600); for a tracking scenario, the "
                   "run's length (default 120).")
@fields_option(None, "default: the graph's own (cekm: learned for navigation, tuned for tracking)")
@click.option("--policy", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="With --fields learned: a field policy file of your own (cekm tune fields' policy.json) in "
                   "place of the shipped one.")
@out_dir_options("Directory for outcome.json and trajectory.png.")
def run_cmd(scenario: str, controller: str, graph_file: Path | None, model_path: Path | None, learn: bool,
            seed: int | None, max_time: float | None, fields: str | None, policy: Path | None, out_dir: Path,
            overwrite: bool) -> None:
    """Run SCENARIO (a name under world/scenarios or a .toml path) in one process, no Zenoh:
    the controller's graph, every node in this process, by the rule a lockstep launch
    follows (so `cekm launch --mode lockstep` gives the same run).

    A scenario with targets whose robots have no goal is a tracking scenario (Fig. 13)."""
    from .tune.graphs import with_fields  # noqa: PLC0415 -- lazy: not at cekm --help

    sc = load_scenario_file(scenario)
    task = scenario_kind(sc)
    refuse_unplannable(sc)
    controller = learning_controller(controller, graph_file) if learn else controller
    try:
        checked = resolve_graph(controller, None if graph_file is None else str(graph_file), task)
        checked = with_fields(checked, fields, task, policy)
        checked.plan([r.id for r in sc.robots], task)
    except GraphError as exc:
        raise FileRefused(str(exc)) from None
    checked = with_params(checked, learning_params(model_path) if learn else None)
    controller = checked.graph.controller
    model = controller_model(model_path) if checked.uses_model else None
    if task == "tracking":
        prepare_out_dir(out_dir, overwrite)
        run_tracking_cmd(sc, controller, model_path, seed, max_time, out_dir, graph=checked, model=model)
        return
    max_time = default_max_time(task) if max_time is None else max_time
    prepare_out_dir(out_dir, overwrite)
    run_navigation_cmd(sc, controller, model, seed, max_time, out_dir, graph=checked)


LOG_GROUP = click.Group(log_group.name, help=log_group.help,
                        commands=[log_info_cmd, log_cat_cmd, log_recover_cmd, export_cmd])
"""``cekm log``: the runtime's log commands and the ROS 2 export beside them (the runtime's
own group, :data:`cekm_swarm.runtime.log_commands.log_group`, stays without it)."""

COMMANDS: tuple[click.Command, ...] = (
    # the paper's experiments, training and the in-process run (docs/reproduction-*.md)
    experiment_group, sweep, train_cmd, run_cmd, fields_cmd, model_group, tune_group,
    # the distributed runtime: launch, the operator tools, logs (docs/runtime.md, docs/tools.md)
    launch_cmd, plot_cmd, topic, node, monitor, LOG_GROUP, replay_cmd, record_cmd, param_group,
    # graphs, the live view, ROS 2 (docs/modules.md, docs/ros2.md)
    graph_group, view_cmd, ros2_group,
)
"""Every command and group of ``cekm``, registered here and nowhere else."""

for _command in COMMANDS:
    main.add_command(_command)


def run_cli_args(argv: list[str]) -> int:
    """The ``cekm`` command with ``argv``, its outcome as an exit code (one line on error)."""
    return run_cli(main, argv)


def run() -> None:  # the console entry and ``python -m cekm_swarm`` (tests/test_cli_interrupt.py)
    restore_sigint()  # a script's background job: kill -INT still stops the command
    sys.exit(run_cli(main))
