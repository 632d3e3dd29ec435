"""One node as its own process: the one shell every module runs in.

``python -m cekm_swarm.node RUN-SPEC.json --robot r1 --node obstacle-3``

It reads the run spec, builds the node (a node that cannot start, say for a bad model or
parameter, exits with :data:`EXIT_CANNOT_START` and its one-line reason, and the
launcher ends the launch with that line instead of restarting it), opens a Zenoh client
session, subscribes to the node's inputs, holds its liveliness token
``<root>/<robot>/alive/<node>/<run>``, and hands every message to the node's timing gate
(:mod:`.timing`, lockstep or real time), publishing what the node computes. Every
received message is validated; a malformed one, one whose stamp the node does not believe
(:class:`~cekm_swarm.protocol.stamps.StampWindow`) or one on a key the node does not read
is dropped and counted per source, never a crash. A step that raises is counted apart
(:meth:`NodeShell.step_failed`): in real time the node goes on, in lockstep it stops and
the launch ends with its line. It serves until SIGTERM/SIGINT, then logs ``DROPS {json}``
with what it handled, dropped and failed.

Decode, the step and publish run on Zenoh's receiving thread (a direct callback): one
thread wake-up per message instead of three, which is most of a module's cost on a loaded
machine. A lock serializes the node's subscriptions, so the node needs none.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import faulthandler
import json
import logging
import os
import signal
import sys
import threading
import time
from typing import Any

import zenoh

from cekm_swarm.errors import CekmError
from cekm_swarm.graph.plan import NodePlan, RunPlan
from cekm_swarm.graph.runspec import RunSpec
from cekm_swarm.node.graph_check import node_class
from cekm_swarm.protocol import DropCounter, KeyKind, Nothing, expect_of
from cekm_swarm.protocol.stamps import ANY_STAMP, StampWindow
from cekm_swarm.runtime.bridge import InlineSubscription, Publishers, declare_alive
from cekm_swarm.runtime.config import LOCKSTEP_MODULE_RUNTIME, ONE_THREAD_RUNTIME, open_client, use_zenoh_runtime
from cekm_swarm.runtime.gc_tuning import freeze_startup_heap
from cekm_swarm.runtime.lifetime import die_with_parent
from cekm_swarm.runtime.model_service import fetch_model_bytes
from cekm_swarm.ticks import tick_of

from .api import Context, NodeError, cannot_start, make_params, raised_at, start_node, traceback_text
from .direct_gate import DirectGate
from .gates import Gate, make_gate
from .live_params import LiveParams
from .runner import Runner
from .timer_gate import Timer, TimerGate
from .wire import Decoder, Encoder

EXIT_CANNOT_START = 78
"""A node that cannot start (bad model, bad parameter): a permanent failure, not restarted."""
CANNOT_START = "CANNOT-START"
"""The prefix of the one line a node that cannot start writes to its log."""
EXIT_STEP_FAILED = 79
"""A node whose step failed in lockstep, where the run cannot go on without that run's
outputs: a permanent failure, not restarted; the launch ends with the node's line."""
STEP_FAILED = "STEP-FAILED"
"""The prefix of the one line such a node writes to its log."""
STALLED = "STEP-STALLED"
"""The prefix of the line a node writes to its log when asked (:data:`STALL_SIGNAL`) while
a lockstep run stalls: whether a step of it is running, and for how long (then every
thread's stack); the launcher says the lines."""
STALL_SIGNAL = signal.SIGUSR1
REPORT = "DROPS"
"""The prefix of the one line (``DROPS {json}``, :meth:`NodeShell.report`) a node writes
to its log as it stops, whatever the log level: what it handled, dropped and failed, which
the launcher sums up."""

log = logging.getLogger("cekm_swarm.node")


