"""Click commands of the runtime tools, registered by the main CLI from :data:`COMMANDS`:

- ``topic list``, ``topic echo KEYEXPR``, ``topic hz KEYEXPR``: inspect a live (or replayed) run;
- ``log info LOG.mcap``: channels, counts, rates and duration of a log (recovers a truncated one);
- ``log recover IN.mcap OUT.mcap``: a complete, indexed copy of a log whose writer was killed;
- ``replay LOG.mcap [--rate X] [--loop]``: republish a log onto Zenoh.

Every networked command takes ``--connect ENDPOINT`` (default: the launcher's embedded
router, ``tcp/127.0.0.1:7447``) and optionally ``--config FILE`` (a Zenoh client config,
e.g. ``deploy/monitor.json5``, for a multi-host setup with credentials).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click

from cekm_swarm.errors import CekmError

from .config import DEFAULT_ENDPOINT, client_config, load_config, open_session

_ROOT_HELP = "Key-space root (docs/design.md section 6)."


def _connect_options(f: Callable[..., Any]) -> Callable[..., Any]:
    f = click.option("--config", "config_file", type=click.Path(dir_okay=False, exists=True, path_type=Path),
                     default=None, help="Zenoh client config file (JSON5); --connect overrides its endpoint.")(f)
    f = click.option("--connect", "endpoint", default=None, metavar="ENDPOINT",
                     help=f"Zenoh endpoint to join [default: {DEFAULT_ENDPOINT}, the launcher's embedded router].")(f)
    return f


@contextlib.contextmanager
def _session(endpoint: str | None, config_file: Path | None) -> Iterator[Any]:
    try:
        if config_file is not None:
            overrides = {"connect/endpoints": [endpoint]} if endpoint else None
            config = load_config(config_file, overrides)
        else:
            config = client_config(endpoint or DEFAULT_ENDPOINT)
        session = open_session(config, "client session")
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None
    try:
        yield session
    finally:
        session.close()


# --------------------------------------------------------------------------- topic


@click.group("topic")
def topic() -> None:
    """Inspect the keys of a live or replayed run (like ``ros2 topic``)."""


@topic.command("list")
@_connect_options
@click.option("--window", default=2.0, show_default=True, type=click.FloatRange(0.05), help="Seconds to listen.")
@click.option("--root", default="cekm", show_default=True, help=_ROOT_HELP)
@click.option("--alive/--no-alive", default=True, show_default=True, help="Also list liveliness tokens.")
def topic_list_cmd(endpoint: str | None, config_file: Path | None, window: float, root: str, alive: bool) -> None:
    """Keys that carried messages during a listening window, with counts and rates."""
    from .topics import alive_tokens, topic_list

    with _session(endpoint, config_file) as session:
        seen = topic_list(session, f"{root}/**", window)
        tokens = alive_tokens(session, f"{root}/*/alive/*") if alive else []
    if not seen:
        click.echo(f"no messages on {root}/** in {window:g} s")
    else:
        w = max(len(k) for k in seen)
        for key, (n, size) in seen.items():
            click.echo(f"{key:<{w}}  {n:>6} msgs  {n / window:>8.1f} Hz  {size / max(n, 1):>7.0f} B/msg")
    if alive:
        click.echo(f"liveliness tokens ({len(tokens)}):")
        for t in tokens:
            click.echo(f"  {t}")


@topic.command("echo")
@_connect_options
@click.argument("key_expr", metavar="KEYEXPR")
@click.option("--count", "-n", type=click.IntRange(1), default=None, help="Stop after N messages.")
@click.option("--timeout", type=click.FloatRange(0.0), default=None, help="Stop after this many seconds of silence.")
@click.option("--full", is_flag=True, help="Print every field in full (arrays too).")
@click.option("--root", default="cekm", show_default=True, help=_ROOT_HELP)
def topic_echo_cmd(endpoint: str | None, config_file: Path | None, key_expr: str, count: int | None,
                   timeout: float | None, full: bool, root: str) -> None:
    """Decode and print the messages on KEYEXPR (e.g. 'cekm/r1/cmd/wheels', 'cekm/r1/**')."""
    from cekm_swarm.protocol import KeySpace

    from .topics import echo

    with _session(endpoint, config_file) as session:
        try:
            n = echo(session, key_expr, click.echo, count=count, timeout=timeout, full=full, keys=KeySpace(root))
        except KeyboardInterrupt:
            return
        except CekmError as exc:
            raise click.ClickException(str(exc)) from None
    if timeout is not None and (count is None or n < count):
        click.echo(f"({n} messages; stopped after {timeout:g} s of silence)", err=True)


@topic.command("hz")
@_connect_options
@click.argument("key_expr", metavar="KEYEXPR")
@click.option("--window", default=5.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds of arrivals the statistics cover.")
@click.option("--interval", default=1.0, show_default=True, type=click.FloatRange(0.05), help="Seconds between reports.")
@click.option("--duration", default=None, type=click.FloatRange(0.0), help="Stop after this many seconds.")
def topic_hz_cmd(endpoint: str | None, config_file: Path | None, key_expr: str, window: float, interval: float,
                 duration: float | None) -> None:
    """Rate, period jitter and age of the newest message of each key matching KEYEXPR."""
    from .topics import ArrivalLog, format_hz

    stop = threading.Event()
    with _session(endpoint, config_file) as session, ArrivalLog(session, key_expr, window) as arrivals:
        t_end = None if duration is None else time.monotonic() + duration
        try:
            while not stop.is_set():
                left = None if t_end is None else t_end - time.monotonic()
                if left is not None and left <= 0:
                    break
                stop.wait(interval if left is None else min(interval, left))
                click.echo(format_hz(arrivals.stats()))
                click.echo("")
        except KeyboardInterrupt:
            pass


# --------------------------------------------------------------------------- log


@click.group("log")
def log_group() -> None:
    """MCAP run logs."""


@log_group.command("info")
@click.argument("log_file", metavar="LOG.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--recover", "recover_to", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="If the log is truncated (its writer was killed), write an indexed copy here.")
def log_info_cmd(log_file: Path, recover_to: Path | None) -> None:
    """Channels, message counts, rates and duration of a log (a truncated log is read up to the cut)."""
    from .mcap_log import format_log_info, log_info, recover_log

    try:
        info = log_info(log_file)
        click.echo(format_log_info(info))
        if recover_to is not None:
            if info.complete:
                click.echo("log is complete; nothing to recover")
            else:
                rep = recover_log(log_file, recover_to)
                click.echo(f"recovered {rep.messages} messages on {rep.channels} channels into {rep.output}")
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None


@log_group.command("recover")
@click.argument("log_file", metavar="IN.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.argument("out_file", metavar="OUT.mcap", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--force", is_flag=True, help="Overwrite OUT.mcap if it exists.")
def log_recover_cmd(log_file: Path, out_file: Path, force: bool) -> None:
    """Copy every complete message (and metadata) of IN.mcap, e.g. a log whose writer was
    killed, into OUT.mcap, a complete, indexed file."""
    from .mcap_log import recover_log

    if out_file.exists() and not force:
        raise click.ClickException(f"{out_file}: exists; use --force to overwrite it")
    try:
        rep = recover_log(log_file, out_file)
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None
    how = "the input was complete" if rep.input_complete else f"the input ends early ({rep.cut_reason})"
    click.echo(f"recovered {rep.messages} messages on {rep.channels} channels and {rep.metadata} metadata "
               f"records into {rep.output}; {how}")


# --------------------------------------------------------------------------- replay


@click.command("replay")
@click.argument("log_file", metavar="LOG.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@_connect_options
@click.option("--rate", default=1.0, show_default=True, type=float,
              help="Speed factor on the recorded timing (2 = twice as fast).")
@click.option("--fast", is_flag=True, help="Publish as fast as possible (ignore the recorded timing).")
@click.option("--loop", is_flag=True, help="Start over at the end, until Ctrl-C.")
@click.option("--keys", "key_expr", default=None, metavar="KEYEXPR", help="Replay only keys matching this.")
def replay_cmd(log_file: Path, endpoint: str | None, config_file: Path | None, rate: float, fast: bool, loop: bool,
               key_expr: str | None) -> None:
    """Republish the recorded messages of LOG.mcap onto Zenoh at the recorded timing."""
    from .replay import replay_log

    if not fast and rate <= 0:
        raise click.BadParameter("must be > 0 (or use --fast)", param_hint="--rate")
    stop = threading.Event()
    with _session(endpoint, config_file) as session:
        try:
            result = replay_log(session, log_file, rate=None if fast else rate, loop=loop, key_expr=key_expr,
                                stop=stop)
        except KeyboardInterrupt:
            stop.set()
            click.echo("interrupted", err=True)
            return
        except CekmError as exc:
            raise click.ClickException(str(exc)) from None
    click.echo(f"published {result.published} messages on {len(result.per_key)} keys in {result.loops} loop(s), "
               f"{result.sim_seconds:.3f} s of sim time in {result.wall_seconds:.3f} s")


COMMANDS: list[click.Command] = [topic, log_group, replay_cmd]
"""The runtime's commands for the main CLI: ``for c in COMMANDS: main.add_command(c)``."""


# --------------------------------------------------------------------------- monitor


@click.command("monitor")
@_connect_options
@click.option("--root", default="cekm", show_default=True, help=_ROOT_HELP)
@click.option("--refresh", default=0.5, show_default=True, type=click.FloatRange(min=0.05), help="Seconds between redraws.")
@click.option("--once", "once_after", type=click.FloatRange(min=0.1), default=None, metavar="SECONDS",
              help="Watch for SECONDS, print one snapshot and exit (for scripts and pipes).")
def monitor(endpoint: str | None, config_file: Path | None, root: str, refresh: float, once_after: float | None) -> None:
    """A live view of a run: robots' poses, goals, status, modules alive, sense-to-command
    latency, and every key's rate and age. Attach from any terminal; Ctrl-C to leave."""
    from .monitor import run_monitor

    with _session(endpoint, config_file) as session:
        run_monitor(session, root=root, refresh=refresh, once_after=once_after, out=click.echo)


COMMANDS.append(monitor)
