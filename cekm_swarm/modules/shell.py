"""The asyncio shell every module process shares: arguments, the Zenoh client session,
the liveliness token, decoding with drop counting, clean shutdown on SIGTERM/SIGINT.

A module is a :class:`ModuleSpec`: the key expression it listens on and a ``handle``
coroutine-free callback ``handle(msg, rec) -> list[(key, Message)]`` that computes what
to publish from one decoded message. A message whose stamp the module's
:class:`~cekm_swarm.protocol.stamps.StampWindow` does not believe is dropped and counted
before any handler sees it (on the fast path too: :meth:`ModuleSpec.admit`). Everything numerical lives in the pure parts
(:mod:`.target`, :mod:`.obstacle`, :mod:`.motor`); this file only moves bytes.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh

from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import DEFAULT_ROOT, MSGPACK_ENCODING, DropCounter, KeySpace, Message, encode
from cekm_swarm.protocol.stamps import StampWindow
from cekm_swarm.runtime.bridge import InlineSubscription, Publishers, Received, declare_alive
from cekm_swarm.runtime.config import (DEFAULT_ENDPOINT, LOCKSTEP_MODULE_RUNTIME, ONE_THREAD_RUNTIME, open_client,
                                       use_zenoh_runtime)
from cekm_swarm.runtime.gc_tuning import freeze_startup_heap
from cekm_swarm.runtime.lifetime import die_with_parent
from cekm_swarm.runtime.model_service import fetch_model_bytes, is_zenoh_source
from cekm_swarm.runtime.process_args import Param, add_params, run_id_arg, to_argv

log = logging.getLogger("cekm_swarm.modules")

MODULE_PARAMS: tuple[Param, ...] = (
    Param("robot", required=True, help="robot id, e.g. r1"),
    Param("model", required=True,
          help="trained model file (.npz), or 'zenoh' to fetch it from the launcher's queryable"),
    Param("model_timeout", float, 30.0, "s to wait for the served model (--model zenoh)"),
    Param("connect", default=DEFAULT_ENDPOINT, help="Zenoh endpoint to join (default %(default)s)"),
    Param("zenoh_config", help="Zenoh client config file (credentials, TLS; see deploy/); --connect sets its endpoint"),
    Param("root", default=DEFAULT_ROOT, help="key space root (default %(default)s)"),
    Param("run_id", run_id_arg, help="the launch's run id, carried in the liveliness token (default: none)"),
    Param("mode", default="realtime", choices=("realtime", "lockstep")),
    Param("log_level", default="INFO"),
)
"""Parameters every module takes: its parser and the launcher's argv both come from here."""

INDEX_PARAM = Param("index", int, required=True, help="distance sensor index j (0..11)")
"""The obstacle module's own parameter."""

MODULE_PROGRAMS = {"target": "cekm_swarm.modules.target", "obstacle": "cekm_swarm.modules.obstacle",
                   "motor": "cekm_swarm.modules.motor"}

TEAM_PARAM = Param("team", required=True, help="every robot of the scenario, comma-separated, in scenario order")
TARGET_RANGE_PARAM = Param("target_range", float, required=True, help="the target sensing range R (m)")
"""The tracking target module's own parameters (docs/tracking.md)."""
TRACKING_RANGE_PARAM = Param("tracking_range", float, None, metavar="R",
                             help="a tracking robot's motor (target sensing range R in m): integrate the tracking "
                                  "target module's fields")
"""The motor's parameter on a tracking scenario."""


def base_parser(description: str) -> argparse.ArgumentParser:
    """Arguments every module takes."""
    return add_params(argparse.ArgumentParser(description=description), MODULE_PARAMS)


def module_argv(name: str, tracking: tuple[tuple[str, ...], float] | None = None, **values: Any) -> list[str]:
    """The command line of module ``name`` (``target``, ``obstacle-<j>``, ``motor``) with
    ``values`` of :data:`MODULE_PARAMS`; what :func:`base_parser` parses back. ``tracking``
    = (every robot in scenario order, the target sensing range) on a tracking scenario:
    the target module is then the tracking target module and the motor integrates its fields."""
    kind, _, j = name.partition("-")
    if kind not in MODULE_PROGRAMS or (kind == "obstacle") != bool(j):
        raise ValueError(f"no module {name!r} (expected target, obstacle-<j> or motor)")
    program = "cekm_swarm.modules.tracking" if kind == "target" and tracking else MODULE_PROGRAMS[kind]
    argv = [sys.executable, "-m", program, *to_argv(MODULE_PARAMS, **values)]
    if kind == "obstacle":
        argv += to_argv((INDEX_PARAM,), index=int(j))
    if tracking and kind == "target":
        argv += to_argv((TEAM_PARAM, TARGET_RANGE_PARAM), team=",".join(tracking[0]), target_range=repr(float(tracking[1])))
    if tracking and kind == "motor":
        argv += to_argv((TRACKING_RANGE_PARAM,), tracking_range=repr(float(tracking[1])))
    return argv


