"""Click commands of the launcher: ``cekm launch`` and ``cekm plot``."""

from __future__ import annotations

import ipaddress
import json
import os
from pathlib import Path
from typing import Any

import click
from click.core import ParameterSource

from cekm_swarm.cli_support import (
    ROOT,
    RUN_ID,
    SIZE,
    FileRefused,
    Finite,
    Interrupted,
    RobotIds,
    RunFailed,
    out_dir_options,
    out_file_option,
    prepare_figure_file,
    prepare_out_dir,
    seed_option,
)
from cekm_swarm.errors import CekmError
from cekm_swarm.experiments.commands import load_scenario_file, refuse_unplannable, scenario_kind
from cekm_swarm.experiments.learning_commands import add_launch_learning, model_option
from cekm_swarm.experiments.learning_run import UNTRAINED, learning_controller, learning_params, model_file_for_launch
from cekm_swarm.graph.spec import GraphError
from cekm_swarm.node.graph_check import CheckedGraph
from cekm_swarm.runtime.config import DEFAULT_ENDPOINT, DEFAULT_PORT, client_config_from_file
from cekm_swarm.runtime.errors import RuntimeTransportError
from cekm_swarm.runtime.log_commands import LOG_HELP
from cekm_swarm.runtime.mcap_sets import log_files
from cekm_swarm.runtime.options import ENDPOINT
from cekm_swarm.runtime.wait import resolve_endpoint
from cekm_swarm.ticks import STEP_TIMEOUT

from .errors import NodeCannotStart, NodeFailed
from .plot import plot_log
from .prepare import PreflightError, body_of, plan_of, port_taken, preflight, resolve


def _env_endpoint() -> str | None:
    try:
        ep = resolve_endpoint(None)
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    return ep.endpoint if ep.explicit else None


@click.command("launch")
@click.argument("scenario")
@click.option("--mode", type=click.Choice(["realtime", "lockstep"]), default="realtime", show_default=True,
              help="realtime: wall clock; lockstep: the world waits for every robot's command (reproducible).")
@seed_option()
@out_dir_options("Directory for outcome.json, run.mcap, trajectory.png and the processes' logs.")
@click.option("--connect", type=ENDPOINT, help="Join this Zenoh endpoint (e.g. tcp/10.0.0.1:7447) instead of "
                                               "opening an embedded router [default: $CEKM_CONNECT unless "
                                               "--port is given].")
@click.option("--port", default=DEFAULT_PORT, show_default=True, type=click.IntRange(1, 65535),
              help="Port of the embedded router on 127.0.0.1 (without --connect).")
@model_option(untrained=True)
@click.option("--learn", is_flag=True, help="The robots' maps learn online as they move (docs/learning.md).")
@click.option("--max-time", type=Finite(min=0.2),
              help="Sim seconds before the run ends (default: as cekm run, 600 for navigation, 120 for tracking).")
@click.option("--controller", default="cekm", show_default=True, metavar="NAME",
              help="The controller whose graph runs (cekm graph list): cekm, fusion, acmommt, stay, ...")
@click.option("--graph", "graph_file", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Run a graph file of your own instead (docs/modules.md).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help="Key space root.")
@click.option("--no-plot", is_flag=True, help="Do not draw trajectory.png.")
@click.option("--robots", "robots", default=None, metavar="R1,R2", type=RobotIds(none_word="none"),
              help="Start only these robots' module processes here; 'none' for a world-only host "
                   "(several hosts: see deploy/README.md).")
@click.option("--no-world", is_flag=True, help="Do not start the world server here (it runs on another host).")
@click.option("--listen", "listen_host", default="127.0.0.1", show_default=True,
              help="Address of the embedded router; 0.0.0.0 serves other hosts.")
@click.option("--config", "zenoh_config", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Zenoh client config file (credentials, TLS; see deploy/) for every process started here; "
                   "--connect or the embedded router sets its endpoint.")
@click.option("--model-from-zenoh", is_flag=True,
              help="Modules fetch the model from the world host's launcher (a robot host needs no model file).")
@click.option("--run-id", type=RUN_ID,
              help="The run's id (default: made by the world host; a robots-only host takes the world's).")
@click.option("--cold-start", is_flag=True,
              help="Start every node process afresh (exec) instead of forking it from a warm fork server.")