def build_node(spec: RunSpec, plan: RunPlan, robot: str, name: str, backend: str = "numpy",
               model_source: Any = None) -> tuple[NodePlan, Runner]:
    """The node instance ``name`` of ``robot``, built and set up (raises CekmError/ValueError
    for a node that cannot start)."""
    try:
        node_plan = plan.node(robot, name)
    except KeyError:
        names = ", ".join(n.name for n in plan.nodes.get(robot, [])) or "none"
        raise CekmError(f"graph {spec.graph.name!r} has no node {name!r} for robot {robot!r} "
                        f"(nodes: {names})") from None
    decl = node_plan.decl
    cls = node_class(decl.program, spec.graph.source, decl.where)
    params = make_params(cls, spec.params.get(decl.name, {}), f"{decl.where}.params")
    ctx = Context(robot, decl.name, node_plan.instance, spec.team, spec.body, spec.mode,
                  model_source if model_source is not None else spec.model, backend,
                  logging.getLogger(f"cekm_swarm.node.{decl.name}"))
    return node_plan, Runner(node_plan, start_node(cls, ctx, params), plan.answer_key(robot))


def stamp_window(plan: RunPlan, node_plan: NodePlan) -> StampWindow:
    """The stamps a node believes: within 8 ticks of the newest it took; a pure reader of
    a reading the world holds, any stamp in bounds and on the grid
    (:data:`~cekm_swarm.protocol.stamps.ANY_STAMP` says why)."""
    reading = plan.holding_reader(node_plan)
    if reading is not None and reading in plan.held_readings(node_plan.robot):
        return StampWindow(ANY_STAMP, ANY_STAMP)
    return StampWindow()