def load_controller(source: str | tuple[str, bytes]):
    """The cooperative EKM of a saved indirect-mapping model: a file path, or
    ``(where, file bytes)`` fetched from the launcher (``--model zenoh``)."""
    from cekm_swarm.controller.cooperative import CooperativeEKM
    from cekm_swarm.models.io import load_model, load_model_bytes

    if isinstance(source, tuple):
        where, blob = source
        model = load_model_bytes(blob, where)
    else:
        where, model = source, load_model(source)
    if not model.kind.startswith("indirect"):
        raise SystemExit(f"{where}: the controller needs an indirect-mapping EKM, not {model.kind!r}")
    return CooperativeEKM(model, backend="numpy")  # no numba in a module process: a third of the memory


Handler = Callable[[Message, Received], list[tuple[str, Message]]]
FastHandler = Callable[[str, bytes], "list[tuple[str, bytes]] | None"]
"""A module's hot path: key and payload bytes in, ``[(key, bytes to publish)]`` out, or None when
it does not take the message (then the general decode-and-handle path runs). It must
give exactly the bytes the general path would encode."""
Admit = Callable[[str, float], bool]
"""A module's stamp check, :meth:`ModuleSpec.admit`: (key, stamp) -> believe it?"""


@dataclass
class ModuleSpec:
    """What one module process is: its name (``target``, ``obstacle-3``, ``motor``), the
    robot, the key expression it listens on and its handler."""

    name: str
    robot: str
    listen: str
    handle: Handler
    keys: KeySpace = field(default_factory=KeySpace)
    drops: DropCounter | None = None
    on_stop: Callable[[], None] | None = None
    fast: FastHandler | None = None
    outputs: tuple[str, ...] = ()
    """Keys the module publishes on, declared before it listens (none: declared on first use)."""
    window: StampWindow = field(default_factory=StampWindow)
    also: tuple[str, ...] = ()
    """More key expressions it listens on (the tracking target module: its pose, its targets, the teammates' shares)."""
    liveliness: Callable[[str, bool], list[tuple[str, Message]]] | None = None
    """Called with (token key, alive) for every liveliness token under the root appearing or
    vanishing (history included); returns what to publish. Serialized with the handler."""

    def __post_init__(self) -> None:
        if self.drops is None:
            self.drops = DropCounter(f"{self.robot}/{self.name}", keys=self.keys)

    def admit(self, key: str, stamp: float) -> bool:
        """True when the stamp of a message received on ``key`` is believable (the window
        then moves to it); else the message is dropped and counted."""
        why = self.window.check(stamp)
        if why is None:
            return True
        self.drops.drop(key, why)
        return False

    @property
    def sender(self) -> str:
        return f"{self.robot}/{self.name}"


def process_one(spec: ModuleSpec, rec: Received) -> list[tuple[str, Message]]:
    """Decode one received sample (dropping and counting a malformed one) and run the
    handler. Never raises for bad input: a handler error on a message is counted as a
    drop of that message too, and the module keeps running."""
    if rec.kind != "put":
        return []
    msg = spec.drops.decode(rec.key, rec.payload)
    if msg is None or not spec.admit(rec.key, msg.stamp):
        return []
    try:
        return spec.handle(msg, rec)
    except Exception as exc:  # noqa: BLE001 - a module must survive any single message
        spec.drops.drop(rec.key, f"handler failed: {type(exc).__name__}: {exc}")
        return []


def respond(spec: ModuleSpec, key: str, payload: bytes) -> list[tuple[str, bytes]]:
    """The bytes to publish for one sample put on ``key``: the module's fast path when it
    takes the message, else :func:`process_one`'s messages, encoded."""
    if spec.fast is not None:
        try:
            out = spec.fast(key, payload)
        except Exception:  # noqa: BLE001 - the general path decides, and counts a bad message
            out = None
        if out is not None:
            return out
    rec = Received(key, payload, "put", MSGPACK_ENCODING, time.monotonic())
    return [(k, encode(m)) for k, m in process_one(spec, rec)]