@click.option("--send-every-reading", is_flag=True,
              help="The world sends every reading every tick, unchanged ones too (default: it holds them: "
                   "docs/runtime.md).")
@click.option("--max-log-size", type=SIZE, metavar="SIZE",
              help="Split the log into a set, run_0.mcap, run_1.mcap, ..., a new file once one holds SIZE "
                   "(500M, 2G, ...); cekm log and cekm replay take the set (docs/tools.md).")
@click.option("--max-log-duration", type=Finite(0.0, min_open=True), metavar="S",
              help="Split the log into a set: a new file every S s of sim time.")
@click.option("--step-timeout", type=Finite(0.0, min_open=True), default=STEP_TIMEOUT, show_default=True,
              metavar="S", help="Lockstep: a tick the world waits S s for (a step that hangs) ends the launch with "
                               "the stall report, exit 1.")
@click.option("--record", "record", type=click.Choice(["full", "lean"]), default="full", show_default=True,
              help="What run.mcap holds: full (every message and view), or lean for long runs (the world's "
                   "messages, commands and shares, views at 1 Hz; docs/tools.md).")
@click.option("--plant", type=click.Choice(["ros2"]), default=None,
              help="ros2: the robots live in ROS 2 (a real robot, Gazebo, Webots over rmw_zenoh); no world is "
                   "simulated (docs/ros2.md, 'Driving a ROS 2 robot').")
@click.option("--domain", "plant_domain", default=0, show_default=True, type=click.IntRange(0, 232),
              help="--plant ros2: ROS_DOMAIN_ID.")
@click.option("--distro", "plant_distro", type=click.Choice(["jazzy", "kilted"]), default="jazzy", show_default=True,
              help="--plant ros2: the ROS 2 distribution.")
@click.option("--robot-description", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="--plant ros2: the robots' body (TOML; default: the scenario's simulated body).")
@click.option("--deadman", type=Finite(0.0, min_open=True), default=0.5, show_default=True, metavar="S",
              help="Real time: s without a robot's commands before the world stops it (a slow or lossy "
                   "link wants more: docs/faults.md).")
@click.option("--deadline-ticks", type=click.IntRange(0, 64), default=0, show_default=True, metavar="N",
              help="Real time: a robot's command for tick k is on time until the end of tick k+N (a link "
                   "whose round trip, retransmissions included, exceeds a tick wants more: docs/faults.md).")
@click.option("--republish", type=Finite(0.0, min_open=True), default=1.0, show_default=True, metavar="S",
              help="Lockstep: s the world waits on a tick before re-publishing its readings.")
@click.option("--world-grace", type=Finite(0.0), default=0.0, show_default=True, metavar="S",
              help="A robots-only host: s to wait for the world server when its token goes without its end "
                   "(a cut link, docs/faults.md) before ending; 0: end at once.")