class NodeShell:
    """The Zenoh side of one node: subscriptions, gate, publishing, liveliness."""

    def __init__(self, spec: RunSpec, plan: RunPlan, node_plan: NodePlan, runner: Runner) -> None:
        self.spec, self.plan, self.node_plan, self.runner = spec, plan, node_plan, runner
        self.keys = spec.keys
        self.drops = DropCounter(node_plan.label, keys=self.keys)
        self.decoder, self.encoder = Decoder(self.keys, self.drops), Encoder()
        self.window = stamp_window(plan, node_plan)
        self.lock = threading.RLock()
        self.closed = threading.Event()
        self.handled = 0
        self.step_failures: dict[str, int] = {}  # "Type: first message (file:line)" -> count
        self._failure_groups: dict[tuple[str, str], str] = {}  # (type, file:line) -> its step_failures key
        self.failure: str | None = None  # lockstep: the step failure that ends the node
        self.on_failure: Any = lambda: None  # set by serve(): stops the node
        lockstep = spec.mode == "lockstep"
        self.lockstep = lockstep
        self.clock_key = node_plan.clock_key
        if TimerGate.fits(node_plan, spec.mode):  # its own timer; it learns each tick from the clock
            self.clock_key = self.keys.world_clock()
        self.gate: Gate = make_gate(runner, spec.mode, self.drops.drop, self.clock_key)
        self.kinds: dict[str, Any] = {s.key: expect_of(b.kind) for b in node_plan.bindings for s in b.sources}
        self.ports: dict[str, str] = {s.key: b.port for b in node_plan.bindings for s in b.sources}
        if self.clock_key is not None:
            self.kinds[self.clock_key] = KeyKind.WORLD_CLOCK
        # readings the world leaves out when unchanged: sense/unchanged key -> reading -> our source keys
        self.holds = plan.holds(node_plan)
        for mk in self.holds:
            self.kinds[mk] = KeyKind.SENSE_UNCHANGED
        # the same, by the reading's key relative to the robot's (as ``Unchanged.keys`` names it)
        self.holds_rel = {mk: {reading[len(mk) - len("sense/unchanged"):]: sources
                               for reading, sources in held.items()} for mk, held in self.holds.items()}
        self.mates = {s.owner for b in node_plan.bindings if b.team for s in b.sources}
        self.own_team_keys = {f"{self.keys.root}/{node_plan.robot}/{d.key}" for d in node_plan.decl.inputs
                              if d.scope == "teammates"}
        self.mate_tokens: dict[str, set[str]] = {m: set() for m in self.mates}
        # every other node reading this node's outputs (teammates, or of its own robot; with
        # a delay or not): its token -> the keys it reads. A reader's (re)appearing token
        # asks for the recent outputs it missed while down (LockstepGate.resend)
        # real time: nothing sent again; a pure node of one key (DirectGate), only to readers with a delay
        self.readers = outputs_readers(plan, node_plan, self.keys, delayed_only=isinstance(self.gate, DirectGate)) \
            if lockstep else {}
        self.pubs: Any = None
        runner.live = LiveParams(runner)  # cekm param: parameters changed while it runs

    # ------------------------------------------------------------------ subscriptions

    def listen_exprs(self) -> list[str]:
        """What to subscribe to (:meth:`~cekm_swarm.graph.plan.RunPlan.listens`; the clock for a timer)."""
        exprs = self.plan.listens(self.node_plan)
        return exprs if self.clock_key is None or self.clock_key in exprs else [*exprs, self.clock_key]

    def on_sample(self, key: str, payload: bytes) -> list[tuple[str, Any]]:
        """One received sample: validate, admit its stamp, hand it to the gate."""
        kind = self.kinds.get(key)
        if kind is None:
            if key not in self.own_team_keys:  # its own robot's share (or other teammates' key): not an input
                self.drops.drop(key, "not a key this node reads")
            return []
        msg = self.decoder.decode(key, kind, payload)
        if msg is None:
            return []
        if kind is KeyKind.SENSE_UNCHANGED:
            return self.on_unchanged(key, msg)
        port = self.ports.get(key)
        why = None if port is None or type(msg) is Nothing else self.runner.node.check_input(port, msg)
        if why is None:
            why = self.window.check(msg.stamp)
        if why is not None:
            self.drops.drop(key, why)
            return []
        try:
            return self.gate.put(key, msg)
        except Exception as exc:  # noqa: BLE001 - a node must survive any single message
            return self.step_failed(exc)

    def step_failed(self, exc: Exception) -> list[tuple[str, Any]]:
        """The node's step (or the check of what it returned) raised: not the input's fault,
        so counted apart from drops, and logged with its traceback the first time each
        kind of failure happens. In real time the node goes on with the next run; in
        lockstep the run cannot go on without this run's outputs, so the node stops and
        the launch ends with its line (:data:`EXIT_STEP_FAILED`)."""
        cause = exc.__cause__ if isinstance(exc, NodeError) and exc.__cause__ is not None else exc
        what = " ".join(f"{type(cause).__name__}: {cause}".split())  # the kind of failure, without the tick
        at = raised_at(cause)
        where = (type(cause).__name__, at or what)  # grouped by where it was raised, not by its text
        group = self._failure_groups.get(where)
        first = group is None
        if group is None:  # named by its first failure's text and its line
            group = "other failures" if len(self.step_failures) >= 64 else what + (f" ({at})" if at else "")
            self._failure_groups[where] = group
        self.step_failures[group] = self.step_failures.get(group, 0) + 1
        line = str(exc) if isinstance(exc, NodeError) else f"{self.node_plan.label}: {what}"
        if first:
            log.error("%s", line, exc_info=cause)
        if self.lockstep and self.failure is None:
            self.failure = f"{line} (in lockstep the run cannot go on without its outputs)"
            self.closed.set()
            self.on_failure()
        return []

    def on_unchanged(self, key: str, msg: Any) -> list[tuple[str, Any]]:
        """The world left readings out as unchanged: the values their pure readers sent at
        ``since`` stand for this tick (:meth:`~cekm_swarm.node.timing.LockstepGate.hold`)."""
        why = self.window.check(msg.stamp)
        if why is not None:
            self.drops.drop(key, why)
            return []
        held = self.holds_rel[key]
        k = tick_of(msg.stamp)
        try:
            return self.gate.hold_all([(source, k, tick_of(since))
                                       for rel, since in zip(msg.keys, msg.since, strict=True)  # checked equal
                                       for source in held.get(rel, ())])
        except Exception as exc:  # noqa: BLE001 - a run it completes may fail like any other
            return self.step_failed(exc)

    def on_token(self, key: str, alive: bool) -> list[tuple[str, Any]]:
        """A liveliness token appeared or vanished: a teammate gone or back; a late reader back."""
        out: list[tuple[str, Any]] = []
        try:
            owner = self.keys.parse(key).robot
        except CekmError:
            return out
        if owner in self.mate_tokens:
            held = self.mate_tokens[owner]
            was = bool(held)
            (held.add if alive else held.discard)(key)
            if was and not held:
                log.warning("%s: teammate %s dropped (its liveliness tokens vanished)", self.node_plan.label, owner)
                sys.stdout.write("DROP " + json.dumps({"robot": self.node_plan.robot, "dropped": owner,
                                                        "wall": time.time()}) + "\n")
                sys.stdout.flush()
                try:
                    self.runner.node.teammate_left(owner)
                    out += self.gate.teammate(owner, False)
                except Exception as exc:  # noqa: BLE001 - as for a message
                    out += self.step_failed(exc)
            elif held and not was:
                out += self.gate.teammate(owner, True)
        if alive and key in self.readers:
            out += self.gate.resend(self.readers[key])
        return out

    def token_expr(self) -> str | None:
        """The liveliness tokens this node watches: every robot's when it reads a teammate's
        key or a teammate reads its outputs, only its own robot's when only nodes of its
        robot read them (a few tokens, not the whole team's), none in real time or when
        nobody reads them."""
        robot = self.node_plan.robot
        if self.mates or any(self.keys.parse(k).robot != robot for k in self.readers):
            return self.keys.alive_all()
        if self.readers:
            head = self.keys.robot_keys(robot)[:-len("/**")]
            return f"{head}/alive/**" if self.keys.run is None else f"{head}/alive/*/{self.keys.run}"
        return None

    def publish(self, out: list[tuple[str, Any]]) -> None:
        for key, msg in out:
            try:
                self.pubs.put(key, self.encoder(msg))
            except Exception as exc:  # noqa: BLE001 - a closing session must not kill the thread
                log.warning("%s: publishing on %s failed: %s", self.node_plan.label, key, exc)

    # ------------------------------------------------------------------ serving

    async def serve(self, session: Any, ready: Any = None) -> int:
        loop = asyncio.get_running_loop()
        stop = asyncio.Event()
        for sig in (signal.SIGTERM, signal.SIGINT):
            with contextlib.suppress(NotImplementedError, RuntimeError):  # not the main thread
                loop.add_signal_handler(sig, stop.set)
        loop.add_signal_handler(STALL_SIGNAL, self.say_where)
        put = zenoh.SampleKind.PUT
        self.on_failure = lambda: loop.call_soon_threadsafe(stop.set)
        self.pubs = Publishers(session, block=self.spec.mode == "lockstep", express=False)
        param_key = self.keys.param(self.node_plan.robot, self.node_plan.name)
        for key in (*self.node_plan.outputs.values(), param_key):  # before listening: none on Zenoh's thread later
            self.pubs.publisher(key)
        self.runner.live.on_change = lambda msg: self.publish([(param_key, msg)])  # the world records it

        def serve_sample(sample: zenoh.Sample) -> None:
            if self.closed.is_set() or sample.kind != put:
                return
            with self.lock:
                self.publish(self.on_sample(str(sample.key_expr), sample.payload.to_bytes()))
                self.handled += 1

        def serve_token(sample: zenoh.Sample) -> None:
            if self.closed.is_set():
                return
            with self.lock:
                try:
                    self.publish(self.on_token(str(sample.key_expr), sample.kind == put))
                except Exception as exc:  # noqa: BLE001 - a node must survive any token event
                    log.warning("%s: liveliness handler failed: %s: %s", self.node_plan.label, type(exc).__name__, exc)

        subs = [InlineSubscription(session, k, serve_sample, raw=True) for k in self.listen_exprs()]
        tokens = None
        watch = self.token_expr()
        if watch is not None:
            tokens = session.liveliness().declare_subscriber(watch, serve_token, history=True)
        params = session.declare_queryable(param_key, zenoh.handlers.Callback(self.serve_param, indirect=True))
        # the token comes last: once it is up, the subscriptions are in place
        token = declare_alive(session, self.keys.alive(self.node_plan.robot, self.node_plan.name))
        log.info("%s: up (%s), listening on %s", self.node_plan.label, self.spec.mode, ", ".join(self.listen_exprs()))
        if isinstance(self.gate, TimerGate):
            threading.Thread(target=self.run_timer, args=(self.gate,), name="timer", daemon=True).start()
        if ready is not None:
            ready()
        try:
            await stop.wait()
        finally:
            self.closed.set()
            for s in subs:
                s.close()
            if tokens is not None:
                tokens.undeclare()
            token.undeclare()  # type: ignore[no-untyped-call]  # zenoh's stub leaves LivelinessToken.undeclare untyped
            params.undeclare()
            self.pubs.close()
        return self.handled

    def run_timer(self, gate: TimerGate) -> None:
        """A node on a timer of its own (:mod:`.timer_gate`): a run every ``timer`` s until it stops."""
        period = self.node_plan.decl.timer
        if period is None:  # only a node that declares a timer takes a TimerGate
            return
        timer = Timer(float(period))
        while not self.closed.wait(timer.wait()):
            with self.lock:
                try:
                    self.publish(gate.fire())
                except Exception as exc:  # noqa: BLE001 - as for a run a message completes
                    self.step_failed(exc)

    def serve_param(self, query: Any) -> None:
        """``cekm param``: the query's JSON payload ``{}`` (what it has) or ``{"set": name,
        "value": v, "at": t}``; the reply's, the parameters or the change scheduled, or ``{"error": why}``."""
        try:
            ask = json.loads(query.payload.to_bytes()) if query.payload is not None else {}
            with self.lock:
                doc = self.runner.live.describe() if "set" not in ask else \
                    self.runner.live.set(str(ask["set"]), ask.get("value"), ask.get("at"))
        except (ValueError, TypeError, KeyError) as exc:
            doc = {"error": " ".join(str(exc).split())}
        if "name" in doc:  # a change scheduled
            log.info("%s: parameter %s = %r scheduled from t=%.3f s", self.node_plan.label, doc["name"], doc["value"],
                     doc["t"])
        query.reply(query.key_expr, json.dumps(doc).encode())

    def say_where(self) -> None:
        """The launcher asks while the run stalls: one :data:`STALLED` line (a step running,
        since when, or none), then every thread's stack when a step runs (where it hangs)."""
        label, stepping = self.node_plan.label, self.runner.stepping
        if stepping is None:
            sys.stderr.write(f"{STALLED} {label}: no step running ({self.runner.runs} runs so far)\n")
        else:
            t, began = stepping
            sys.stderr.write(f"{STALLED} {label}: its step at t={t:.3f} s has run for "
                             f"{time.monotonic() - began:.1f} s; its threads' stacks follow\n")
            sys.stderr.flush()
            faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        sys.stderr.flush()

    def report(self) -> dict[str, Any]:
        c = self.gate.counts()
        return {"handled": self.handled, "runs": self.runner.runs, "dropped": self.drops.by_source(),
                "repeats": c.repeats, "stale": c.stale, "step_failures": dict(self.step_failures),
                "not_ready": c.not_ready, "ran_without": list(c.ran_without),
                "param_changes": list(self.runner.live.changes)}


