"""What every operator tool's command shares: the ``--connect``/``--config``/``--wait``
options, a session that waits for the router, SIGINT handling, the key space and key
expressions checked. Every networked command joins the endpoint given by ``--connect``,
else the ``CEKM_CONNECT`` environment variable, else the launcher's embedded router
(``tcp/127.0.0.1:7447``), optionally with ``--config FILE`` (a Zenoh client config with
credentials or TLS, as in ``deploy/``), and waits for the router up to ``--wait`` seconds
with a "waiting for the router at ..." line. Data goes to stdout (``--json``: one JSON
object per line), waiting and progress lines to stderr. Exit codes: 0 done, 1 the command
failed, 2 bad usage, 130 interrupted (Ctrl-C)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click
import zenoh

from cekm_swarm.cli_support import Finite, Interrupted
from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import KeySpace

from .options import ENDPOINT
from .wait import DEFAULT_WAIT, ENV_CONNECT, open_tool_session, resolve_endpoint

_ROOT_HELP = "Key-space root (docs/design.md section 6)."

def _connect_options(f: Callable[..., Any]) -> Callable[..., Any]:
    f = click.option("--wait", "wait_s", default=DEFAULT_WAIT, show_default=True, type=Finite(0.0),
                     help="Seconds to wait for the router before giving up (0: do not wait).")(f)
    f = click.option("--config", "config_file", type=click.Path(dir_okay=False, exists=True, path_type=Path),
                     default=None, help="Zenoh client config file (JSON5); --connect overrides its endpoint.")(f)
    f = click.option("--connect", "endpoint", default=None, metavar="ENDPOINT", type=ENDPOINT,
                     help=f"Zenoh endpoint to join [default: ${ENV_CONNECT}, else tcp/127.0.0.1:7447, the "
                          f"launcher's embedded router].")(f)
    return f


def _say(text: str) -> None:
    click.echo(text, err=True)


def _open(endpoint: str | None, config_file: Path | None, wait_s: float,
          stop: threading.Event | None = None) -> zenoh.Session:
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


def _keys(root: str) -> KeySpace:
    try:
        return KeySpace(root)
    except CekmError as exc:
        raise click.BadParameter(str(exc), param_hint="--root") from None


def _check_key_expr(key_expr: str, hint: str = "KEYEXPR") -> str:
    try:
        zenoh.KeyExpr(key_expr)
    except Exception as exc:
        raise click.BadParameter(f"{key_expr!r} is not a Zenoh key expression: {str(exc).split(' at /')[0]}",
                                 param_hint=hint) from None
    return key_expr


# --------------------------------------------------------------------------- topic