def launch_cmd(scenario: str, mode: str, seed: int | None, out_dir: Path, overwrite: bool, connect: str | None,
               port: int, model_path: Path | None, learn: bool, max_time: float | None, controller: str,
               graph_file: Path | None,
               root: str, no_plot: bool, robots: tuple[str, ...] | None, no_world: bool, listen_host: str,
               zenoh_config: Path | None, model_from_zenoh: bool, run_id: str | None, cold_start: bool,
               send_every_reading: bool, max_log_size: int | None, max_log_duration: float | None,
               record: str, step_timeout: float, deadman: float, deadline_ticks: int, republish: float,
               world_grace: float,
               plant: str | None = None, plant_domain: int = 0, plant_distro: str = "jazzy",
               robot_description: Path | None = None) -> None:
    """Run SCENARIO through the distributed runtime: the world server and, per robot, every
    node of the controller's graph as its own process on Zenoh (cekm: 1 + 12 + 1),
    supervised (restarted when they die)."""
    from cekm_swarm.modules.learner import SNAPSHOT_DIR  # noqa: PLC0415 -- lazy: not at cekm --help

    from .launcher import LaunchConfig, Launcher  # noqa: PLC0415 -- lazy: not at cekm --help

    if connect is None and click.get_current_context().get_parameter_source("port") is not ParameterSource.COMMANDLINE:
        connect = _env_endpoint()  # --connect > CEKM_CONNECT > the embedded router (an explicit --port hosts it)
    # every check before anything is written or started
    sc = load_scenario_file(scenario)
    scenario_kind(sc)  # a tracking or a navigation scenario, or refused here
    refuse_unplannable(sc)
    known = [r.id for r in sc.robots]
    only = robots  # None: every robot; (): none ('none', a world-only host)
    _check_hosts(scenario, known, only, no_world, listen_host)
    _check_zenoh_config(zenoh_config, connect)
    params = None
    if learn:
        controller, params = learning_controller(controller, graph_file), learning_params(model_path)
    checked, task = _checked_graph(sc, controller, graph_file, params)
    _check_plant(sc, checked, task, mode, plant, robot_description)
    if model_path not in (None, UNTRAINED) and checked.uses_model:  # refused before --overwrite clears --out
        body = body_of(sc)
        preflight(checked, plan_of(checked, tuple(known), task, body, root), body, str(model_path))
    if connect is None:  # a taken port is refused before --out is touched: the retry with --port needs no --overwrite
        _check_port(listen_host, port)
    prepare_out_dir(out_dir, overwrite)
    model_path = model_file_for_launch(model_path, out_dir)  # untrained maps: a file the nodes read
    config = LaunchConfig(scenario, out_dir, mode=mode, seed=seed, connect=connect, port=port, model=model_path,
                          max_time=max_time, controller=controller, graph=graph_file, root=root, plot=not no_plot,
                          robots=only, world=not no_world, listen_host=listen_host, zenoh_config=zenoh_config,
                          model_from_zenoh=model_from_zenoh, run_id=run_id, warm_start=not cold_start,
                          hold_readings=not send_every_reading and plant is None, max_log_size=max_log_size,
                          max_log_duration=max_log_duration, record=record, step_timeout=step_timeout, plant=plant,
                          plant_domain=plant_domain, plant_distro=plant_distro, robot_description=robot_description,
                          params=params, deadman=deadman, deadline_ticks=deadline_ticks, republish=republish,
                          world_grace=world_grace)
    os.environ[SNAPSHOT_DIR] = str((out_dir / "maps").resolve())  # a learner's state: a restart goes on from it
    launcher = Launcher(config, echo=lambda s: click.echo(s))
    outcome = _launched(launcher)
    if learn and not no_world:
        add_launch_learning(out_dir, outcome, model_path)
    if no_world:
        click.echo(f"modules of {', '.join(only) if only else 'every robot'} stopped; "
                   f"the world host writes the outcome")
        if launcher.interrupted:
            raise Interrupted()
        return
    _report(launcher, outcome, out_dir)


def _check_hosts(scenario: str, known: list[str], only: tuple[str, ...] | None, no_world: bool,
                 listen_host: str) -> None:
    """``--robots`` names robots of the scenario, a ``--no-world`` host starts something, and
    ``--listen`` is an IP address (or localhost)."""
    unknown = [r for r in only or () if r not in known]
    if unknown:
        raise click.BadParameter(f"{scenario} has no robot {', '.join(unknown)} (robots: {', '.join(known)})",
                                 param_hint="'--robots'")
    if no_world and only == ():
        raise click.UsageError("--no-world with no robot here starts nothing: name robots with --robots")
    try:
        ipaddress.ip_address(listen_host.strip("[]"))
    except ValueError:
        if listen_host != "localhost":
            raise click.BadParameter(f"{listen_host!r} is not an IP address (e.g. 127.0.0.1, or 0.0.0.0 to serve "
                                     f"other hosts)", param_hint="'--listen'") from None


def _check_zenoh_config(zenoh_config: Path | None, connect: str | None) -> None:
    """A bad ``--config`` file is refused before any process starts."""
    if zenoh_config is None:
        return
    try:
        client_config_from_file(zenoh_config, connect or DEFAULT_ENDPOINT)
    except RuntimeTransportError as exc:
        raise click.UsageError(str(exc)) from None


def _checked_graph(sc: Any, controller: str, graph_file: Path | None,
                   params: dict[str, Any] | None) -> tuple[CheckedGraph, str]:
    """The controller's graph for the scenario and its task, checked and planned for its
    robots; a bad graph refused naming its file."""
    try:
        checked, task = resolve(sc, controller, graph_file, params)
        checked.plan([r.id for r in sc.robots], task)
    except GraphError as exc:
        raise FileRefused(str(exc)) from None
    return checked, task