async def run_module(spec: ModuleSpec, endpoint: str, *, block: bool = False,
                     ready: Callable[[], None] | None = None, config_file: str | None = None) -> int:
    """Serve ``spec`` until SIGTERM/SIGINT: subscribe, hold the liveliness token, publish
    what the handler returns. Returns the number of messages handled.

    Decode, handler and publish run on Zenoh's receiving thread (a direct callback): one
    thread wake-up per message instead of three (Zenoh's callback thread, the event loop's
    self-pipe, the loop), which is most of a module's cost on a loaded machine
    (``benchmarks/bench_runtime.py``). The handler never blocks and messages of the one
    subscription arrive in order on that thread, so the module's state needs no lock. The
    event loop owns the life cycle: signals, the liveliness token, shutdown."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        try:
            loop.add_signal_handler(sig, stop.set)
        except (NotImplementedError, RuntimeError):  # pragma: no cover - non-main thread
            pass
    session = open_client(endpoint, config_file=config_file)
    handled = [0]
    try:
        pubs = Publishers(session, block=block, express=False)
        for key in spec.outputs:  # before listening: no declaration on Zenoh's thread later
            pubs.publisher(key)
        closed = threading.Event()
        put = zenoh.SampleKind.PUT
        # several subscriptions may call back on different threads; re-entrant, since a put
        # on a key this module also listens on (its own share) is delivered within the put
        lock = threading.RLock()

        def publish(out: list[tuple[str, bytes]]) -> None:
            for key, data in out:
                try:
                    pubs.put(key, data)
                except Exception as exc:  # noqa: BLE001 - a closing session must not kill the thread
                    log.warning("%s: publishing on %s failed: %s", spec.sender, key, exc)

        def serve(sample: zenoh.Sample) -> None:
            if closed.is_set() or sample.kind != put:
                return
            with lock:
                publish(respond(spec, str(sample.key_expr), sample.payload.to_bytes()))
                handled[0] += 1

        def token(sample: zenoh.Sample) -> None:
            if closed.is_set():
                return
            with lock:
                try:
                    out = spec.liveliness(str(sample.key_expr), sample.kind == put)
                except Exception as exc:  # noqa: BLE001 - a module must survive any token event
                    log.warning("%s: liveliness handler failed: %s: %s", spec.sender, type(exc).__name__, exc)
                    out = []
                publish([(k, encode(m)) for k, m in out])

        sub = InlineSubscription(session, spec.listen, serve, raw=True)
        more = [InlineSubscription(session, k, serve, raw=True) for k in spec.also]
        tokens = None
        if spec.liveliness is not None:
            tokens = session.liveliness().declare_subscriber(spec.keys.alive_all(), token, history=True)
        # The token comes last: once it is up, the subscription is in place.
        token = declare_alive(session, spec.keys.alive(spec.robot, spec.name))
        log.info("%s: up, listening on %s", spec.sender, spec.listen)
        if ready:
            ready()
        try:
            await stop.wait()
        finally:
            closed.set()
            sub.close()
            for m in more:
                m.close()
            if tokens is not None:
                tokens.undeclare()
            if spec.on_stop:
                spec.on_stop()
            token.undeclare()
            pubs.close()
    finally:
        session.close()
    if spec.drops.total:
        log.warning("%s: %d malformed messages dropped: %s", spec.sender, spec.drops.total,
                    "; ".join(f"{r.source} x{r.count}" for r in spec.drops.records()))
    log.info("%s: DROPS %s", spec.sender, json.dumps({"handled": handled[0], "dropped": spec.drops.by_source()}))
    log.info("%s: stopped after %d messages", spec.sender, handled[0])
    return handled[0]


def main_of(build: Callable[[argparse.Namespace], ModuleSpec], parser: argparse.ArgumentParser,
            argv: list[str] | None = None) -> int:
    """Parse arguments, build the module, serve it; the body of each module's ``main``."""
    die_with_parent()  # started by a launcher: stop when it dies, whatever kills it
    args = parser.parse_args(argv)
    # a module receives one message and sends one per period: one thread does it (sending
    # apart in lockstep, where a put may wait for the send queue: runtime.config)
    use_zenoh_runtime(LOCKSTEP_MODULE_RUNTIME if args.mode == "lockstep" else ONE_THREAD_RUNTIME)
    logging.basicConfig(level=args.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s.%(msecs)03d %(name)s %(levelname)s %(message)s", datefmt="%H:%M:%S")
    t0 = time.perf_counter()
    try:
        if is_zenoh_source(args.model):
            args.model = fetch_model(args)
        spec = build(args)
    except CekmError as exc:  # a model or transport error: a clear line in the module's log, not a traceback
        log.error("%s/%s: cannot start: %s", args.robot, parser.prog, exc)
        return 2
    log.info("%s: model loaded in %.2f s (pid %d)", spec.sender, time.perf_counter() - t0, os.getpid())
    freeze_startup_heap()  # the model and tables stay; per message only short-lived objects
    asyncio.run(run_module(spec, args.connect, block=args.mode == "lockstep", config_file=args.zenoh_config))
    # The session is closed and everything logged: skip the interpreter's teardown (about
    # 0.4 s of CPU per process with numba loaded, seconds for a robot's 14 processes).
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def fetch_model(args: argparse.Namespace) -> tuple[str, bytes]:
    """``(where, bytes)`` of the model served at ``<root>/world/model`` (``--model zenoh``)."""
    key = KeySpace(args.root).world_model()
    session = open_client(args.connect, config_file=args.zenoh_config)
    try:
        return f"zenoh:{key}", fetch_model_bytes(session, key, args.model_timeout)
    finally:
        session.close()


def keyspace(args: Any) -> KeySpace:
    """The module's key space: its root, and its run id in the liveliness token."""
    return KeySpace(args.root, run=getattr(args, "run_id", None))
