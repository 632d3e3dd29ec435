"""Zenoh configurations and session opening: the embedded router and clients.

The embedded default needs no ``zenohd`` binary: a router session is opened in-process
from the Python wheel (``mode: router``) and module processes join it as clients.
Multicast scouting is always off, so parallel runs (and tests) on one machine never
find each other; every connection is an explicit endpoint.
"""

from __future__ import annotations

import ipaddress
import json
import os
import random
import re
import socket
from pathlib import Path

import zenoh

from .errors import RuntimeTransportError

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 7447
DEFAULT_ENDPOINT = f"tcp/{DEFAULT_HOST}:{DEFAULT_PORT}"
"""Where the launcher's embedded router listens, and where tools connect by default."""


ONE_THREAD_RUNTIME = "(rx: (handover: app), tx: (handover: app), net: (handover: app), acc: (handover: app))"
"""Zenoh's runtimes all on one worker thread (the value of Zenoh's ``ZENOH_RUNTIME``
variable, read once, when a process opens its first session; the default is five
runtimes on six threads). A module process receives one message and sends one per
period: each hand-off between Zenoh's receiving, sending and timer threads is a thread
wake-up, which costs more than the work it hands over on this 2-core machine
(``benchmarks/bench_runtime.py``)."""

LOCKSTEP_MODULE_RUNTIME = "(rx: (handover: app), net: (handover: app), acc: (handover: app), app: (worker_threads: 1))"
"""A module's Zenoh in lockstep: :data:`ONE_THREAD_RUNTIME` with sending on a thread of
its own. In lockstep a module publishes with congestion control BLOCK from Zenoh's
receiving callback. With sending on that same thread, a put that found the send queue
full waited for the one thread that would empty it: a burst of well-formed readings for
the current tick (300 back to back, as any peer on the key can send) closed the module's
session after 5 s, and the run re-published 26 ticks (docs/robustness.md). The sending
thread costs a wake-up per message sent: about 0.9 ms more CPU per tick for one robot's
14 modules (5.1 -> 6.0 ms, three runs each in alternation, ``benchmarks/bench_runtime.py
--module-runtime``) with no change in lockstep speed. In real time modules publish with
congestion control DROP, which waits at most 1 ms for room (Zenoh's ``wait_before_drop``)
and then drops the message, and keep :data:`ONE_THREAD_RUNTIME`."""

ROUTER_RUNTIME = "(rx: (handover: app), net: (handover: app), acc: (handover: app), app: (worker_threads: 2))"
"""Zenoh's runtimes in the world server when it hosts the router on loopback: receiving,
timers and accepting on one runtime with two worker threads, sending on a thread of its
own. A message's routing is done on one thread, so a tick costs the router about 15
thread wake-ups instead of 35 with Zenoh's default threads. The second worker is there for Zenoh's
blocking steps: with a single thread, a client that goes silent without closing (a
stopped ``cekm topic echo``) froze all routing for 10 s when its lease expired, and a
real-time run's robots were stopped by the dead-man
(``tests/runtime/test_launch_stalled_client.py``).

Sending stays apart. A router forwards a message into the receiver's send queue (two
64 KB batches) on the thread that received it, and waits there while the queue is full
until the sending task has written a batch out. With sending handed to the same two
workers, two such waits took both (a burst of 128 KB towards one module: four 32 KB
messages or 200 of 1 KB; or one message Zenoh cut into fragments), nothing was sent any
more, and after 5 s Zenoh closed the module's session ("Unable to push non droppable
network message ... Closing transport"): the run stalled 5-10 s at a time and the
messages were lost (``benchmarks/bench_large_messages.py``, docs/robustness.md). The
sending thread cost nothing measurable (docs/performance.md). A router serving other
hosts keeps Zenoh's default threads."""

