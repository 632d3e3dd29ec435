"""``cekm log info|cat|recover`` (summarise, print, or repair an MCAP log), ``cekm replay``
(republish a log, hosting the router itself unless told where to join) and ``cekm
record`` (record live keys like the world server's log)."""

from __future__ import annotations

import contextlib
import select
import signal
import sys
import termios
import threading
import tty
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

from cekm_swarm.cli_support import ROOT, SIZE, Finite, Interrupted
from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import DEFAULT_ROOT

from .config import DEFAULT_HOST, DEFAULT_PORT, open_embedded_router
from .jsonout import json_line
from .mcap_log import format_log_info, log_info, log_root, recover_log
from .mcap_sets import log_files, set_file
from .replay import MAX_GAP_S, ReplayControl, log_span, replay_log
from .tool_session import _ROOT_HELP, _check_key_expr, _connect_options, _keys, _open, _say, _session, _sigint_sets
from .wait import ENV_CONNECT, resolve_endpoint


@click.group("log")
def log_group() -> None:
    """MCAP run logs."""


def _refuse_existing(out: Path, force: bool, files: list[Path] | None = None) -> None:
    """An output log that exists is refused unless ``--force``: a log cannot be made again.
    ``files``: the existing files the output would replace (default: ``out`` if it exists)."""
    files = ([out] if out.exists() else []) if files is None else files
    if files and not force:
        what = f"{out}: exists" if files == [out] else f"{files[0]} .. {files[-1].name}: a log set exists there"
        raise click.ClickException(f"{what}; use --force to overwrite it")


LOG_HELP = ("LOG is an .mcap file, or a log set (split with --max-log-size/--max-log-duration): its directory "
            "or its first file (run_0.mcap), read as one log in time order.")


@log_group.command("info", epilog=LOG_HELP)
@click.argument("log_file", metavar="LOG", type=click.Path(exists=True, path_type=Path))
@click.option("--recover", "recover_to", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="If the log is truncated (its writer was killed), write an indexed copy here.")
@click.option("--force", is_flag=True, help="Overwrite the --recover file if it exists.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object: file, completeness, channels.")
def log_info_cmd(log_file: Path, recover_to: Path | None, force: bool, as_json: bool) -> None:
    """Channels, message counts, rates and duration of a log (a truncated log is read up to the cut)."""
    if recover_to is not None and log_file.is_dir():
        raise click.BadParameter("--recover takes one file (a log set's files are recovered one by one)",
                                 param_hint="LOG")
    if recover_to is not None:
        _refuse_existing(recover_to, force)
    try:
        info = log_info(log_file)
        if as_json:
            doc = asdict(info)
            doc["path"] = str(info.path)
            click.echo(json_line(doc))
        else:
            click.echo(format_log_info(info))
        if recover_to is not None:
            if info.complete:
                _say("log is complete; nothing to recover")
            else:
                rep = recover_log(log_file, recover_to)
                _say(f"recovered {rep.messages} messages on {rep.channels} channels into {rep.output}")
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None


@log_group.command("cat", epilog=LOG_HELP)
@click.argument("log_file", metavar="LOG", type=click.Path(exists=True, path_type=Path))
@click.option("--topics", "topics", multiple=True, metavar="KEYEXPR",
              help="Only these topics (key expressions; repeat or separate with commas).")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per message (topic, times, message).")
@click.option("--views", is_flag=True, help="Also list the Foxglove view messages (size only).")
@click.option("--start", type=Finite(), default=None, help="Only messages at or after this sim time (s).")
@click.option("--end", type=Finite(), default=None, help="Only messages at or before this sim time (s).")
@click.option("--root", default=None, type=ROOT,
              help="Key-space root (docs/design.md section 6) [default: the log's own, else cekm].")