def _check_plant(sc: Any, checked: CheckedGraph, task: str, mode: str, plant: str | None,
                 robot_description: Path | None) -> None:
    """A ROS 2 plant's body the model does not fit, or a lockstep run on one, refused before
    anything starts; ``--robot-description`` only with ``--plant ros2``."""
    if plant is not None:
        from .plant_host import refuse_plant  # noqa: PLC0415 -- lazy: the ROS 2 plant, only with --plant

        refuse_plant(sc, checked, task, mode, robot_description)
    elif robot_description is not None:
        raise click.UsageError("--robot-description describes a ROS 2 robot: use it with --plant ros2")


def _check_port(listen_host: str, port: int) -> None:
    """The embedded router's port is free, or the run failed naming it."""
    why = port_taken(listen_host, port)
    if why is not None:
        raise RunFailed(f"cannot open the Zenoh router on {listen_host}:{port}: {why}; port {port} is taken "
                        f"(another run or program listens there): choose another with --port")


def _launched(launcher: Any) -> dict[str, Any]:
    """The launch run to its end, its outcome; each way it can fail as the one line and exit
    code of its kind (bad input 2, a failed run 1)."""
    try:
        return launcher.launch()
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    except (GraphError, PreflightError, NodeCannotStart):  # bad input: cekm: error: <the one line>
        raise
    except NodeFailed as exc:  # a step failed or hung: the run failed (exit 1), its one line
        raise RunFailed(str(exc)) from None
    except CekmError as exc:  # the world server or the embedded router did not come up: say why, no traceback
        raise RunFailed(str(exc)) from None


def _report(launcher: Any, outcome: dict[str, Any], out_dir: Path) -> None:
    """What a world host's finished launch prints, and the exit it ends with (a full disk, no
    outcome or an interruption)."""
    if launcher.log_full is not None:  # the log's disk filled: the run ended there, the log is closed
        for line in outcome_summary(outcome) if outcome.get("robots") else ():
            click.echo(line)
        raise RunFailed(f"the log's disk is full: {launcher.log_full}")
    if not outcome:
        if launcher.interrupted:
            raise Interrupted("interrupted before the run started")
        raise RunFailed(f"the run left no outcome; see {out_dir / 'launch.log'} and {out_dir / 'logs'}")
    for line in outcome_summary(outcome):
        click.echo(line)
    if outcome.get("aborted"):
        click.echo("the run was stopped before its end (see the world's events in outcome.json)")
    logs = outcome.get("log", {}).get("files") or ["run.mcap"]
    log_name = logs[0] if len(logs) == 1 else f"{logs[0]} .. {logs[-1]} ({len(logs)} files)"
    written = [str(out_dir / n) for n in ("outcome.json", "run.mcap", "trajectory.png") if (out_dir / n).is_file()]
    if len(logs) > 1:
        written.insert(1, str(out_dir / log_name))
    click.echo("wrote " + ", ".join(written))
    if launcher.interrupted:
        raise Interrupted()