MAX_MESSAGE_BYTES = 32 * 1024
"""The largest message the runtime's Zenoh carries: payload plus attachment, in bytes
(inclusive). The largest legitimate one is the served model's reply (the R15 model file,
18,441 bytes, and its 64-byte digest); every other message of a run is under 4 KB (a
tracking field of 6 robots and 10 targets, 3.8 KB; the largest scene, 4.0 KB). Half of
Zenoh's 64 KB batch: no message anyone may send is cut into fragments, and none costs a
receiver more than 32 KB of memory and decoding. Before this limit (and before
:data:`ROUTER_RUNTIME` kept sending apart), ten messages of 100 KB or 1 MB on a module's
key made a 313-tick lockstep run last 70-116 s instead of 2-11 s, and none of them was
delivered (``benchmarks/bench_large_messages.py``, docs/robustness.md).

Every router the runtime opens drops a bigger message as it comes in
(:func:`message_size_limits`), before any subscriber, the world's recorder included, sees
it; Zenoh counts no such drop. Every process also refuses to reassemble a fragmented
message over this size (bounded memory whatever a router forwards). A model file over
it cannot be served (:class:`cekm_swarm.runtime.model_service.ModelServer` says so)."""


def message_size_limits(config: zenoh.Config, *, router: bool) -> None:
    """Apply :data:`MAX_MESSAGE_BYTES`: at a router, a low-pass filter on every message
    coming in (put, delete, query, reply; any key); everywhere, Zenoh's reassembly buffer
    (``transport/link/rx/max_message_size``) unless the config sets a smaller one."""
    try:
        own = int(json.loads(config.get_json("transport/link/rx/max_message_size")))
    except Exception:
        own = None
    if own is None or own > MAX_MESSAGE_BYTES:
        _insert(config, "transport/link/rx/max_message_size", MAX_MESSAGE_BYTES)
    if router:
        _insert(config, "low_pass_filter", [{
            "id": "max-message-size", "flows": ["ingress"], "messages": ["put", "delete", "query", "reply"],
            "key_exprs": ["**"], "size_limit": MAX_MESSAGE_BYTES}])


def use_zenoh_runtime(spec: str) -> None:
    """Run this process's Zenoh as ``spec`` says (:data:`ONE_THREAD_RUNTIME`,
    :data:`ROUTER_RUNTIME`), unless ``ZENOH_RUNTIME`` is already set; call before the
    first session opens."""
    os.environ.setdefault("ZENOH_RUNTIME", spec)


EPHEMERAL_RANGE = Path("/proc/sys/net/ipv4/ip_local_port_range")
"""Where Linux keeps the range its outgoing connections take their source ports from."""


def ephemeral_ports(path: Path = EPHEMERAL_RANGE) -> tuple[int, int]:
    """The kernel's ephemeral port range (first, last); Linux's default where unreadable."""
    try:
        first, last = (int(v) for v in path.read_text().split())
    except (OSError, ValueError):
        return 32768, 60999
    return first, last


def _bindable(host: str, port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def free_port(host: str = DEFAULT_HOST, tries: int = 200) -> int:
    """A TCP port free on ``host`` right now (bound and released; for tests and launchers).

    Drawn at random from outside the kernel's ephemeral range: a port from inside it (what
    binding port 0 gives) can be taken, between its release and its use, as the source port
    of any outgoing connection -- a client retrying to reach that very port included, which
    then connects to itself and keeps the port from the router meant to listen there."""
    first, last = ephemeral_ports()
    pool = [*range(10000, max(10000, first)), *range(max(10000, last + 1), 65536)]
    rng = random.Random(os.urandom(8))  # not the caller's random state
    for port in rng.sample(pool, min(tries, len(pool))):
        if _bindable(host, port):
            return port
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:  # nothing outside is free
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _insert(config: zenoh.Config, path: str, value: object) -> None:
    try:
        config.insert_json5(path, json.dumps(value))
    except Exception as exc:  # zenoh raises ZError with the reason
        raise RuntimeTransportError(f"zenoh config: cannot set '{path}' to {value!r}: {exc}") from None


def _common(config: zenoh.Config) -> None:
    _insert(config, "scouting/multicast/enabled", False)
    # No scouting happens, so no need to wait the default 500 ms for it when opening.
    _insert(config, "scouting/delay", 0)
    # Nothing here uses shared memory, and Zenoh's shared-memory transport, on by default,
    # wakes each session about 20 times a second (about 1.6 ms of CPU per second per
    # process, 80 us per wake-up on a cold cache): with 112 module processes, a tenth of a
    # core, and a wake-up in the middle of a tick's few ms of work.
    _insert(config, "transport/shared_memory/enabled", False)


RECONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2.0}
"""How a client retries its router after losing it (Zenoh's ``connect/retry``): first after
0.25 s, then doubling up to every 1 s, for ever. A client reconnects by itself, and Zenoh
re-declares its subscriptions, publishers, queryables and liveliness tokens on the new
link, so a router restart costs at most about 1 s after the router is back (Zenoh's
default backs off to 4 s). The first connection is not retried: opening a session still
fails at once when nothing listens."""