def log_cat_cmd(log_file: Path, topics: tuple[str, ...], as_json: bool, views: bool, start: float | None,
                end: float | None, root: str | None) -> None:
    """Print a log's messages, decoded, in time order (like mcap cat, ros2 bag echo)."""
    from .logcat import CatCounts, cat_lines  # noqa: PLC0415 -- lazy: cekm --help loads no log reader

    if start is not None and end is not None and end < start:
        raise click.UsageError(f"--end {end:g} is before --start {start:g}: no message can be in that window")
    patterns = tuple(p.strip() for t in topics for p in t.split(",") if p.strip())
    for p in patterns:
        if not p.startswith("/"):
            _check_key_expr(p, "--topics")
    counts = CatCounts()
    if root is None:  # the root the log was written under (a run launched with --root run2)
        root = log_root(log_file) or DEFAULT_ROOT
    try:
        for line in cat_lines(log_file, topics=patterns or None, as_json=as_json, views=views, start=start, end=end,
                              keys=_keys(root), counts=counts):
            click.echo(line)
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None
    except BrokenPipeError:  # `| head`
        sys.stderr.close()
        return
    if counts.malformed:
        _say(f"{counts.malformed} malformed message(s) in the log (printed as errors)")


@log_group.command("recover")
@click.argument("log_file", metavar="IN.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.argument("out_file", metavar="OUT.mcap", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--force", is_flag=True, help="Overwrite OUT.mcap if it exists.")
def log_recover_cmd(log_file: Path, out_file: Path, force: bool) -> None:
    """Copy every complete message (and metadata) of IN.mcap, e.g. a log whose writer was
    killed, into OUT.mcap, a complete, indexed file."""
    _refuse_existing(out_file, force)
    try:
        rep = recover_log(log_file, out_file)
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None
    how = "the input was complete" if rep.input_complete else f"the input ends early ({rep.cut_reason})"
    click.echo(f"recovered {rep.messages} messages on {rep.channels} channels and {rep.metadata} metadata "
               f"records into {rep.output}; {how}")


# --------------------------------------------------------------------------- replay


@contextlib.contextmanager
def _keyboard(control: Any, stop: threading.Event) -> Iterator[bool]:
    """On a terminal: space pauses and resumes the replay, q stops it. Yields whether active."""
    if not sys.stdin.isatty():
        yield False
        return
    fd = sys.stdin.fileno()
    try:
        saved = termios.tcgetattr(fd)
    except termios.error:
        yield False
        return
    done = threading.Event()

    def read() -> None:
        while not done.is_set() and not stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if not ready:
                continue
            ch = sys.stdin.read(1)
            if ch == " ":
                control.toggle()
            elif ch in ("q", "Q"):
                stop.set()
                control.resume()

    tty.setcbreak(fd)
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        yield True
    finally:
        done.set()
        reader.join(1.0)
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


@click.command("replay", epilog=LOG_HELP)
@click.argument("log_file", metavar="LOG", type=click.Path(exists=True, path_type=Path))
@_connect_options
@click.option("--port", default=None, type=click.IntRange(1, 65535),
              help="Port of the router the replay hosts on 127.0.0.1 [default: 7447] (when it joins none).")
@click.option("--rate", default=1.0, show_default=True, type=Finite(),
              help="Speed factor on the recorded timing (2 = twice as fast).")
@click.option("--fast", is_flag=True, help="Publish as fast as possible (ignore the recorded timing).")
@click.option("--loop", is_flag=True, help="Start over at the end, until Ctrl-C.")
@click.option("--start", default=0.0, show_default=True, type=Finite(0.0),
              help="Skip this many seconds from the log's start.")
@click.option("--keys", "key_expr", default=None, metavar="KEYEXPR", help="Replay only keys matching this.")
@click.option("--start-paused", is_flag=True, help="Wait for a key press (space) before the first message.")
@click.option("--quiet", is_flag=True, help="No progress line.")
def replay_cmd(log_file: Path, endpoint: str | None, config_file: Path | None, wait_s: float, port: int | None,
               rate: float, fast: bool, loop: bool, start: float, key_expr: str | None, start_paused: bool,
               quiet: bool) -> None:
    """Republish the recorded messages of LOG.mcap onto Zenoh at the recorded timing.

    With no --connect (and no CEKM_CONNECT, no --config) the replay hosts the router itself
    on tcp/127.0.0.1:7447 (--port), where `cekm monitor` and `cekm topic` find it. On a
    terminal, space pauses and resumes, q stops."""
    host_router = _check_replay(log_file, endpoint, config_file, port, rate, fast, start, key_expr, start_paused)
    stop = threading.Event()
    control = ReplayControl()
    if start_paused:
        control.pause()
    session = _host_router(port) if host_router else _replay_session(endpoint, config_file, wait_s)
    tty = sys.stderr.isatty() and not quiet
    width = [0]

    def progress(p: Any) -> None:
        line = p.line()
        sys.stderr.write("\r" + line + " " * max(0, width[0] - len(line)))
        sys.stderr.flush()
        width[0] = len(line)

    try:
        with _sigint_sets(stop) as hit, _keyboard(control, stop) as keyboard:
            if keyboard and tty:
                _say("space: pause/resume, q: stop")
            result = replay_log(session, log_file, rate=None if fast else rate, loop=loop, key_expr=key_expr,
                                stop=stop, start=start, control=control, on_progress=progress if tty else None)
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        session.close()
        if tty and width[0]:
            sys.stderr.write("\n")
    click.echo(f"published {result.published} messages on {len(result.per_key)} keys in {result.loops} loop(s), "
               f"{result.sim_seconds:.3f} s of sim time in {result.wall_seconds:.3f} s")
    if result.jumped:
        _say(f"replay: did not wait across {result.jumped} gap(s) of more than {MAX_GAP_S:g} s of sim time "
             f"between two messages (log times no run reaches: stamps its recorder should not have kept)")
    if hit[0]:
        raise Interrupted() from None


