"""Click commands of the operator tools, registered by the main CLI from :data:`COMMANDS`:

- ``topic list|echo|hz|info|pub``: inspect and drive a live (or replayed) run;
- ``node list``: the live module processes, from their liveliness tokens;
- ``log info|cat``: summarise or print an MCAP log; ``log recover IN OUT``: a complete,
  indexed copy of a log whose writer was killed;
- ``replay LOG.mcap``: republish a log (hosting the router itself unless told where to join);
- ``record [KEYEXPR] --out LOG.mcap``: record live keys like the world server's log;
- ``monitor``: a live view of a run.

Every networked command joins the endpoint given by ``--connect``, else the
``CEKM_CONNECT`` environment variable, else the launcher's embedded router
(``tcp/127.0.0.1:7447``), optionally with ``--config FILE`` (a Zenoh client config with
credentials or TLS, as in ``deploy/``), and waits for the router up to ``--wait`` seconds
with a "waiting for the router at ..." line. Data goes to stdout (``--json``: one JSON
object per line), waiting and progress lines to stderr. Exit codes: 0 done, 1 the
command failed, 2 bad usage, 130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click

from cekm_swarm.errors import CekmError

from cekm_swarm.cli_support import ENDPOINT, ROOT, Interrupted

from .wait import DEFAULT_WAIT, ENV_CONNECT

_ROOT_HELP = "Key-space root (docs/design.md section 6)."


def _connect_options(f: Callable[..., Any]) -> Callable[..., Any]:
    f = click.option("--wait", "wait_s", default=DEFAULT_WAIT, show_default=True, type=click.FloatRange(0.0),
                     help="Seconds to wait for the router before giving up (0: do not wait).")(f)
    f = click.option("--config", "config_file", type=click.Path(dir_okay=False, exists=True, path_type=Path),
                     default=None, help="Zenoh client config file (JSON5); --connect overrides its endpoint.")(f)
    f = click.option("--connect", "endpoint", default=None, metavar="ENDPOINT", type=ENDPOINT,
                     help=f"Zenoh endpoint to join [default: ${ENV_CONNECT}, else tcp/127.0.0.1:7447, the "
                          f"launcher's embedded router].")(f)
    return f


def _say(text: str) -> None:
    click.echo(text, err=True)


def _open(endpoint: str | None, config_file: Path | None, wait_s: float, stop: threading.Event | None = None):
    from .wait import open_tool_session, resolve_endpoint

    try:
        resolve_endpoint(endpoint)
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    try:
        return open_tool_session(endpoint, config_file, timeout=wait_s, say=_say, stop=stop)
    except CekmError as exc:
        raise click.ClickException(str(exc)) from None


@contextlib.contextmanager
def _session(endpoint: str | None, config_file: Path | None, wait_s: float = DEFAULT_WAIT) -> Iterator[Any]:
    try:
        session = _open(endpoint, config_file, wait_s)
    except KeyboardInterrupt:
        raise Interrupted() from None
    try:
        yield session
    finally:
        session.close()


@contextlib.contextmanager
def _sigint_sets(stop: threading.Event) -> Iterator[list[bool]]:
    """Within the block, Ctrl-C sets ``stop`` (the work ends cleanly) instead of raising;
    yields a flag list whose first item says whether it happened."""
    hit = [False]

    def handler(signum: int, frame: Any) -> None:
        hit[0] = True
        stop.set()

    try:
        old = signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread (tests): no handler
        yield hit
        return
    try:
        yield hit
    finally:
        signal.signal(signal.SIGINT, old)


def _keys(root: str):
    from cekm_swarm.protocol import KeySpace

    try:
        return KeySpace(root)
    except CekmError as exc:
        raise click.BadParameter(str(exc), param_hint="--root") from None


def _check_key_expr(key_expr: str, hint: str = "KEYEXPR") -> str:
    import zenoh

    try:
        zenoh.KeyExpr(key_expr)
    except Exception as exc:
        raise click.BadParameter(f"{key_expr!r} is not a Zenoh key expression: {str(exc).split(' at /')[0]}",
                                 param_hint=hint) from None
    return key_expr


# --------------------------------------------------------------------------- topic


@click.group("topic")
def topic() -> None:
    """Inspect and drive the keys of a live or replayed run (like ros2 topic)."""


@topic.command("list")
@_connect_options
@click.option("--window", default=2.0, show_default=True, type=click.FloatRange(0.05), help="Seconds to listen.")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--alive/--no-alive", default=True, show_default=True, help="Also list liveliness tokens.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per key.")
def topic_list_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, window: float, root: str,
                   alive: bool, as_json: bool) -> None:
    """Keys that carried messages during a listening window, with counts and rates."""
    from .jsonout import json_line
    from .topics import alive_tokens, topic_list

    keys = _keys(root)
    with _session(endpoint, config_file, wait_s) as session:
        try:
            seen = topic_list(session, keys.everything(), window)
            tokens = alive_tokens(session, keys.alive_all()) if alive else []
        except KeyboardInterrupt:
            raise Interrupted() from None
    if as_json:
        for key, (n, size) in seen.items():
            click.echo(json_line({"key": key, "messages": n, "rate_hz": n / window, "bytes_per_msg": size / max(n, 1)}))
        for t in tokens:
            click.echo(json_line({"token": t}))
        return
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
@click.option("--timeout", type=click.FloatRange(0.0), default=None,
              help="Stop after this many seconds of silence (default: wait for messages until Ctrl-C).")
@click.option("--full", is_flag=True, help="Print every field in full (arrays too), the message as JSON.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per message: key and message (or error).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
def topic_echo_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key_expr: str, count: int | None,
                   timeout: float | None, full: bool, as_json: bool, root: str) -> None:
    """Decode and print the messages on KEYEXPR (e.g. 'cekm/r1/cmd/wheels', 'cekm/r1/**')."""
    from .topics import echo

    _check_key_expr(key_expr)
    keys = _keys(root)
    with _session(endpoint, config_file, wait_s) as session:
        try:
            n = echo(session, key_expr, click.echo, count=count, timeout=timeout, full=full, keys=keys,
                     as_json=as_json, waiting=_say)
        except KeyboardInterrupt:
            raise Interrupted() from None
    if timeout is not None and (count is None or n < count):
        _say(f"({n} messages; stopped after {timeout:g} s of silence)")


@topic.command("hz")
@_connect_options
@click.argument("key_expr", metavar="KEYEXPR")
@click.option("--window", default=5.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds of arrivals the statistics cover.")
@click.option("--interval", default=1.0, show_default=True, type=click.FloatRange(0.05), help="Seconds between reports.")
@click.option("--duration", default=None, type=click.FloatRange(0.0), help="Stop after this many seconds.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per key and report.")
def topic_hz_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key_expr: str, window: float,
                 interval: float, duration: float | None, as_json: bool) -> None:
    """Rate, period jitter and age of the newest message of each key matching KEYEXPR."""
    from dataclasses import asdict

    from .jsonout import json_line
    from .topics import ArrivalLog, format_hz

    _check_key_expr(key_expr)
    stop = threading.Event()
    said = False
    with _session(endpoint, config_file, wait_s) as session, ArrivalLog(session, key_expr, window) as arrivals:
        t_end = None if duration is None else time.monotonic() + duration
        try:
            while not stop.is_set():
                left = None if t_end is None else t_end - time.monotonic()
                if left is not None and left <= 0:
                    break
                stop.wait(interval if left is None else min(interval, left))
                stats = arrivals.stats()
                if not stats:
                    if not said:
                        _say(f"waiting for messages on {key_expr} ...")
                        said = True
                    continue
                if as_json:
                    for s in stats:
                        click.echo(json_line(asdict(s)))
                else:
                    click.echo(format_hz(stats))
                    click.echo("")
        except KeyboardInterrupt:
            raise Interrupted() from None


@topic.command("info")
@_connect_options
@click.argument("key_expr", metavar="KEYEXPR")
@click.option("--window", default=2.0, show_default=True, type=click.FloatRange(0.1), help="Seconds to measure rates.")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--json", "as_json", is_flag=True, help="One JSON object: publishers, subscribers, rates.")
def topic_info_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key_expr: str, window: float,
                   root: str, as_json: bool) -> None:
    """Publishers and subscribers of KEYEXPR (from the router) and the rate of each key."""
    from dataclasses import asdict

    from .jsonout import json_line
    from .topics import ArrivalLog, format_endpoints, router_endpoints

    _check_key_expr(key_expr)
    keys = _keys(root)
    with _session(endpoint, config_file, wait_s) as session:
        try:
            with ArrivalLog(session, key_expr, window) as arrivals:
                ep = router_endpoints(session, key_expr, keys)
                threading.Event().wait(window)
                stats = arrivals.stats()
        except KeyboardInterrupt:
            raise Interrupted() from None
    if as_json:
        click.echo(json_line({"key_expr": key_expr, "publishers": None if ep is None else ep.publishers,
                              "subscribers": None if ep is None else ep.subscribers,
                              "keys": [asdict(s) for s in stats]}))
    else:
        click.echo(format_endpoints(ep, stats))


@topic.command("pub")
@_connect_options
@click.argument("key", metavar="KEY")
@click.argument("message", metavar="JSON")
@click.option("--count", "-n", default=1, show_default=True, type=click.IntRange(1), help="Messages to publish.")
@click.option("--rate", default=None, type=click.FloatRange(min=0.0, min_open=True), help="Messages per second.")
@click.option("--stamp", default=None, type=float, help="The messages' stamp, over the JSON's (default: the JSON's, else 0).")
@click.option("--wait-subscriber", default=5.0, show_default=True, type=click.FloatRange(0.0),
              help="Seconds to wait for a subscriber before publishing anyway.")
@click.option("--confirm-timeout", default=3.0, show_default=True, type=click.FloatRange(0.1),
              help="Seconds to wait for the messages to come back through the router.")
@click.option("--no-confirm", is_flag=True,
              help="Do not check that the router passed the messages on (needs no subscribe permission).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
def topic_pub_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key: str, message: str, count: int,
                  rate: float | None, stamp: float | None, wait_subscriber: float, confirm_timeout: float,
                  no_confirm: bool, root: str) -> None:
    """Publish a message on KEY, its fields as a JSON map, e.g.
    cekm topic pub cekm/r1/cmd/wheels '{"v_l": 0.05, "v_r": 0.05, "seq": 1}'.

    The message is validated as a receiver would. A router whose access control forbids
    this client to publish on KEY drops the message silently, so by default a second
    session with the same credentials listens on KEY and the command fails (exit 1) when
    the messages do not come back through the router."""
    from cekm_swarm.protocol import MessageError

    from .topics import build_message, publish

    keys = _keys(root)
    try:
        payload = build_message(key, message, keys, stamp=stamp)
    except MessageError as exc:
        raise click.BadParameter(str(exc), param_hint="KEY/JSON") from None
    stop = threading.Event()
    with _session(endpoint, config_file, wait_s) as session, _sigint_sets(stop) as hit:
        probe = None if no_confirm else _open(endpoint, config_file, wait_s, stop)
        try:
            res = publish(session, key, payload, count=count, rate=rate, probe=probe, stop=stop,
                          wait_subscriber=wait_subscriber, waiting=_say, confirm_timeout=confirm_timeout,
                          keys=keys)
        finally:
            if probe is not None:
                probe.close()
    if hit[0]:
        raise Interrupted(f"interrupted after {res.sent} message(s)")
    if res.confirmed is not None and res.confirmed < res.sent:
        raise click.ClickException(
            f"{key}: the router passed on {res.confirmed} of {res.sent} message(s): its access control forbids "
            f"this client to publish on {key} (or to subscribe to it, for the check; --no-confirm skips it)")
    note = "" if res.matched else " (no subscriber was listening)"
    click.echo(f"published {res.sent} message(s) on {key}{note}")


# --------------------------------------------------------------------------- node


@click.group("node")
def node() -> None:
    """The node processes of a run (like ros2 node)."""


@node.command("list")
@_connect_options
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--timeout", default=0.0, show_default=True, type=click.FloatRange(0.0),
              help="If none is alive yet, wait this many seconds for the first one.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per owner: alive and missing modules.")
def node_list_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, root: str, timeout: float,
                  as_json: bool) -> None:
    """Live nodes per robot (and the world server), from their liveliness tokens, against
    the nodes of the graph the run runs (which the world serves)."""
    from .jsonout import json_line
    from .nodes import format_nodes, group_tokens, wait_for_tokens

    from .rungraph import fetch_run_graph

    keys = _keys(root)
    with _session(endpoint, config_file, wait_s) as session:
        if timeout > 0:
            _say(f"waiting for live modules under {keys.alive_all()} ...")
        try:
            tokens = wait_for_tokens(session, keys, timeout)
        except KeyboardInterrupt:
            raise Interrupted() from None
        graph = fetch_run_graph(session, keys.world_graph()) if tokens else None
    groups, other = group_tokens(tokens, keys, None if graph is None else graph.nodes)
    if graph is not None and not as_json:
        click.echo(f"graph {graph.name} (controller {graph.controller}): {len(graph.nodes)} nodes per robot")
    if as_json:
        for g in groups:
            click.echo(json_line(g.as_dict()))
        for t in other:
            click.echo(json_line({"token": t}))
    else:
        click.echo(format_nodes(groups, other))


# --------------------------------------------------------------------------- log


@click.group("log")
def log_group() -> None:
    """MCAP run logs."""


@log_group.command("info")
@click.argument("log_file", metavar="LOG.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--recover", "recover_to", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="If the log is truncated (its writer was killed), write an indexed copy here.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object: file, completeness, channels.")
def log_info_cmd(log_file: Path, recover_to: Path | None, as_json: bool) -> None:
    """Channels, message counts, rates and duration of a log (a truncated log is read up to the cut)."""
    from dataclasses import asdict

    from .jsonout import json_line
    from .mcap_log import format_log_info, log_info, recover_log

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


@log_group.command("cat")
@click.argument("log_file", metavar="LOG.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--topics", "topics", multiple=True, metavar="KEYEXPR",
              help="Only these topics (key expressions; repeat or separate with commas).")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per message (topic, times, message).")
@click.option("--views", is_flag=True, help="Also list the Foxglove view messages (size only).")
@click.option("--start", type=float, default=None, help="Only messages at or after this sim time (s).")
@click.option("--end", type=float, default=None, help="Only messages at or before this sim time (s).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
def log_cat_cmd(log_file: Path, topics: tuple[str, ...], as_json: bool, views: bool, start: float | None,
                end: float | None, root: str) -> None:
    """Print a log's messages, decoded, in time order (like mcap cat, ros2 bag echo)."""
    from .logcat import CatCounts, cat_lines

    patterns = tuple(p.strip() for t in topics for p in t.split(",") if p.strip())
    for p in patterns:
        if not p.startswith("/"):
            _check_key_expr(p, "--topics")
    counts = CatCounts()
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