def outcome_summary(outcome: dict) -> list[str]:
    """The lines a finished launch prints: each robot, tracking's A, latency, in real time
    the deadline misses and the ticks they fell on, where a tick's CPU went and how much of
    the machine's time the host stole meanwhile, restarts."""
    from world.episode import pushed_out_note  # noqa: PLC0415 -- lazy: the world's modules, not at cekm --help
    from world.outcome import MISSED_TICKS_KEPT  # noqa: PLC0415 -- lazy: the world's modules
    from world.tracking import tracking_summary  # noqa: PLC0415 -- lazy: the world's modules

    lines = []
    tracking = "tracking" in outcome  # docs/tracking.md

    for r, o in outcome["robots"].items():
        left = pushed_out_note(o)
        if tracking:
            lines.append(f"{r}: path {o['path_length_m']:.2f} m, {o['collisions']} collisions{left}")
        else:
            hits = ("collisions not known (a ROS 2 robot)" if o["collisions"] is None
                    else f"{o['collisions']} collisions")
            state = ("" if o["reached"] is None
                     else f"{'reached' if o['reached'] else 'NOT reached'} in {o['time_s']:.1f} s, ")
            lines.append(f"{r}: {state}path {o['path_length_m']:.2f} m, {hits}{left}")  # (None: a ROS 2 tracking robot)
    if tracking:
        lines.append(tracking_summary(outcome["tracking"], sum(o["collisions"] for o in outcome["robots"].values())))
    lat = outcome.get("sense_to_command_ms", {})
    if lat.get("n"):
        lines.append(f"sense-to-command latency p50 {lat['p50']} ms, p99 {lat['p99']} ms ({lat['n']} robot-ticks)")
    scan = outcome.get("scan_to_twist_ms", {})  # a ROS 2 plant's run (docs/ros2.md)
    if scan.get("n"):
        lines.append(f"scan-to-Twist latency p50 {scan['p50']} ms, p99 {scan['p99']} ms ({scan['n']} Twists)")
    if outcome.get("mode") == "realtime":
        misses = outcome.get("deadline_misses", 0)
        robot_ticks = outcome.get("ticks", 0) * len(outcome["robots"])
        line = f"deadline misses: {misses} of {robot_ticks} robot-ticks"
        if outcome.get("deadline_ticks"):
            line += f" (a command up to {outcome['deadline_ticks']} ticks late allowed: --deadline-ticks)"
        ticks = sorted(int(k) for k in outcome.get("deadline_miss_ticks", {}))
        if ticks:
            shown = ", ".join(map(str, ticks[:8])) + (", ..." if len(ticks) > 8 else "")
            line += f", in {len(ticks)}{'+' if len(ticks) >= MISSED_TICKS_KEPT else ''} ticks ({shown})"
        if outcome.get("first_tick_ms") is not None:
            line += f"; tick 0 answered after {outcome['first_tick_ms']:.0f} ms (the clock started then)"
        lines.append(line)
    cpu = outcome.get("launcher", {}).get("cpu", {})
    if cpu.get("total_ms_per_tick") is not None:
        split = ", ".join(f"{k} {v:.1f}" for k, v in cpu.get("ms_per_tick", {}).items())
        line = f"CPU per tick: {cpu['total_ms_per_tick']:.1f} ms ({split})"
        if cpu.get("not_counted"):
            line += f"; {cpu['not_counted']} process lives not counted (restarts: begun or ended mid-run)"
        steal = cpu.get("host", {}).get("steal")
        if steal is not None:
            line += f"; the host stole {100 * steal:.0f} % of this machine's time meanwhile"
            if steal >= 0.1:
                line += " (timings are slower for it)"
        lines.append(line)
    restarts = outcome.get("launcher", {}).get("restarts")
    if restarts:
        lines.append(f"restarts: {restarts}")
    return lines


@click.command("plot", epilog=LOG_HELP)
@click.argument("log", metavar="LOG", type=click.Path(exists=True, path_type=Path))
@out_file_option("The PNG to write (replaced if it exists).")
@click.option("--title", help="Figure title.")
def plot_cmd(log: Path, out_path: Path, title: str | None) -> None:
    """Draw the run recorded in LOG (an MCAP log of `cekm launch`): arena and robot paths."""
    prepare_figure_file(out_path)
    try:
        log_files(log)  # a directory with no log, or with several, is named before any work
        outcome = None
        sibling = log / "outcome.json" if log.is_dir() else log.with_name("outcome.json")
        if sibling.is_file():  # an extra (which robots reached their goals): a bad one is passed over, said once
            try:
                outcome = json.loads(sibling.read_text())
            except (OSError, UnicodeDecodeError, ValueError) as exc:
                outcome = f"not readable JSON ({type(exc).__name__})"
            if not isinstance(outcome, dict):
                why = outcome if isinstance(outcome, str) else "not a JSON object"
                click.echo(f"cekm: note: {sibling}: {why}; drawing the log alone", err=True)
                outcome = None
        fig = plot_log(log, title=title, outcome=outcome)
    except CekmError as exc:  # a log it cannot read: a failure (exit 1), as in `cekm log info`
        raise RunFailed(str(exc)) from None
    fig.savefig(out_path, dpi=130)
    click.echo(f"wrote {out_path}")