def _check_replay(log_file: Path, endpoint: str | None, config_file: Path | None, port: int | None, rate: float,
                  fast: bool, start: float, key_expr: str | None, start_paused: bool) -> bool:
    """Refuse a replay's bad options before anything starts; whether it hosts the router."""
    if not fast and rate <= 0:
        raise click.BadParameter("must be > 0 (or use --fast)", param_hint="--rate")
    if key_expr is not None:
        _check_key_expr(key_expr, "--keys")
    try:
        ep = resolve_endpoint(endpoint)
    except CekmError as exc:
        raise click.BadParameter(str(exc), param_hint="--connect" if endpoint else ENV_CONNECT) from None
    try:
        span = log_span(log_file)
    except CekmError as exc:  # a log it cannot read: a failure (exit 1), as in `cekm log info`
        raise click.ClickException(str(exc)) from None
    if span is not None and start > span[1] - span[0]:
        raise click.BadParameter(f"{start:g} s is past the log's end ({span[1] - span[0]:.3f} s long)",
                                 param_hint="--start")
    if start_paused and not sys.stdin.isatty():
        raise click.UsageError("--start-paused needs a terminal (space resumes the replay)")
    host_router = not ep.explicit and config_file is None
    if port is not None and not host_router:
        raise click.UsageError(f"--port is for the router the replay hosts; it joins {ep.endpoint} ({ep.source})")
    return host_router


def _host_router(port: int | None) -> Any:
    """The router a replay hosts on 127.0.0.1 (``--port``, default 7447), said on stderr."""
    p = DEFAULT_PORT if port is None else port
    try:
        session = open_embedded_router(p)
    except CekmError as exc:
        raise click.ClickException(f"{exc} (a run or another replay holds port {p}? --port P hosts elsewhere, "
                                   f"--connect ENDPOINT joins that router)") from None
    _say(f"replay: hosting the router on tcp/{DEFAULT_HOST}:{p} (attach: cekm monitor"
         f"{'' if p == DEFAULT_PORT else f' --connect tcp/{DEFAULT_HOST}:{p}'})")
    return session


def _replay_session(endpoint: str | None, config_file: Path | None, wait_s: float) -> Any:
    """A session joining the router ``--connect`` (or the config file) names."""
    try:
        return _open(endpoint, config_file, wait_s)
    except KeyboardInterrupt:
        raise Interrupted() from None


# --------------------------------------------------------------------------- record


@contextlib.contextmanager
def _sigterm_as_sigint() -> Iterator[None]:
    """Within the block SIGTERM does what Ctrl-C does at that moment (waiting for the
    router: end; recording: stop, close the file, print the summary), instead of killing
    the process and leaving an MCAP file without its summary. It is never ignored: a
    command started in the background by a shell has SIGINT ignored, SIGTERM still ends it."""

    def handler(signum: int, frame: Any) -> None:
        on_int = signal.getsignal(signal.SIGINT)
        if callable(on_int) and on_int is not signal.default_int_handler:
            on_int(signal.SIGINT, frame)  # the recording's own: stop cleanly
        else:
            raise KeyboardInterrupt

    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (tests): no handler
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@click.command("record")
@click.argument("key_expr", metavar="[KEYEXPR]", default=None, required=False)
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The MCAP file to write.")
@_connect_options
@click.option("--duration", default=None, type=Finite(0.0, min_open=True),
              help="Stop after this many seconds (default: Ctrl-C).")