def outputs_readers(plan: RunPlan, node_plan: NodePlan, keys: Any,
                    delayed_only: bool = False) -> dict[str, frozenset[str]]:
    """The liveliness token of every other node that reads ``node_plan``'s outputs -> the
    output keys it reads (``delayed_only``: with ``delay = 1``). A pure node of one key
    (:class:`DirectGate`) sends its recent runs again only to delayed readers: a same-tick
    reader of it gets fresh values (the world sends a rejoining robot every reading on its
    next tick), and such a node's last runs may be old (its reading held unchanged since
    t = 0), whose stamps would set a restarted reader's stamp window in the past, so that it
    dropped every value of now, the only copies of its delayed inputs among them."""
    mine = set(node_plan.outputs.values())
    readers: dict[str, set[str]] = {}
    for r in plan.team:
        for n in plan.nodes[r]:
            if (n.robot, n.name) == (node_plan.robot, node_plan.name):
                continue
            read = {s.key for b in n.bindings for s in b.sources if s.key in mine and (b.delay or not delayed_only)}
            if read:
                readers.setdefault(keys.alive(n.robot, n.name), set()).update(read)
    return {k: frozenset(v) for k, v in readers.items()}


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m cekm_swarm.node", description="run one node of a controller's graph")
    p.add_argument("spec", help="the run spec (OUT/run-spec.json, written by cekm launch)")
    p.add_argument("--robot", required=True, help="robot id, e.g. r1")
    p.add_argument("--node", required=True, help="the node instance, e.g. obstacle-3")
    p.add_argument("--run-id", help="the run's id (default: the run spec's); named here so `ps` tells runs apart")
    return p