@contextlib.contextmanager
def _keyboard(control: Any, stop: threading.Event) -> Iterator[bool]:
    """On a terminal: space pauses and resumes the replay, q stops it. Yields whether active."""
    if not sys.stdin.isatty():
        yield False
        return
    import select
    import termios
    import tty

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


@click.command("replay")
@click.argument("log_file", metavar="LOG.mcap", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@_connect_options
@click.option("--port", default=None, type=click.IntRange(1, 65535),
              help="Port of the router the replay hosts on 127.0.0.1 [default: 7447] (when it joins none).")
@click.option("--rate", default=1.0, show_default=True, type=float,
              help="Speed factor on the recorded timing (2 = twice as fast).")
@click.option("--fast", is_flag=True, help="Publish as fast as possible (ignore the recorded timing).")
@click.option("--loop", is_flag=True, help="Start over at the end, until Ctrl-C.")
@click.option("--start", default=0.0, show_default=True, type=click.FloatRange(0.0),
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
    from .config import DEFAULT_HOST, DEFAULT_PORT, open_embedded_router
    from .replay import ReplayControl, replay_log, log_span
    from .wait import resolve_endpoint

    if not fast and rate <= 0:
        raise click.BadParameter("must be > 0 (or use --fast)", param_hint="--rate")
    if key_expr is not None:
        _check_key_expr(key_expr, "--keys")
    try:
        ep = resolve_endpoint(endpoint)
        span = log_span(log_file)
    except CekmError as exc:
        raise click.BadParameter(str(exc), param_hint="--connect" if endpoint else ENV_CONNECT) from None
    if span is not None and start > span[1] - span[0]:
        raise click.BadParameter(f"{start:g} s is past the log's end ({span[1] - span[0]:.3f} s long)",
                                 param_hint="--start")
    if start_paused and not sys.stdin.isatty():
        raise click.UsageError("--start-paused needs a terminal (space resumes the replay)")
    host_router = not ep.explicit and config_file is None
    if port is not None and not host_router:
        raise click.UsageError(f"--port is for the router the replay hosts; it joins {ep.endpoint} ({ep.source})")
    stop = threading.Event()
    control = ReplayControl()
    if start_paused:
        control.pause()
    if host_router:
        p = DEFAULT_PORT if port is None else port
        try:
            session = open_embedded_router(p)
        except CekmError as exc:
            raise click.ClickException(f"{exc} (a run or another replay holds port {p}? --port P hosts elsewhere, "
                                       f"--connect ENDPOINT joins that router)") from None
        _say(f"replay: hosting the router on tcp/{DEFAULT_HOST}:{p} (attach: cekm monitor"
             f"{'' if p == DEFAULT_PORT else f' --connect tcp/{DEFAULT_HOST}:{p}'})")
    else:
        try:
            session = _open(endpoint, config_file, wait_s)
        except KeyboardInterrupt:
            raise Interrupted() from None
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
    if hit[0]:
        raise Interrupted() from None


# --------------------------------------------------------------------------- record


@click.command("record")
@click.argument("key_expr", metavar="[KEYEXPR]", default=None, required=False)
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The MCAP file to write.")
@_connect_options
@click.option("--duration", default=None, type=click.FloatRange(0.0, min_open=True),
              help="Stop after this many seconds (default: Ctrl-C).")
@click.option("--count", "-n", default=None, type=click.IntRange(1), help="Stop after N messages.")
@click.option("--no-views", is_flag=True, help="Record the key-space channels only (no Foxglove views).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
def record_cmd(key_expr: str | None, out_path: Path, endpoint: str | None, config_file: Path | None, wait_s: float,
               duration: float | None, count: int | None, no_views: bool, root: str) -> None:
    """Record the live keys matching KEYEXPR (default: the whole key space) into an MCAP log
    with the channels and Foxglove views of the world server's own log (not the static
    scene, which the world does not publish). Ctrl-C stops and closes the file."""
    from .record import record
    from .wait import resolve_endpoint

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
        try:
            res = record(session, out_path, key_expr, keys=keys, stop=stop, duration=duration, count=count,
                         views=not no_views, on_first=first, on_progress=progress,
                         metadata={"endpoint": resolve_endpoint(endpoint).endpoint})
        except CekmError as exc:
            raise click.ClickException(str(exc)) from None
    if tty:
        sys.stderr.write("\n")
    span = "" if res.first_stamp is None else f", sim time {res.first_stamp:.3f} .. {res.last_stamp:.3f} s"
    bad = f", {res.malformed} malformed" if res.malformed else ""
    click.echo(f"recorded {res.messages} messages on {len(res.per_key)} keys{span}{bad} into {out_path}")
    if res.first_stamp is not None and keys.world_state() in res.per_key and not res.geometry:
        _say(f"no static scene in the recording: nothing answered on {keys.world_geometry()}")
    if hit[0]:
        raise Interrupted() from None


# --------------------------------------------------------------------------- monitor


@click.command("monitor")
@_connect_options
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--robot", "robots", multiple=True, metavar="ID", help="Show only this robot (repeat, or r1,r2).")
@click.option("--keys", "key_expr", default=None, metavar="KEYEXPR",
              help="List the rate and age of every key matching this (e.g. 'cekm/r1/**').")
@click.option("--refresh", default=0.5, show_default=True, type=click.FloatRange(min=0.05), help="Seconds between redraws.")
@click.option("--once", "once_after", type=click.FloatRange(min=0.1), default=None, metavar="SECONDS",
              help="Watch for SECONDS, print one snapshot and exit (for scripts and pipes).")
@click.option("--json", "as_json", is_flag=True, help="With --once: the snapshot as one JSON object.")
def monitor(endpoint: str | None, config_file: Path | None, wait_s: float, root: str, robots: tuple[str, ...],
            key_expr: str | None, refresh: float, once_after: float | None, as_json: bool) -> None:
    """A live view of a run (80 columns): the run's phase, robots' poses, goals, status,
    commands, modules alive and sense-to-command latency; --keys adds per-key rates.
    Attach from any terminal, before or after the run starts; Ctrl-C to leave."""
    from .logcat import key_filter
    from .monitor import run_monitor
    from .wait import resolve_endpoint

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