@click.option("--count", "-n", default=None, type=click.IntRange(1), help="Stop after N messages.")
@click.option("--no-views", is_flag=True, help="Record the key-space channels only (no Foxglove views).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--max-log-size", type=SIZE, metavar="SIZE",
              help="Split the recording into a set, LOG_0.mcap, LOG_1.mcap, ..., a new file once one holds SIZE "
                   "(500M, 2G, ...).")
@click.option("--max-log-duration", type=Finite(0.0, min_open=True), metavar="S",
              help="Split the recording into a set: a new file every S s of sim time.")
@click.option("--force", is_flag=True, help="Overwrite the --out log (or set) if it exists.")
def record_cmd(key_expr: str | None, out_path: Path, endpoint: str | None, config_file: Path | None, wait_s: float,
               duration: float | None, count: int | None, no_views: bool, root: str, max_log_size: int | None,
               max_log_duration: float | None, force: bool) -> None:
    """Record the live keys matching KEYEXPR (default: the whole key space) into an MCAP log
    with the channels and Foxglove views of the world server's own log, and the static
    scene, which it asks the world server for. Ctrl-C or SIGTERM stops and closes the file.
    A message whose stamp is not believable (not a tick's sim time in [0, 1e7] s, or more
    than 8 ticks from the newest taken) is dropped and counted, as in the world's own log."""
    first = set_file(out_path, 0)
    split = max_log_size is not None or max_log_duration is not None
    old = (log_files(first) if first.is_file() else []) if split else ([out_path] if out_path.exists() else [])
    _refuse_existing(out_path, force, old)  # before waiting for the router
    with _sigterm_as_sigint():
        _record(key_expr, out_path, endpoint, config_file, wait_s, duration, count, no_views, root, max_log_size,
                max_log_duration, [p for p in old if p != out_path])


def _record(key_expr: str | None, out_path: Path, endpoint: str | None, config_file: Path | None, wait_s: float,
            duration: float | None, count: int | None, no_views: bool, root: str, max_log_size: int | None,
            max_log_duration: float | None, replaced: list[Path]) -> None:
    from .record import record  # noqa: PLC0415 -- lazy: cekm --help loads no recorder

    keys = _keys(root)
    key_expr = _check_key_expr(key_expr or keys.everything())
    stop = threading.Event()
    tty = sys.stderr.isatty()

    def first() -> None:
        if tty:
            sys.stderr.write("\r" + " " * 60 + "\r")
        _say(f"recording {key_expr} into {out_path}")

    def progress(r: Any) -> None:
        if tty:
            sim = "" if r.last_stamp is None else f", sim {r.last_stamp:.2f} s"
            sys.stderr.write(f"\r{r.messages} messages on {len(r.per_key)} keys{sim}   ")
            sys.stderr.flush()

    with _session(endpoint, config_file, wait_s) as session, _sigint_sets(stop) as hit:
        _say(f"waiting for messages on {key_expr} ...")
        for p in replaced:  # --force over a set: its old files go, so the new set holds only this recording
            p.unlink(missing_ok=True)
        try:
            res = record(session, out_path, key_expr, keys=keys, stop=stop, duration=duration, count=count,
                         views=not no_views, on_first=first, on_progress=progress,
                         metadata={"endpoint": resolve_endpoint(endpoint).endpoint}, max_bytes=max_log_size,
                         max_seconds=max_log_duration)
        except CekmError as exc:
            raise click.ClickException(str(exc)) from None
    if tty:
        sys.stderr.write("\n")
    span = "" if res.first_stamp is None else f", sim time {res.first_stamp:.3f} .. {res.last_stamp:.3f} s"
    bad = f", {res.malformed} malformed" if res.malformed else ""
    bad += f", {res.dropped} dropped (stamp not believable)" if res.dropped else ""
    into = out_path if len(res.files) <= 1 else f"{res.files[0]} .. {res.files[-1].name} ({len(res.files)} files)"
    click.echo(f"recorded {res.messages} messages on {len(res.per_key)} keys{span}{bad} into {into}")
    if res.first_stamp is not None and keys.world_state() in res.per_key and not res.geometry:
        _say(f"no static scene in the recording: nothing answered on {keys.world_geometry()}")
    if hit[0]:
        raise Interrupted() from None


# --------------------------------------------------------------------------- monitor

