"""The ROS 2 commands of the ``cekm`` CLI (registered by ``cekm_swarm/cli.py``):

- ``cekm log export RUN.mcap --to ros2 --out BAG_DIR``: a run's log as a rosbag2 bag;
- ``cekm ros2 bridge``: a live run's topics in ``rmw_zenoh``'s wire format, and teleop.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
from pathlib import Path
from typing import Any

import click

from cekm_swarm.cli_support import ROOT, Finite, Interrupted, RobotIds, prepare_out_dir
from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import DEFAULT_ROOT, KeySpace
from cekm_swarm.runtime.mcap_log import MSGPACK, is_complete, log_root, read_messages
from cekm_swarm.runtime.options import ENDPOINT
from cekm_swarm.runtime.wait import DEFAULT_WAIT, ENV_CONNECT, resolve_endpoint

from .interfaces import DEFAULT_DISTRO, DISTROS


def _say(text: str) -> None:
    click.echo(text, err=True)


@click.command("export")
@click.argument("log_file", metavar="RUN.mcap", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--to", "to", type=click.Choice(["ros2"]), required=True,
              help="ros2: a rosbag2 directory (metadata.yaml + MCAP storage, CDR, ros2msg schemas).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="The bag directory to write (absent or empty).")
@click.option("--overwrite", is_flag=True, help="Clear a non-empty --out directory first (without it, one is refused).")
@click.option("--distro", type=click.Choice(DISTROS), default=DEFAULT_DISTRO, show_default=True,
              help="ROS 2 distribution whose message definitions and type hashes the bag carries.")
@click.option("--quiet", is_flag=True, help="No progress bar (there is none when stderr is not a terminal).")
def export_cmd(log_file: Path, to: str, out_dir: Path, overwrite: bool, distro: str, quiet: bool) -> None:
    """Export RUN.mcap for ROS 2 tools: `ros2 bag play`, `ros2 bag info`, Foxglove, rosbags."""
    from .bag import export_ros2, format_report  # noqa: PLC0415 -- lazy: cekm --help loads no exporter

    try:
        is_complete(log_file)  # a missing or non-MCAP file: one line, before anything is written
        if next(read_messages(log_file, encodings=[MSGPACK]), None) is None:
            raise click.UsageError(f"{log_file}: no message of the key space to export")
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    prepare_out_dir(out_dir, overwrite)
    bar: Any = None

    def progress(done: int, total: int | None) -> None:
        nonlocal bar
        if quiet:
            return
        if bar is None:
            from tqdm import tqdm  # noqa: PLC0415 -- lazy: a progress bar only on a terminal

            bar = tqdm(total=total, unit="msg", desc="export", file=sys.stderr, leave=False, disable=None)
        bar.update(done - bar.n)

    try:
        keys = KeySpace(log_root(log_file) or DEFAULT_ROOT)  # the log's own key root (a launch's --root)
        report = export_ros2(log_file, out_dir, distro=distro, keys=keys, progress=progress)
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        if bar is not None:
            bar.close()
    click.echo(format_report(report))


@click.group("ros2")
def ros2_group() -> None:
    """ROS 2 interoperability: a live run as rmw_zenoh topics (docs/ros2.md)."""


@ros2_group.command("bridge")
@click.option("--connect", "endpoint", default=None, metavar="ENDPOINT", type=ENDPOINT,
              help=f"Zenoh endpoint to join [default: ${ENV_CONNECT}, else tcp/127.0.0.1:7447, the "
                   f"launcher's embedded router].")
@click.option("--config", "config_file", type=click.Path(dir_okay=False, exists=True, path_type=Path), default=None,
              help="Zenoh client config file (JSON5: credentials, TLS); --connect overrides its endpoint.")
@click.option("--wait", "wait_s", default=DEFAULT_WAIT, show_default=True, type=Finite(0.0),
              help="Seconds to wait for the router before giving up (0: do not wait).")
@click.option("--domain", default=0, show_default=True, type=click.IntRange(0, 232), help="ROS_DOMAIN_ID.")
@click.option("--robots", default=None, metavar="r1,r2", type=RobotIds(),
              help="Only these robots' topics (default: every robot).")
@click.option("--teleop", default=None, metavar="r1,r2", type=RobotIds(),
              help="Drive these robots from geometry_msgs/msg/Twist on /<robot>/cmd_vel (their modules must not run).")
@click.option("--distro", type=click.Choice(DISTROS), default=DEFAULT_DISTRO, show_default=True,
              help="ROS 2 distribution whose type hashes the topics carry.")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help="Key-space root of the run.")
@click.option("--json", "as_json", is_flag=True, help="Print the final report as one JSON object.")
def bridge_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, domain: int,
               robots: tuple[str, ...] | None, teleop: tuple[str, ...] | None, distro: str, root: str,
               as_json: bool) -> None:
    """Publish a live run's topics as a ROS 2 node under rmw_zenoh, until Ctrl-C or SIGTERM."""
    from .bridge import BridgeConfig, bridge_session, run_bridge  # noqa: PLC0415 -- lazy: cekm --help loads no bridge

    config = BridgeConfig(domain=domain, robots=robots, teleop=teleop or (),
                          distro=distro, root=root)
    stop = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:  # Ctrl-C or SIGTERM: the bridge's normal end
        stop.set()

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        try:
            resolve_endpoint(endpoint)
        except CekmError as exc:
            raise click.UsageError(str(exc)) from None
        try:
            session = bridge_session(endpoint, config_file, timeout=wait_s, say=_say, stop=stop)
        except CekmError as exc:
            if stop.is_set():  # stopped while waiting for the router
                raise Interrupted() from None
            raise click.ClickException(str(exc)) from None
        if stop.is_set():
            session.close()
            raise Interrupted()
        try:
            report = run_bridge(session, config, stop, say=_say)
        finally:
            session.close()
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    if as_json:
        click.echo(json.dumps(report, sort_keys=True))
    else:
        refused = sum(report["twists_refused"].values())
        teleop_text = (f"; {report['twists']} Twists, {refused} refused, {report['wheel_commands']} wheel commands"
                       if config.teleop else "")
        click.echo(f"ros2 bridge: {report['received']} run messages ({report['dropped']} malformed dropped), "
                   f"{report['published']} ROS 2 messages on {report['topics']} topics{teleop_text}")

