"""Click commands of the operator tools, registered by the main CLI from :data:`COMMANDS`:

- ``topic list|echo|hz|info|pub``, ``node list`` (:mod:`.topic_commands`);
- ``log info|cat|recover``, ``replay``, ``record`` (:mod:`.log_commands`);
- ``monitor``: a live view of a run (here).

What they share (endpoint, waiting for the router, exit codes): :mod:`.tool_session`.
"""

from __future__ import annotations

from pathlib import Path

import click

from cekm_swarm.cli_support import ROOT, Finite, Interrupted
from cekm_swarm.errors import CekmError

from .log_commands import log_group, record_cmd, replay_cmd
from .tool_session import _ROOT_HELP, _check_key_expr, _connect_options, _keys, _session
from .topic_commands import node, topic
from .wait import resolve_endpoint


@click.command("monitor")
@_connect_options
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--robot", "robots", multiple=True, metavar="ID", help="Show only this robot (repeat, or r1,r2).")
@click.option("--keys", "key_expr", default=None, metavar="KEYEXPR",
              help="List the rate and age of every key matching this (e.g. 'cekm/r1/**').")
@click.option("--refresh", default=0.5, show_default=True, type=Finite(min=0.05), help="Seconds between redraws.")
@click.option("--once", "once_after", type=Finite(min=0.1), default=None, metavar="SECONDS",
              help="Watch for SECONDS, print one snapshot and exit (for scripts and pipes).")
@click.option("--json", "as_json", is_flag=True, help="With --once: the snapshot as one JSON object.")
def monitor(endpoint: str | None, config_file: Path | None, wait_s: float, root: str, robots: tuple[str, ...],
            key_expr: str | None, refresh: float, once_after: float | None, as_json: bool) -> None:
    """A live view of a run (80 columns): the run's phase, robots' poses, goals, status,
    commands, modules alive and sense-to-command latency; --keys adds per-key rates.
    Attach from any terminal, before or after the run starts; Ctrl-C to leave."""
    from .logcat import key_filter  # noqa: PLC0415 -- lazy: cekm --help loads no monitor
    from .monitor import run_monitor  # noqa: PLC0415 -- lazy: cekm --help loads no monitor (rich)

    _keys(root)
    if as_json and once_after is None:
        raise click.UsageError("--json needs --once SECONDS (the live view is for a terminal)")
    wanted = {r.strip() for t in robots for r in t.split(",") if r.strip()} or None
    chooser = None
    if key_expr is not None:
        chooser = key_filter([_check_key_expr(key_expr, "--keys")])
    try:
        shown = resolve_endpoint(endpoint).endpoint
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    with _session(endpoint, config_file, wait_s) as session:
        try:
            run_monitor(session, root=root, refresh=refresh, once_after=once_after, out=click.echo, robots=wanted,
                        key_filter=chooser, endpoint=shown if config_file is None else "", as_json=as_json)
        except KeyboardInterrupt:
            raise Interrupted() from None
    if once_after is None:
        raise Interrupted() from None


COMMANDS: list[click.Command] = [topic, log_group, replay_cmd, monitor, node, record_cmd]
"""The runtime's commands for the main CLI: ``for c in COMMANDS: main.add_command(c)``."""