def node_argv(spec_path: str, robot: str, name: str, run_id: str | None = None) -> list[str]:
    """The command line that starts node ``name`` of ``robot`` (what :func:`parser` parses)."""
    argv = [sys.executable, "-m", "cekm_swarm.node", str(spec_path), "--robot", robot, "--node", name]
    return argv + (["--run-id", run_id] if run_id else [])


def main(argv: list[str] | None = None) -> int:
    die_with_parent()  # started by a launcher: stop when it dies, whatever kills it
    signal.signal(STALL_SIGNAL, signal.SIG_IGN)  # asked before it serves: nothing to say yet
    args = parser().parse_args(argv)
    label = f"{args.robot}/{args.node}"
    try:
        spec = RunSpec.read(args.spec)
    except CekmError as exc:
        return _cannot_start(label, str(exc))
    if args.run_id and args.run_id != spec.run_id:
        spec = spec.with_(run_id=args.run_id)
    # a node receives a message and sends one per period: one thread does it (sending apart
    # in lockstep, where a put may wait for the send queue: runtime.config)
    use_zenoh_runtime(LOCKSTEP_MODULE_RUNTIME if spec.mode == "lockstep" else ONE_THREAD_RUNTIME)
    logging.basicConfig(level=spec.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s.%(msecs)03d %(name)s %(levelname)s %(message)s", datefmt="%H:%M:%S")
    t0 = time.perf_counter()
    try:
        plan = spec.plan()
        source: str | tuple[str, bytes] | None = spec.model
        if source == "zenoh":
            source = _fetch_model(spec)
        node_plan, runner = build_node(spec, plan, args.robot, args.node, "numpy", source)
    except (CekmError, ValueError) as exc:
        if exc.__cause__ is not None:  # the node's own code raised: its traceback in this log
            sys.stderr.write(traceback_text(exc))
        return _cannot_start(label, str(exc))
    except Exception as exc:  # noqa: BLE001 - a user's node may fail in any way while starting
        sys.stderr.write(traceback_text(exc))
        return _cannot_start(label, cannot_start(label, exc))
    log.info("%s: built in %.2f s (pid %d)", label, time.perf_counter() - t0, os.getpid())
    freeze_startup_heap()  # the model and tables stay; per message only short-lived objects
    shell = NodeShell(spec, plan, node_plan, runner)
    session = open_client(spec.connect, config_file=spec.zenoh_config)
    try:
        asyncio.run(shell.serve(session))
    finally:
        session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves Session.close untyped
        runner.node.close()
    report = shell.report()
    if shell.drops.total:
        log.warning("%s: %d messages dropped (malformed, a stamp out of its window, or a value no run reads; "
                    "the first of each source says why): %s", label, shell.drops.total,
                    "; ".join(f"{r.source} x{r.count}" for r in shell.drops.records()))
    if shell.step_failures:
        log.warning("%s: %d runs failed: %s", label, sum(shell.step_failures.values()),
                    "; ".join(f"{what} x{n}" for what, n in shell.step_failures.items()))
    log.info("%s: stopped after %d messages, %d runs", label, shell.handled, runner.runs)
    sys.stderr.write(f"{REPORT} {json.dumps({'node': label, **report})}\n")
    if shell.failure is not None:
        sys.stderr.write(f"{STEP_FAILED} {shell.failure}\n")
    # the session is closed and everything logged: skip the interpreter's teardown
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(EXIT_STEP_FAILED if shell.failure is not None else 0)


def _cannot_start(label: str, why: str) -> int:
    line = " ".join(why.split()) if why.startswith(label) else f"{label}: {' '.join(why.split())}"
    sys.stderr.write(f"{CANNOT_START} {line}\n")
    sys.stderr.flush()
    return EXIT_CANNOT_START


def _fetch_model(spec: RunSpec) -> tuple[str, bytes]:
    """``(where, bytes)`` of the model the world host's launcher serves (``--model-from-zenoh``)."""
    key = spec.keys.world_model()
    session = open_client(spec.connect, config_file=spec.zenoh_config)
    try:
        return f"zenoh:{key}", fetch_model_bytes(session, key, spec.model_timeout)
    finally:
        session.close()  # type: ignore[no-untyped-call]  # zenoh's stub leaves Session.close untyped
