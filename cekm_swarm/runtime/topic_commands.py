"""``cekm topic list|echo|hz|info|pub`` (inspect and drive a live or replayed run) and
``cekm node list`` (the live node processes, from their liveliness tokens, against the
run's graph)."""

from __future__ import annotations

import threading
import time
from dataclasses import asdict
from pathlib import Path

import click

from cekm_swarm.cli_support import ROOT, Finite, Interrupted
from cekm_swarm.protocol import MessageError

from .jsonout import json_line
from .tool_session import _ROOT_HELP, _check_key_expr, _connect_options, _keys, _open, _say, _session, _sigint_sets


@click.group("topic")
def topic() -> None:
    """Inspect and drive the keys of a live or replayed run (like ros2 topic)."""


@topic.command("list")
@_connect_options
@click.option("--window", default=2.0, show_default=True, type=Finite(0.05), help="Seconds to listen.")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--alive/--no-alive", default=True, show_default=True, help="Also list liveliness tokens.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per key.")
def topic_list_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, window: float, root: str,
                   alive: bool, as_json: bool) -> None:
    """Keys that carried messages during a listening window, with counts and rates."""
    from .topics import alive_tokens, topic_list  # noqa: PLC0415 -- lazy: cekm --help loads no topic tools

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
@click.option("--timeout", type=Finite(0.0), default=None,
              help="Stop after this many seconds of silence (default: wait for messages until Ctrl-C).")
@click.option("--full", is_flag=True, help="Print every field in full (arrays too), the message as JSON.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per message: key and message (or error).")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
def topic_echo_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key_expr: str, count: int | None,
                   timeout: float | None, full: bool, as_json: bool, root: str) -> None:
    """Decode and print the messages on KEYEXPR (e.g. 'cekm/r1/cmd/wheels', 'cekm/r1/**')."""
    from .topics import echo  # noqa: PLC0415 -- lazy: cekm --help loads no topic tools

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
@click.option("--window", default=5.0, show_default=True, type=Finite(0.1),
              help="Seconds of arrivals the statistics cover.")
@click.option("--interval", default=1.0, show_default=True, type=Finite(0.05), help="Seconds between reports.")
@click.option("--duration", default=None, type=Finite(0.0), help="Stop after this many seconds.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per key and report.")
def topic_hz_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key_expr: str, window: float,
                 interval: float, duration: float | None, as_json: bool) -> None:
    """Rate, period jitter and age of the newest message of each key matching KEYEXPR."""
    from .topics import ArrivalLog, format_hz  # noqa: PLC0415 -- lazy: cekm --help loads no topic tools

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
@click.option("--window", default=2.0, show_default=True, type=Finite(0.1), help="Seconds to measure rates.")
@click.option("--root", default="cekm", show_default=True, type=ROOT, help=_ROOT_HELP)
@click.option("--json", "as_json", is_flag=True, help="One JSON object: publishers, subscribers, rates.")
def topic_info_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, key_expr: str, window: float,
                   root: str, as_json: bool) -> None:
    """Publishers and subscribers of KEYEXPR (from the router) and the rate of each key."""
    from .topics import ArrivalLog, format_endpoints, router_endpoints  # noqa: PLC0415 -- lazy: cekm --help loads no topic tools

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
@click.option("--rate", default=None, type=Finite(min=0.0, min_open=True), help="Messages per second.")
@click.option("--stamp", default=None, type=Finite(),
              help="The messages' stamp, over the JSON's (default: the JSON's, else 0).")
@click.option("--wait-subscriber", default=5.0, show_default=True, type=Finite(0.0),
              help="Seconds to wait for a subscriber before publishing anyway.")
@click.option("--confirm-timeout", default=3.0, show_default=True, type=Finite(0.1),
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
    from .topics import build_message, publish  # noqa: PLC0415 -- lazy: cekm --help loads no topic tools

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
@click.option("--timeout", default=0.0, show_default=True, type=Finite(0.0),
              help="If none is alive yet, wait this many seconds for the first one.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per owner: alive and missing modules.")
def node_list_cmd(endpoint: str | None, config_file: Path | None, wait_s: float, root: str, timeout: float,
                  as_json: bool) -> None:
    """Live nodes per robot (and the world server), from their liveliness tokens, against
    the nodes of the graph the run runs (which the world serves)."""
    from .nodes import format_nodes, group_tokens, wait_for_tokens  # noqa: PLC0415 -- lazy: cekm --help loads no node tools
    from .rungraph import fetch_run_graph  # noqa: PLC0415 -- lazy: cekm --help loads no run-graph reader

    keys = _keys(root)
    with _session(endpoint, config_file, wait_s) as session:
        if timeout > 0:
            _say(f"waiting for live modules under {keys.alive_all()} ...")
        try:
            tokens = wait_for_tokens(session, keys, timeout)
        except KeyboardInterrupt:
            raise Interrupted() from None
        graph = fetch_run_graph(session, keys.world_graph()) if tokens else None
    groups, other = group_tokens(tokens, keys, None if graph is None else graph.nodes,
                                 () if graph is None else graph.team)
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

