"""Where a command connects, and waiting for the router to be there.

- :func:`resolve_endpoint`: the one rule every command follows for its Zenoh endpoint:
  an explicit ``--connect`` wins, then the ``CEKM_CONNECT`` environment variable, then
  the default (the launcher's embedded router, ``tcp/127.0.0.1:7447``).
- :func:`open_when_ready`: open a client session, and while nothing listens at the
  endpoint, say once "waiting for the router at ENDPOINT ..." and retry until a timeout,
  the way ``ros2 topic echo`` and ``z_sub`` wait instead of giving up. Other failures
  (refused credentials, a bad config) are not retried: waiting would not fix them.
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import zenoh

from .config import DEFAULT_ENDPOINT, check_endpoint, client_config, client_config_from_file, load_config, open_session
from .errors import RuntimeTransportError

ENV_CONNECT = "CEKM_CONNECT"
"""Environment variable naming the Zenoh endpoint of every command (below ``--connect``)."""

DEFAULT_WAIT = 60.0
"""Seconds a tool waits for the router before it gives up (``--wait``)."""

RETRY_PERIOD = 0.25
"""Seconds between two attempts to reach the router."""


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A resolved endpoint and where it came from (``--connect``, ``CEKM_CONNECT`` or ``default``)."""

    endpoint: str
    source: str

    @property
    def explicit(self) -> bool:
        """True when the user named it (option or environment), False for the default."""
        return self.source != "default"


def resolve_endpoint(connect: str | None, environ: Mapping[str, str] | None = None) -> Endpoint:
    """``--connect`` > ``CEKM_CONNECT`` > :data:`DEFAULT_ENDPOINT`, checked; a bad value is
    refused naming the option or the variable."""
    env = os.environ if environ is None else environ
    if connect:
        try:
            return Endpoint(check_endpoint(connect), "--connect")
        except RuntimeTransportError as exc:
            raise RuntimeTransportError(f"--connect: {exc}") from None
    value = env.get(ENV_CONNECT, "").strip()
    if value:
        try:
            return Endpoint(check_endpoint(value), ENV_CONNECT)
        except RuntimeTransportError as exc:
            raise RuntimeTransportError(f"{ENV_CONNECT}: {exc}") from None
    return Endpoint(DEFAULT_ENDPOINT, "default")


def _unreachable(exc: BaseException) -> bool:
    """True when opening failed because nothing accepts connections at the endpoint (worth
    retrying). A router that refuses the session (credentials, TLS) is told apart by
    :func:`~cekm_swarm.runtime.config.open_session`, whose message then says so."""
    text = str(exc)
    return "nothing accepts connections there" in text or (
        "Unable to connect" in text and "refused" not in text and "authentication failed" not in text)


def _refused_session(exc: BaseException) -> bool:
    """True when the endpoint accepted a TCP connection but Zenoh's session was refused
    without credentials (:func:`~cekm_swarm.runtime.config.open_session`'s wording)."""
    return "accepts connections but refused a Zenoh session" in str(exc)


def open_when_ready(make_config: Callable[[], zenoh.Config], endpoint: str, *, timeout: float = DEFAULT_WAIT,
                    say: Callable[[str], None] | None = None, stop: threading.Event | None = None,
                    what: str = "client session") -> zenoh.Session:
    """Open a session with a fresh ``make_config()``; while the router at ``endpoint`` is not
    up, call ``say("waiting for the router at ENDPOINT ...")`` once and retry every
    :data:`RETRY_PERIOD` s until ``timeout`` s have passed (0: one attempt) or ``stop`` is set.

    Raises :class:`RuntimeTransportError` naming the endpoint and the time waited."""
    t0 = time.monotonic()
    said = refused = False
    while True:
        try:
            return open_session(make_config(), what)
        except RuntimeTransportError as exc:
            if not _unreachable(exc):
                # a router that came up between Zenoh's attempt and the TCP probe that explains it
                # looks like one refusing the session: while waiting, ask once more before saying so
                if refused or timeout <= 0 or not _refused_session(exc):
                    raise
                refused = True
                time.sleep(0.2)
                continue
            waited = time.monotonic() - t0
            if waited >= timeout or (stop is not None and stop.is_set()):
                if timeout <= 0:
                    raise RuntimeTransportError(f"no router at {endpoint} (start a run, `cekm replay`, or "
                                                f"give --connect / {ENV_CONNECT})") from None
                raise RuntimeTransportError(f"no router at {endpoint} after waiting {waited:.0f} s (start a run, "
                                            f"`cekm replay`, or give --connect / {ENV_CONNECT})") from None
            if not said and say is not None:
                say(f"waiting for the router at {endpoint} ...")
                said = True
            pause = min(RETRY_PERIOD, max(0.0, timeout - waited))
            if stop is not None:
                stop.wait(pause)
            else:
                time.sleep(pause)


def open_tool_session(connect: str | None, config_file: str | Path | None = None, *, timeout: float = DEFAULT_WAIT,
                      say: Callable[[str], None] | None = None, stop: threading.Event | None = None) -> zenoh.Session:
    """The session of a command-line tool: endpoint by :func:`resolve_endpoint`, client
    config from ``config_file`` (credentials, TLS) or the defaults, waiting for the router."""
    ep = resolve_endpoint(connect)
    if config_file is not None and not ep.explicit:  # the file's own endpoint
        def make() -> zenoh.Config:
            return load_config(config_file)
        try:
            endpoint = ", ".join(json.loads(make().get_json("connect/endpoints"))) or ep.endpoint
        except Exception:
            endpoint = ep.endpoint
        return open_when_ready(make, endpoint, timeout=timeout, say=say, stop=stop)
    if config_file is not None:
        def make() -> zenoh.Config:
            return client_config_from_file(config_file, ep.endpoint)
    else:
        def make() -> zenoh.Config:
            return client_config(ep.endpoint)
    make()  # a bad config file fails here, before any waiting
    return open_when_ready(make, ep.endpoint, timeout=timeout, say=say, stop=stop)


def open_client_when_ready(endpoint: str, config_file: str | Path | None = None, *, timeout: float = DEFAULT_WAIT,
                           say: Callable[[str], None] | None = None,
                           stop: threading.Event | None = None) -> zenoh.Session:
    """A client session to ``endpoint`` (with ``config_file``'s credentials and TLS, if
    given), waiting for the router as :func:`open_when_ready` does: what a robots-only host
    started before the world host calls."""
    if config_file is not None:
        def make() -> zenoh.Config:
            return client_config_from_file(config_file, endpoint)
    else:
        def make() -> zenoh.Config:
            return client_config(endpoint)
    make()
    return open_when_ready(make, endpoint, timeout=timeout, say=say, stop=stop)
