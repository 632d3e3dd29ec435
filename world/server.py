"""The world server of the distributed runtime: runs a scenario tick by tick with the same
world side as ``cekm run`` (:class:`world.episode.Episode`, or
:class:`world.tracking.TrackingEpisode`) and talks to the robots' node processes over
Zenoh. A thin composition of its parts:

* :mod:`world.config`: its settings, declared once (command line, :class:`WorldConfig`,
  the launcher's argv), and the checks of what they name;
* :mod:`world.publisher`: per tick and robot the readings its graph reads
  (``<root>/<robot>/sense/...``), then ``<root>/world/clock`` and ``<root>/world/state``;
  a stalled lockstep tick again; the tick's log (``OUT/run.mcap``: what the world sent,
  its Foxglove views, and what other sessions sent that passes
  :class:`world.recorder.RecordFilter`, log time the world's sim time);
* :mod:`world.inbox`: each robot's latest answer to a tick (``RunPlan.answer_key``; the
  wheel command), checked, with its latency;
* :mod:`world.clocks`: when a tick's commands are taken, lockstep or real time (with the
  dead-man of :mod:`world.deadman`);
* :mod:`world.outcome`: events, progress lines, ``OUT/outcome.json`` and
  ``OUT/trajectory.json`` at the end (every robot at its goal, ``--max-time``, or
  SIGTERM/SIGINT).

With a run spec (``--spec``; ``cekm launch`` writes it) the graph says which nodes the
world waits for before tick 0 (``--wait-modules S``), which readings it publishes, what
answers a tick and which keys it records; it serves the spec on ``<root>/world/graph`` for
the tools. With ``--connect`` the server joins a router as a client; with ``--listen`` it
hosts the router itself (the launcher's embedded default), so a tick's readings leave and
its commands arrive with no router hop between the world and the nodes.

Progress goes to stdout as lines ``READY {json}`` (the session is open and the token up),
``START``, ``PROGRESS {json}``, ``EVENT {json}`` and ``DONE {json}``.

``python -m world.server SCENARIO --connect tcp/127.0.0.1:7447 --out DIR [--mode lockstep]``
``python -m world.server SCENARIO --listen tcp/127.0.0.1:7447 --wait-modules 180 --spec RUN-SPEC.json --out DIR``

Imports only ``world``, the protocol, the transport, the robot's body and graphs as data.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import click
import zenoh

from cekm_swarm.errors import CekmError
from cekm_swarm.graph.plan import WORLD_KEYS
from cekm_swarm.graph.spec import GraphError
from cekm_swarm.protocol import DropCounter, KeySpace
from cekm_swarm.protocol.user import PARAM_CHANGE_KIND, ParamChange, user_schemas
from cekm_swarm.runtime.bridge import (
    InlineSubscription,
    LivelinessWatcher,
    Publishers,
    declare_alive,
    wait_matching_async,
)
from cekm_swarm.runtime.config import (
    ROUTER_RUNTIME,
    is_loopback,
    open_client,
    open_embedded_router,
    tcp_host_port,
    use_zenoh_runtime,
)
from cekm_swarm.runtime.errors import RuntimeTransportError
from cekm_swarm.runtime.gc_tuning import freeze_startup_heap
from cekm_swarm.runtime.heap import HeapTrimmer, hold_mmap_threshold, trim
from cekm_swarm.runtime.lifetime import die_with_parent
from cekm_swarm.runtime.mcap_record import LogFull
from cekm_swarm.runtime.record import serve_geometry, serve_json
from cekm_swarm.runtime.rungraph import default_nodes
from cekm_swarm.runtime.wait import open_client_when_ready
from cekm_swarm.ticks import TICK_S

from .clocks import LockstepClock, RealtimeClock, Stopped
from .config import (
    DEFAULT_MAX_TIME,
    REPUBLISH_S,
    CheckpointsError,
    WorldConfig,
    load_run_graph,
    parse_checkpoints,
    server_argv,
    world_options,
)
from .deadman import Deadman
from .inbox import CommandInbox
from .outcome import RunStats, emit, latency_ms, progress_doc, write_outputs
from .publisher import TickPublisher
from .recorder import LEAN_VIEW_TICKS, RECORD_QUEUE, RecordFilter, open_run_log
from .run_episode import make_episode
from .scenario import ScenarioError, load_scenario
from .sim import World
from .tracking import run_kind

__all__ = ["WorldServer", "WorldConfig", "CheckpointsError", "parse_checkpoints", "server_argv", "main",
           "DEFAULT_MAX_TIME", "REPUBLISH_S"]

log = logging.getLogger("world.server")


class Refused(click.ClickException):
    """Bad input named by the command line (a scenario, checkpoints, a run spec): one line
    ``Error: ...`` on stderr, exit code 2, before anything starts."""

    exit_code = 2


class StoppedWaiting(CekmError):
    """SIGINT or SIGTERM came while the server waited for the router: it ends (exit 130)."""


class WorldServer:
    """One run of a scenario over Zenoh (see the module's docstring), set up from a
    :class:`WorldConfig`; :meth:`run` runs it and writes its outputs."""

    def __init__(self, config: WorldConfig) -> None:
        self.config = cfg = config
        self.keys = KeySpace(cfg.root, run=cfg.run_id)
        self.scenario = load_scenario(cfg.scenario)
        robots = [r.id for r in self.scenario.robots]
        checkpoints = parse_checkpoints(cfg.checkpoints, robots) if cfg.checkpoints else None
        task = run_kind(self.scenario, checkpoints or {})
        self.task = task  # navigation or tracking (docs/tracking.md)
        self.world = World(self.scenario, seed=cfg.seed)
        self.robots = list(self.world.robot_ids)
        self.spec, self.plan = load_run_graph(cfg.spec, self.scenario, self.robots, task, cfg.root, cfg.run_id)
        self.out = Path(cfg.out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.max_ticks = int(math.ceil(cfg.max_time / TICK_S))
        self.episode = make_episode(self.world, task, checkpoints, self.max_ticks)
        self.drops = DropCounter("world commands", keys=self.keys)
        self.record_drops = DropCounter("world recorder", keys=self.keys)
        plan = self.plan
        declared = None
        if plan is not None:  # each node's parameter changes (cekm param set), recorded as its messages are
            declared = {k: v for r in self.robots for k, v in plan.sent_keys(r).items()}
            declared.update({self.keys.param(r, n.name): PARAM_CHANGE_KIND for r in self.robots for n in plan.nodes[r]})
        self.declared = declared
        answers = ({plan.answer_key(r): r for r in self.robots} if plan is not None
                   else {self.keys.cmd_wheels(r): r for r in self.robots})
        sends = None if plan is None else {r: set(plan.world_keys(r)) for r in self.robots}
        held = None if plan is None else {r: set(plan.held_readings(r)) for r in self.robots}
        self.heap = HeapTrimmer()
        hold_mmap_threshold()  # large transient buffers (the log's chunks) never settle in the heap
        self.deadman = Deadman(self.robots, cfg.deadman, time.monotonic())  # restarted when the run starts
        self.inbox = CommandInbox(self.robots, answers, self.drops, self.deadman)
        self.publisher = TickPublisher(self.keys, self.world, self.episode, sends,
                                       RecordFilter(self.keys, self.robots, self.record_drops, declared,
                                                    lean=cfg.record == "lean"), held)
        self.publisher.map_every = {} if plan is None else {r: p for r in self.robots if (p := plan.map_period(r))}
        if cfg.record == "lean":
            self.publisher.view_every = LEAN_VIEW_TICKS
        self.stats = RunStats()
        self.stop = asyncio.Event()
        self.arrived = asyncio.Event()
        self.stop_reason = "signal"
        self.stop_waiting = threading.Event()  # set by a signal: the wait for the router ends at once
        self.log_full: LogFull | None = None  # the log's disk filled: the run ended there

    def _lost_log(self, exc: LogFull, t: float) -> None:
        """The log's disk is full: the recorder closed the file; the run ends here, in one line."""
        if self.log_full is None:
            self.log_full = exc
            self.stop_reason = "log disk full"
            log.error("%s", exc)
            self.stats.event("log_full", t, {"log": str(exc), "closed": exc.closed, "messages": exc.messages,
                                             "bytes": exc.size})

    def _request_stop(self) -> None:
        """End the run: the tick loop sees ``stop`` at its next wait (waking a lockstep wait)."""
        self.stop.set()
        self.arrived.set()
        self.stop_waiting.set()

    def _progress(self) -> None:
        emit("PROGRESS", progress_doc(self.world, self.episode, self.robots, self.deadman.stopped,
                                      self.publisher.republished, self.stats.deadline_misses))

    def _world_keys(self, robot: str) -> list[str]:
        """The sense keys whose subscribers the world waits for before tick 0 (with the
        robot's ``sense/unchanged`` when it has held readings)."""
        if self.plan is not None:
            held = [self.keys.sense_unchanged(robot)] if self.plan.held_readings(robot) else []
            return self.plan.world_keys(robot) + held
        out = []  # no run spec: every reading the world publishes for the task
        for rel, wk in WORLD_KEYS.items():
            if wk.per_robot and self.task in wk.tasks:
                head = f"{self.keys.root}/{robot}/"
                out += [head + rel.replace("{j}", str(j)) for j in range(self.keys.range_sensors)] \
                    if "{j}" in rel else [head + rel]
        return out

    def _clock(self) -> LockstepClock | RealtimeClock:
        cfg = self.config
        parts = (self.inbox, self.publisher, self.episode, self.stats, self.stop, self.arrived)
        if cfg.mode == "lockstep":
            return LockstepClock(*parts, republish=cfg.republish)
        return RealtimeClock(*parts, deadman=self.deadman, wait_first=cfg.wait_modules > 0,
                             deadline_ticks=cfg.deadline_ticks)

    async def run(self) -> dict[str, Any]:
        cfg = self.config
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            with contextlib.suppress(NotImplementedError, RuntimeError):  # pragma: no cover
                loop.add_signal_handler(sig, self._request_stop)
        def wake() -> None:  # from Zenoh's thread: a command arrived
            loop.call_soon_threadsafe(self.arrived.set)

        self.inbox.wake = wake
        self.deadman.restart(time.monotonic())
        geometry = self.world.static_geometry()
        pub = self.publisher
        # first: a router that cannot start (a taken port), or none to join, leaves no log behind
        session = await self._open_session()
        try:
            pub.recorder, pub.views = self._open_log(geometry)
        except BaseException:
            session.close()
            raise
        t_wall0 = time.perf_counter()  # set again once the nodes are alive: wall_seconds is the run's own
        aborted = False
        try:
            pub.pubs = Publishers(session, block=True, express=False)
            pub.record_sub = session.declare_subscriber(self.keys.everything(),
                                                        zenoh.handlers.RingChannel(RECORD_QUEUE),
                                                        allowed_origin=zenoh.Locality.REMOTE)
            keys = self.inbox.answer_keys
            every_robot = all(k == self.keys.cmd_wheels(r) for k, r in keys.items())
            on = [self.keys.cmd_wheels_all()] if every_robot else list(keys)
            cmd_subs = [InlineSubscription(session, k, self.inbox.on_command) for k in on]
            token = declare_alive(session, self.keys.alive("world", "server"))
            served = [serve_geometry(session, self.keys.world_geometry(), geometry)]  # for `cekm record`
            if self.spec is not None:
                served.append(serve_json(session, self.keys.world_graph(), self.spec.to_dict()))
            emit("READY", {"endpoint": cfg.listen or cfg.connect, "router": bool(cfg.listen)})
            if cfg.wait_modules > 0 and not await self._wait_for_nodes(session, cfg.wait_modules):
                self._request_stop()
            t_wall0 = time.perf_counter()
            rejoins = self._watch_rejoins(session) if pub.held else None
            await self._wait_subscribers()
            start = loop.time()
            try:
                aborted = not await self._ticks()
            finally:
                self.stats.tick_loop_seconds = loop.time() - start
                self.stats.tick_loop_cpu_end = time.process_time()  # every thread's, ended ones too
            self._progress()
            await asyncio.sleep(0.05)  # what is still in flight gets recorded
            for sub in cmd_subs:
                sub.close()
            if self.log_full is None:
                try:
                    pub.record_tick(self.inbox.now)
                except LogFull as exc:
                    self._lost_log(exc, self.episode.t)
            ended = declare_alive(session, self.keys.world_ended())  # before its own token goes: a normal end
            token.undeclare()
            if rejoins is not None:
                rejoins.undeclare()
            for q in served:
                q.undeclare()
            pub.record_sub.undeclare()
            pub.pubs.close()
            ended.undeclare()
        finally:
            session.close()
            try:
                pub.recorder.close()
            except LogFull as exc:
                self._lost_log(exc, self.episode.t)
                aborted = True
        return self._write_outputs(time.perf_counter() - t_wall0, aborted)

    async def _open_session(self) -> zenoh.Session:
        """The world's Zenoh session: the router it hosts, or one it joins (waiting for it in a
        thread, so that a signal ends the wait at once)."""
        cfg = self.config
        try:
            session = await asyncio.to_thread(open_world_session, cfg, self.stop_waiting)
        except RuntimeTransportError:
            if self.stop_waiting.is_set():
                raise StoppedWaiting(f"stopped while waiting for the router at {cfg.connect}") from None
            if cfg.listen or cfg.wait_router <= 0:
                raise
            raise RuntimeTransportError(f"no Zenoh router at {cfg.connect} after waiting {cfg.wait_router:g} s "
                                        f"(--wait-router): start the router first, or check --connect") from None
        if self.stop.is_set():
            session.close()
            raise StoppedWaiting(f"stopped while waiting for the router at {cfg.connect}")
        return session

    def _open_log(self, geometry: dict[str, Any]) -> tuple[Any, Any]:
        """The run's log (``run.mcap`` or its set) and its Foxglove views."""
        cfg = self.config
        schemas = None if self.spec is None else {**self.spec.schemas, **user_schemas([ParamChange])}
        return open_run_log(self.out / "run.mcap", self.scenario.name, self.world.seed, cfg.mode, geometry,
                            self.world.body_radius, max_bytes=cfg.max_log_size, max_seconds=cfg.max_log_duration,
                            record=cfg.record, keys=self.keys, kinds=self.declared, schemas=schemas)

    async def _wait_subscribers(self) -> None:
        """Every node's subscription known before tick 0 is published (at most ``--match-timeout``
        s a key, then the run starts anyway, saying so)."""
        timeout = self.config.match_timeout
        for r in self.robots:
            for k in self._world_keys(r):
                if self.stop.is_set():
                    break
                if not await wait_matching_async(self.publisher.pubs.publisher(k), timeout):
                    log.warning("no subscriber on %s after %.0f s; starting anyway", k, timeout)

    async def _ticks(self) -> bool:
        """The tick loop; False when it was stopped before the run's end."""
        cfg, ep, inbox, clock = self.config, self.episode, self.inbox, self._clock()
        last_progress = -1e9
        try:
            if self.stop.is_set():  # interrupted (or nodes missing) before tick 0
                raise Stopped
            freeze_startup_heap()  # no full collection walks the world, its log and its session mid-run
            emit("START", {"mode": cfg.mode, "robots": self.robots, "scenario": self.scenario.name,
                           "seed": self.world.seed, "cpu_s": time.process_time()})
            while True:
                readings = ep.readings()
                inbox.opened(ep.t)
                self.publisher.publish(readings)
                clock.opened()
                commands = await clock.commands(readings)
                inbox.collect_latency(ep.t, keep=cfg.mode == "lockstep" or ep.tick > 0)
                ep.apply(commands)
                now = time.monotonic()
                if now - last_progress >= cfg.progress_every:
                    last_progress = now
                    self._progress()
                if self.heap.due(now):  # freed memory back to the system, off the loop (runtime/heap.py)
                    asyncio.get_running_loop().run_in_executor(None, trim)
                if ep.done or ep.tick >= self.max_ticks:
                    return True
                ep.advance()
        except Stopped:
            self.stats.event("stopped", ep.t, {"reason": self.stop_reason})
            return False
        except LogFull as exc:  # from the tick's log: the run cannot be recorded further
            self._lost_log(exc, ep.t)
            return False

    def _watch_rejoins(self, session: zenoh.Session) -> Any:
        """A liveliness subscriber telling the publisher of each robot node that (re)joins
        from now on (a restart): the robot's next tick sends every reading, so a node that
        lost the values standing for left-out readings gets them at once."""
        put, robots = zenoh.SampleKind.PUT, set(self.robots)

        def on_token(sample: zenoh.Sample) -> None:
            if sample.kind != put:
                return
            try:
                owner = self.keys.parse(str(sample.key_expr)).robot
            except CekmError:
                return
            if owner in robots:
                self.publisher.rejoined(owner)

        return session.liveliness().declare_subscriber(self.keys.alive_all(), on_token)

    async def _wait_for_nodes(self, session: zenoh.Session, timeout: float) -> bool:
        """Hold tick 0 until every node of every robot holds its liveliness token (at most
        ``timeout`` s, or until SIGTERM); False, with an event naming the missing ones."""
        if self.plan is not None:
            expected = self.plan.tokens(self.robots)
        else:  # no run spec: the nodes of the default controller's graph (cekm)
            names = default_nodes(self.task, self.keys.range_sensors)
            expected = {self.keys.alive(r, n) for r in self.robots for n in names}
        with LivelinessWatcher(session, self.keys.alive_all()) as watcher:
            waiter = asyncio.ensure_future(watcher.wait_all(expected, timeout))
            stopper = asyncio.ensure_future(self.stop.wait())
            await asyncio.wait({waiter, stopper}, return_when=asyncio.FIRST_COMPLETED)
            stopper.cancel()
            if not waiter.done():
                waiter.cancel()
                return False
            missing = waiter.result()
        if missing:
            self.stop_reason = "modules missing"
            self.stats.event("modules_missing", self.episode.t, {"after_s": timeout, "missing": sorted(missing)})
            log.error("%d of %d nodes not alive after %.0f s: %s", len(missing), len(expected), timeout,
                      ", ".join(sorted(missing)[:8]))
            return False
        return True

    def _write_outputs(self, wall: float, aborted: bool) -> dict[str, Any]:
        ep, st, pub, inbox = self.episode, self.stats, self.publisher, self.inbox
        doc = {"scenario": self.scenario.name, "controller": self.spec.graph.controller if self.spec else "cekm",
               "graph": None if self.spec is None else self.spec.graph.name, "seed": self.world.seed,
               "robots": ep.outcome(), "wall_seconds": round(wall, 3),
               "tick_loop_seconds": round(st.tick_loop_seconds, 3), "mode": self.config.mode, "sim_seconds": ep.t,
               "ticks": ep.tick, "aborted": aborted, "republished": pub.republished,
               "readings_left_out": pub.left_out,
               "log": _log_doc(pub, self.config),
               "deadline_misses": st.deadline_misses, "deadline_ticks": self.config.deadline_ticks,
               "deadline_miss_ticks": {str(k): v for k, v in st.missed_ticks.items()},
               "command_age_ticks": {str(k): v for k, v in sorted(st.command_age.items())},
               "first_tick_ms": None if st.first_tick_s is None else round(1000 * st.first_tick_s, 3),
               "sense_to_command_ms": latency_ms(inbox.latencies),
               "dropped_messages": self.drops.total + self.record_drops.total, "recorded_messages": pub.recorded,
               "drops": {"commands": self.drops.by_source(), "recorder": self.record_drops.by_source()},
               "late_commands": inbox.late_commands, "events": st.events}
        if self.log_full is not None:
            doc["log_full"] = str(self.log_full)
        doc.update(ep.summary())
        try:
            write_outputs(self.out, doc, ep)
        except OSError as exc:  # the same full disk: the outcome goes out on the DONE line only
            log.error("cannot write %s: %s", self.out / "outcome.json", exc.strerror or exc)
            doc["outputs_unwritten"] = f"{exc.strerror or exc}"
        emit("DONE", {"cpu_s": self.stats.tick_loop_cpu_end, **{k: doc[k] for k in (
            "sim_seconds", "wall_seconds", "aborted", "robots") + (("log_full",) if "log_full" in doc else ())}})
        return doc


def _log_doc(pub: TickPublisher, cfg: WorldConfig) -> dict[str, Any]:
    """What the run's log is: its files (one, or a set), the recording, what a lean one left out."""
    files = getattr(pub.recorder, "files", None) or [pub.recorder.path]
    return {"files": [p.name for p in files], "record": cfg.record, "left_out": pub.record_filter.left_out,
            "max_bytes": cfg.max_log_size, "max_seconds": cfg.max_log_duration}


def open_world_session(cfg: WorldConfig, stop: threading.Event | None = None) -> zenoh.Session:
    """The world's Zenoh session: the router itself with ``--listen``, else a client of
    ``--connect``, waiting up to ``--wait-router`` s for that router to be up (as every
    networked command does: "waiting for the router at ENDPOINT ..." on stdout, which the
    launcher shows, and in the log) until ``stop`` is set."""
    if cfg.listen:
        host, port = tcp_host_port(cfg.listen)
        return open_embedded_router(port, host)
    if cfg.wait_router <= 0:
        return open_client(cfg.connect, config_file=cfg.zenoh_config)

    def say(text: str) -> None:
        log.info("%s", text)
        print(text, flush=True)

    return open_client_when_ready(cfg.connect, cfg.zenoh_config, timeout=cfg.wait_router, say=say, stop=stop)


@click.command("world.server", context_settings={"help_option_names": ["-h", "--help"]})
@world_options
def world_cmd(**values: Any) -> None:
    """The cekm world server: simulate SCENARIO and serve it to the robots' nodes over Zenoh."""
    cfg = WorldConfig(**values)
    if cfg.listen and cfg.connect != WorldConfig.connect and click.get_current_context().get_parameter_source(
            "connect") is click.core.ParameterSource.COMMANDLINE:
        raise click.UsageError("--listen and --connect: host the router, or join one, not both")
    if cfg.listen:
        try:
            host, _ = tcp_host_port(cfg.listen)
        except CekmError as exc:
            raise click.BadParameter(str(exc), param_hint="--listen") from None
        if cfg.zenoh_config:
            raise click.UsageError("--zenoh-config is a client's config; with --listen the world hosts the router")
        if is_loopback(host):
            use_zenoh_runtime(ROUTER_RUNTIME)  # one thread routes a message; sending on a thread of its own
    logging.basicConfig(level=cfg.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s.%(msecs)03d %(name)s %(levelname)s %(message)s", datefmt="%H:%M:%S")
    try:
        server = WorldServer(cfg)
    except (ScenarioError, CheckpointsError, GraphError) as exc:  # refused before anything starts, in one line
        raise Refused(str(exc)) from None
    try:
        doc = asyncio.run(server.run())
    except StoppedWaiting as exc:
        log.warning("%s", exc)
        sys.exit(130)
    except CekmError as exc:  # e.g. the router's port is taken: one clear line for the launcher's log
        log.error("cannot run: %s", exc)
        sys.exit(2)
    sys.exit(4 if "log_full" in doc else 0 if not doc["aborted"] else 3)


def main(argv: list[str] | None = None) -> int:
    die_with_parent()  # started by a launcher: stop (writing the outcome) when it dies, whatever kills it
    try:
        world_cmd.main(args=argv, prog_name="python -m world.server", standalone_mode=True)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