def _reconnect(config: zenoh.Config) -> None:
    """Set :data:`RECONNECT_RETRY` unless the config (a user's file) sets its own."""
    try:
        own = json.loads(config.get_json("connect/retry"))
    except Exception:
        own = None
    if own is None:
        _insert(config, "connect/retry", RECONNECT_RETRY)


def check_endpoint(endpoint: str) -> str:
    """Return ``endpoint`` if it looks like a Zenoh locator ``proto/host:port``."""
    proto, sep, rest = endpoint.partition("/")
    host, colon, port = rest.rpartition(":")
    if not sep or proto not in ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream") or (
            proto != "unixsock-stream" and (not colon or not host or not port.isdigit())):
        raise RuntimeTransportError(f"endpoint {endpoint!r}: expected e.g. 'tcp/127.0.0.1:7447'")
    if proto != "unixsock-stream" and not 1 <= int(port) <= 65535:
        raise RuntimeTransportError(f"endpoint {endpoint!r}: port {int(port)} is not in 1..65535")
    return endpoint


def tcp_host_port(endpoint: str) -> tuple[str, int]:
    """``("127.0.0.1", 7447)`` of ``tcp/127.0.0.1:7447``; other locators are refused."""
    check_endpoint(endpoint)
    proto, _, rest = endpoint.partition("/")
    host, _, port = rest.rpartition(":")
    if proto != "tcp":
        raise RuntimeTransportError(f"endpoint {endpoint!r}: the embedded router listens on tcp/HOST:PORT")
    return host.strip("[]"), int(port)


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def embedded_router_config(port: int = DEFAULT_PORT, host: str = DEFAULT_HOST) -> zenoh.Config:
    """Router mode, listening on ``tcp/host:port``, multicast scouting off."""
    config = zenoh.Config()
    _insert(config, "mode", "router")
    _insert(config, "listen/endpoints", [check_endpoint(f"tcp/{host}:{int(port)}")])
    _common(config)
    message_size_limits(config, router=True)
    # Read-only admin space: `cekm topic info` asks the router who publishes and subscribes
    # (answered only on a query; nothing runs otherwise).
    _insert(config, "adminspace", {"enabled": True, "permissions": {"read": True, "write": False}})
    return config


def client_config(endpoint: str = DEFAULT_ENDPOINT, *, user: str | None = None,
                  password: str | None = None) -> zenoh.Config:
    """Client mode connecting to ``endpoint``, multicast scouting off, optional user/password."""
    config = zenoh.Config()
    _insert(config, "mode", "client")
    _insert(config, "connect/endpoints", [check_endpoint(endpoint)])
    _common(config)
    message_size_limits(config, router=False)
    _reconnect(config)
    if (user is None) != (password is None):
        raise RuntimeTransportError("client config: give both user and password, or neither")
    if user is not None:
        _insert(config, "transport/auth/usrpwd/user", user)
        _insert(config, "transport/auth/usrpwd/password", password)
    return config


TLS_FILES = ("root_ca_certificate", "listen_certificate", "listen_private_key", "connect_certificate",
             "connect_private_key")
"""Keys under ``transport/link/tls`` naming a file (PEM)."""


def check_tls_files(config: zenoh.Config, what: str) -> None:
    """Fail with the key and the path when a TLS file the config names is missing
    (Zenoh itself only says that it cannot connect or listen)."""
    for key in TLS_FILES:
        try:
            value = json.loads(config.get_json(f"transport/link/tls/{key}"))
        except Exception:
            continue
        if isinstance(value, str) and not Path(value).is_file():
            where = "" if Path(value).is_absolute() else f" (relative to the working directory {os.getcwd()})"
            raise RuntimeTransportError(f"zenoh config {what}: transport/link/tls/{key}: no such file {value!r}{where}")


def _without_source(text: str) -> str:
    """Zenoh's error text less the Rust source location it ends with (`` at
    /root/.cargo/.../lib.rs:1486.``): the build machine's file means nothing to a user."""
    return re.sub(r"\s+at /\S+\.rs:\d+\.?\s*$", "", text.strip())


def load_config(path: str | Path, overrides: dict[str, object] | None = None) -> zenoh.Config:
    """A config file (JSON5) with optional overrides {'path/in/config': value}; the TLS
    files it names must exist."""
    path = Path(path)
    if not path.is_file():
        raise RuntimeTransportError(f"zenoh config {path}: no such file")
    try:
        config = zenoh.Config.from_file(str(path))
    except Exception as exc:
        raise RuntimeTransportError(f"zenoh config {path}: {_without_source(str(exc))}") from None
    for k, v in (overrides or {}).items():
        _insert(config, k, v)
    check_tls_files(config, str(path))
    return config


def open_session(config: zenoh.Config, what: str = "zenoh session") -> zenoh.Session:
    """zenoh.open with a precise error (unreachable endpoint, bad credentials, busy port)."""
    try:
        return zenoh.open(config)
    except Exception as exc:
        detail = str(exc).split(" at /", 1)[0]
        try:
            mode = json.loads(config.get_json("mode"))
            eps = json.loads(config.get_json("listen/endpoints" if mode == "router" else "connect/endpoints"))
        except Exception:
            mode, eps = "?", "?"
        if mode == "client" and "Unable to connect" in detail and isinstance(eps, list):
            detail = _why_not_connected(config, eps, detail)
        raise RuntimeTransportError(f"cannot open {what} ({mode}, endpoints {eps}): {detail}") from None


def _why_not_connected(config: zenoh.Config, endpoints: list[str], detail: str) -> str:
    """Zenoh says "Unable to connect" both when nothing listens and when the router refuses
    the session: tell them apart by a plain TCP connection to each endpoint."""
    reachable = [ep for ep in endpoints if _tcp_reachable(ep)]
    if not reachable:
        return f"{detail.strip()} (nothing accepts connections there: is the router running, and the address right?)"
    try:
        user = json.loads(config.get_json("transport/auth/usrpwd/user"))
    except Exception:
        user = None
    if user:
        return f"authentication failed for user {user!r} at {reachable[0]} (the router refused the credentials)"
    return (f"{reachable[0]} accepts connections but refused a Zenoh session: a router that requires "
            f"credentials or TLS (give a client config with --config), or not a Zenoh router at all")


def _tcp_reachable(endpoint: str, timeout: float = 1.0) -> bool:
    proto, _, rest = endpoint.partition("/")
    host, _, port = rest.split("#", 1)[0].rpartition(":")
    if proto not in ("tcp", "tls") or not port.isdigit():
        return False
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            return True
    except OSError:
        return False


def open_embedded_router(port: int = DEFAULT_PORT, host: str = DEFAULT_HOST) -> zenoh.Session:
    """Open the in-process router on ``tcp/host:port`` (fails clearly if the port is taken)."""
    return open_session(embedded_router_config(port, host), "embedded router")


def client_config_from_file(path: str | Path, endpoint: str = DEFAULT_ENDPOINT) -> zenoh.Config:
    """A client config file (JSON5: credentials, TLS keys, as in ``deploy/``) joining
    ``endpoint``, which replaces the file's ``connect/endpoints``; multicast scouting stays
    off. A router-mode file is refused: processes join, the launcher routes."""
    config = load_config(path, {"connect/endpoints": [check_endpoint(endpoint)]})
    try:
        mode = json.loads(config.get_json("mode"))
    except Exception:
        mode = None
    if mode not in (None, "client", "peer"):
        raise RuntimeTransportError(f"zenoh config {path}: mode is {mode!r}; a process joins as 'client'")
    _insert(config, "mode", "client")
    _common(config)
    message_size_limits(config, router=False)
    _reconnect(config)
    return config


def open_client(endpoint: str = DEFAULT_ENDPOINT, *, user: str | None = None, password: str | None = None,
                config_file: str | Path | None = None) -> zenoh.Session:
    """Open a client session to ``endpoint`` (fails at once if nothing listens there, or
    if the router refuses the credentials). ``config_file``: a client config file whose
    credentials and TLS settings are used (see :func:`client_config_from_file`)."""
    if config_file is not None:
        if user is not None or password is not None:
            raise RuntimeTransportError("client config: give credentials in the config file or as user/password, "
                                        "not both")
        return open_session(client_config_from_file(config_file, endpoint), f"client session ({config_file})")
    return open_session(client_config(endpoint, user=user, password=password), "client session")
