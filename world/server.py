"""The world server of the distributed runtime: runs a scenario tick by tick with
:class:`world.episode.Episode` (the same world side as the in-process runner) and talks
to the robots' module processes over Zenoh.

Per tick (0.128 s of sim time, stamp = sim time) and robot it publishes
``<root>/<robot>/sense/range/<j>`` (12, every tick) and ``<root>/<robot>/sense/target``
(even ticks), then ``<root>/world/clock`` and ``<root>/world/state``; it applies each
robot's latest ``cmd/wheels`` and advances.

* ``lockstep``: the world advances only when every robot's command stamped with the
  tick's sim time has arrived. If one is missing after ``--republish`` seconds, the tick's
  readings (and each robot's latest target reading) are published again, so a restarted
  module catches up. Same scenario and seed give the same trajectory as ``cekm run``.
* ``realtime``: ticks follow the wall clock, which (with ``--wait-modules``) starts once
  every robot has answered tick 0 (at most ``FIRST_TICK_WAIT_S``: a start-up burst is not
  a missed deadline; its time is ``first_tick_ms``). At each tick boundary the latest command of
  each robot is applied; a robot whose commands have stopped (the next tick would end
  more than ``--deadman`` s after its last command arrived) is stopped (wheels 0) and
  the stop is reported.

A range reading's ``d`` is the obstacle input u_j, the distance from the robot's centre
(surface range + body radius), None when nothing is in range; an out-of-range target is
sent as alpha = d = 0, visible False.

Everything under ``<root>/**`` that passes the checks of :class:`world.recorder.RecordFilter` is recorded
into ``OUT/run.mcap`` (log time: the server's sim time when it is recorded, at most a
tick after it arrived; publish time: its checked stamp), with Foxglove view channels; what fails them is dropped
and counted per source (``drops`` in ``outcome.json``). The world trusts nothing from the
network: a command whose stamp is not a tick's time near the world's clock is dropped too.
Results: ``OUT/outcome.json`` (the fields of ``cekm run``) and
``OUT/trajectory.json`` (pose and command per tick) are written at the end, which is when
every robot reached its goal, at ``--max-time``, or on SIGTERM/SIGINT.

Zenoh: with ``--connect`` the server joins a router as a client; with ``--listen`` it
hosts the router itself (the launcher's embedded default), so a tick's readings leave and
its commands arrive with no router hop between the world and the modules: two of the six
hops of a tick's critical path (world, module, motor, world) are gone. ``--wait-modules S``
holds tick 0 until every module of every robot holds its liveliness token.

Progress goes to stdout as lines ``READY {json}`` (the session is open and the token up),
``START``, ``PROGRESS {json}``, ``EVENT {json}`` and ``DONE {json}``.

``python -m world.server SCENARIO --connect tcp/127.0.0.1:7447 --out DIR [--mode lockstep]``
``python -m world.server SCENARIO --listen tcp/127.0.0.1:7447 --wait-modules 180 --out DIR``

Its pure parts live beside it: the sense messages and their encoder in :mod:`world.sense`,
the recorder's filter and the log's opening in :mod:`world.recorder`, the dead-man in
:mod:`world.deadman`, the tracking episode in :mod:`world.tracking`; its settings are a
:class:`WorldConfig` made from :data:`WORLD_PARAMS`.

Imports only ``world``, ``cekm_swarm.protocol``, ``cekm_swarm.runtime`` and ``cekm_swarm.errors``.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import json
import logging
import math
import os
import signal
import sys
import time
from dataclasses import make_dataclass
from pathlib import Path
from typing import Any

import zenoh

from cekm_swarm.protocol import DEFAULT_ROOT, Clock, DropCounter, KeySpace, WheelCommand, WorldState, encode
from cekm_swarm.errors import CekmError
from cekm_swarm.graph.runspec import RunSpec
from cekm_swarm.graph.spec import GraphError
from cekm_swarm.protocol.stamps import PAST_S, stamp_problem
from cekm_swarm.runtime.bridge import (InlineSubscription, LivelinessWatcher, Publishers, Received, declare_alive,
                                       wait_matching_async)
from cekm_swarm.runtime.config import (DEFAULT_ENDPOINT, ROUTER_RUNTIME, is_loopback, open_client, open_embedded_router,
                                       tcp_host_port, use_zenoh_runtime)
from cekm_swarm.runtime.gc_tuning import freeze_startup_heap
from cekm_swarm.runtime.lifetime import die_with_parent
from cekm_swarm.runtime.mcap_log import McapRecorder
from cekm_swarm.runtime.process_args import Param, add_params, run_id_arg, to_argv
from cekm_swarm.runtime.record import serve_geometry, serve_json
from cekm_swarm.runtime.rungraph import default_nodes

from .deadman import DEADMAN_S, Deadman
from .episode import TICK_S, Episode, TickReadings
from .recorder import RECORD_QUEUE, RecordFilter, open_run_log
from .scenario import ScenarioError, load_scenario
from .sense import SENDER, SenseEncoder
from .sim import World
from .tracking import TrackingEpisode, run_kind

RECORD_BY = 0.75
"""Real time: the fraction of a tick by which the world writes the tick's log if some
robot's command is still missing (it writes it as soon as every command is in). Written
right after the readings went out, the log (about a seventh of the world's CPU, some 5 ms
a tick with 16 robots, py-spy) landed in the burst in which every robot's modules and
motor compete for the two cores."""

FIRST_TICK_WAIT_S = 10.0
"""Real time: how long the world waits for every robot's answer to tick 0 before its wall
clock starts anyway (:meth:`WorldServer._first_answers`)."""

MISSED_TICKS_KEPT = 200
"""Real time: how many ticks with a deadline miss ``outcome.json`` lists (tick -> robots
that missed it), to tell a start-up hiccup from misses spread over the run."""

log = logging.getLogger("world.server")
REPUBLISH_S = 1.0
DEFAULT_MAX_TIME = 600.0


def emit(kind: str, doc: dict[str, Any]) -> None:
    """One progress line on stdout for the launcher. When the launcher is gone (the pipe
    is broken: it was killed, and the server is stopping on its parent-death signal),
    the lines go nowhere and the run still ends cleanly: outcome written, log closed."""
    try:
        sys.stdout.write(f"{kind} {json.dumps(doc)}\n")
        sys.stdout.flush()
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # also for the interpreter's last flush
        os.close(devnull)


# --------------------------------------------------------------------------- the server


class CheckpointsError(ValueError):
    """``--checkpoints`` is unreadable or malformed; the message names what is wrong."""


def parse_checkpoints(value: str, robots: list[str]) -> dict[str, list[tuple[float, float]]]:
    """``--checkpoints``: JSON ``{robot: [[x, y], ...]}``, or the path of a file holding it.
    Raises :class:`CheckpointsError` naming what is wrong (the file, the robot, the entry)."""
    where = "--checkpoints"
    raw = value
    if not value.lstrip().startswith("{"):
        where = f"--checkpoints {value}"
        try:
            raw = Path(value).read_text()
        except OSError as exc:
            raise CheckpointsError(f"{where}: cannot read it ({exc.strerror or exc})") from None
    try:
        doc = json.loads(raw)
    except json.JSONDecodeError as exc:
        raise CheckpointsError(f"{where}: not JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise CheckpointsError(f"{where}: must be a JSON object {{robot: [[x, y], ...]}}, got {type(doc).__name__}")
    out: dict[str, list[tuple[float, float]]] = {}
    for robot, cps in doc.items():
        if robot not in robots:
            raise CheckpointsError(f"{where}: no robot {robot!r} in the scenario (robots: {', '.join(robots)})")
        if not isinstance(cps, list) or not cps:
            raise CheckpointsError(f"{where}: {robot}: must be a non-empty list of [x, y]")
        for i, c in enumerate(cps):
            if not (isinstance(c, list) and len(c) == 2
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in c)):
                raise CheckpointsError(f"{where}: {robot}[{i}]: must be [x, y] with finite numbers, got {c!r}")
        out[robot] = [(float(c[0]), float(c[1])) for c in cps]
    return out


def load_run_graph(path: str | None, scenario: Any, robots: list[str], task: str, root: str,
                   run_id: str | None) -> tuple[Any, Any]:
    """The run spec at ``path`` and its plan for this run (None, None without one),
    refused with a :class:`CheckpointsError`-like one-line error when it does not fit the
    scenario (another team, task or key root)."""
    if not path:
        return None, None
    spec = RunSpec.read(path)
    if tuple(spec.team) != tuple(robots):
        raise GraphError(path, "team", f"the run spec is for robots {', '.join(spec.team)}, the scenario "
                                       f"{scenario.name!r} has {', '.join(robots)}")
    if spec.task != task:
        raise GraphError(path, "task", f"the run spec is for a {spec.task} run, {scenario.name!r} is a {task} scenario")
    if spec.root != root:
        raise GraphError(path, "root", f"the run spec's key root is {spec.root!r}, the world's {root!r}")
    spec = spec.with_(run_id=run_id)
    return spec, spec.plan()


class WorldServer:
    """One run of a scenario over Zenoh (see the module's docstring), set up from a
    :class:`WorldConfig`; :meth:`run` runs it and writes its outputs."""

    def __init__(self, config: WorldConfig) -> None:
        self.config = cfg = config
        self.keys = KeySpace(cfg.root, run=cfg.run_id)
        self.scenario = load_scenario(cfg.scenario)
        checkpoints = parse_checkpoints(cfg.checkpoints, [r.id for r in self.scenario.robots]) if cfg.checkpoints else None
        task = run_kind(self.scenario, checkpoints or {})
        self.tracking = task == "tracking"  # docs/tracking.md
        self.world = World(self.scenario, seed=cfg.seed)
        self.robots = list(self.world.robot_ids)
        self.spec, self.plan = load_run_graph(cfg.spec, self.scenario, self.robots, task, cfg.root, cfg.run_id)
        self.controller = self.spec.graph.controller if self.spec is not None else "cekm"
        self.out = Path(cfg.out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.lockstep = cfg.mode == "lockstep"
        self.max_ticks = int(math.ceil(cfg.max_time / TICK_S))
        self.drops = DropCounter("world commands", keys=self.keys)
        self.record_drops = DropCounter("world recorder", keys=self.keys)
        declared = None if self.plan is None else {k: v for r in self.robots for k, v in self.plan.sent_keys(r).items()}
        self.record_filter = RecordFilter(self.keys, self.robots, self.record_drops, declared)
        self.episode = TrackingEpisode(self.world, self.max_ticks) if self.tracking else Episode(self.world, checkpoints)
        self.cmd_keys = ({self.plan.answer_key(r): r for r in self.robots} if self.plan is not None
                         else {self.keys.cmd_wheels(r): r for r in self.robots})
        # what the world publishes per robot: the sense keys its graph reads (no graph: every one of the task)
        self.sends: dict[str, set[str]] | None = (None if self.plan is None else
                                                   {r: set(self.plan.world_keys(r)) for r in self.robots})
        self.latest: dict[str, WheelCommand] = {}
        self.arrived = asyncio.Event()
        self.events: list[dict[str, Any]] = []
        self.republished = 0
        self.deadline_misses = 0
        self.first_tick_s: float | None = None  # real time: tick 0's readings to its last command
        self.missed_ticks: dict[int, int] = {}  # real time: tick -> robots that missed it (the first MISSED_TICKS_KEPT ticks)
        self.latencies: list[float] = []  # s from publishing a tick's readings to its command
        self.sent_at: dict[float, float] = {}
        self.last_target: dict[str, bytes] = {}  # the latest target reading's payload, per robot
        self.last_tracking: dict[str, tuple[Any, Any]] = {}  # tracking: the latest (SensePose, SenseTargets), per robot
        self._sense_encoders: dict[str, SenseEncoder] = {}
        self.stop = asyncio.Event()
        self.stop_reason = "signal"
        self.recorded = 0
        self.tick_loop_seconds = 0.0  # wall s from the first tick's readings to the last tick
        self._unrecorded: list[tuple[str, bytes, float]] = []
        self._unviewed: tuple[float, dict[str, Any]] | None = None  # the tick's (t, state) for the views
        self.now = 0.0  # the sim time of the tick whose readings are out (read by Zenoh's thread)
        self.late_commands = 0
        # set when the run starts (run()); declared here so every attribute has one home
        self.deadman = Deadman(self.robots, cfg.deadman, time.monotonic())  # restarted at the run's start
        self._loop: asyncio.AbstractEventLoop | None = None  # the run's loop: Zenoh's thread wakes it
        self._lat_pending: collections.deque[tuple[str, float, float]] = collections.deque()
        self._lat_seen: dict[tuple[str, float], float] = {}
        self.recorder: McapRecorder | None = None  # run.mcap, open while the run runs
        self.views: Any = None  # Foxglove views of the log, when foxglove-sdk is installed
        self.pubs: Publishers | None = None
        self.record_sub: Any = None  # Zenoh subscriber with a ring channel (RECORD_QUEUE)
        self.cmd_subs: list[InlineSubscription] = []

    # ------------------------------------------------------------------ receiving

    def _on_command(self, rec: Received) -> None:
        """A ``cmd/wheels`` sample, on Zenoh's receiving thread: keep the robot's latest
        command, note when it was heard (dead-man) and how long after its tick's readings
        it came; in lockstep, wake the tick loop. Touches only what the loop reads whole."""
        robot = self.cmd_keys.get(rec.key)
        if robot is None:
            if rec.kind == "put":
                self.drops.drop(rec.key, "no robot of this run has this key")
            return
        if rec.kind != "put":
            return
        msg = self.drops.decode(rec.key, rec.payload)
        if not isinstance(msg, WheelCommand):
            return
        why = stamp_problem(msg.stamp, self.now, PAST_S, 0.0)  # a command is for a tick already out
        if why is not None:
            self.drops.drop(rec.key, why)
            return
        if (old := self.latest.get(robot)) is not None and msg.stamp < old.stamp:
            self.late_commands += 1  # believable but superseded (a motor's repeat for a re-published tick)
            return
        self.latest[robot] = msg
        self.deadman.heard(robot, rec.at)
        sent = self.sent_at.get(msg.stamp)
        if sent is not None:
            self._lat_pending.append((robot, msg.stamp, rec.at - sent))
        if self._tick_answered():  # one wake-up of the tick loop per tick, not per robot
            self._loop.call_soon_threadsafe(self.arrived.set)

    def _waiting(self, t: float) -> list[str]:
        """The robots whose latest command is not for the tick at sim time ``t``."""
        return [r for r in self.robots if (c := self.latest.get(r)) is None or c.stamp != t]

    def _tick_answered(self) -> bool:
        """Every robot's latest command is for the current tick (on Zenoh's thread, per command)."""
        now, latest = self.now, self.latest
        return all((c := latest.get(r)) is not None and c.stamp == now for r in self.robots)

    def _drain_records(self, now: float) -> None:
        """Record what other sessions sent under ``<root>/**`` since the last drain (it
        arrived during the previous tick or, just now, this one): log time ``now``, the
        server's sim time, publish time the message's checked stamp (:class:`RecordFilter`).
        Done once per tick in one batch: no thread wakes up per message."""
        put = zenoh.SampleKind.PUT
        check = self.record_filter.check
        while (sample := self.record_sub.try_recv()) is not None:
            if sample.kind != put:
                continue
            key, payload = str(sample.key_expr), sample.payload.to_bytes()
            stamp = check(key, payload, now)
            if stamp is not None:
                self.recorder.write(key, payload, now, stamp)
                self.recorded += 1

    # ------------------------------------------------------------------ publishing

    def _send(self, key: str, msg: Any) -> None:
        """Publish ``msg``; it is recorded by :meth:`_record_sent` (the record subscription
        sees only other sessions)."""
        self._put(key, encode(msg), msg.stamp)

    def _put(self, key: str, payload: bytes, stamp: float) -> None:
        self.pubs.put(key, payload)
        self._unrecorded.append((key, payload, stamp))

    def _sense(self, rd: TickReadings) -> list[tuple[str, bytes]]:
        enc = self._sense_encoders.get(rd.robot)
        if enc is None:
            w = self.world
            enc = self._sense_encoders[rd.robot] = SenseEncoder(self.keys, rd.robot, w.sensor_angles, w.body_radius)
        return enc(rd)

    def _record_sent(self) -> None:
        for key, payload, stamp in self._unrecorded:
            self.recorder.write(key, payload, stamp)
        self.recorded += len(self._unrecorded)
        self._unrecorded.clear()

    def _publish_tick(self, readings: list[TickReadings]) -> None:
        w, ep = self.world, self.episode
        self.now = ep.t  # commands from here on may be for this tick
        self.sent_at[ep.t] = time.monotonic()
        if len(self.sent_at) > 64:
            self.sent_at.pop(next(iter(self.sent_at)))
        sends = self.sends
        for rd in readings:
            want = None if sends is None else sends[rd.robot]
            for key, payload in self._sense(rd):
                if want is None or key in want:
                    self._put(key, payload, rd.t)
            if rd.target is not None:
                self.last_target[rd.robot] = payload  # the last one: the target's
            if self.tracking and rd.robot in ep.sense:
                pose, targets = self.last_tracking[rd.robot] = ep.sense[rd.robot]
                for key, msg in ((self.keys.sense_targets(rd.robot), targets), (self.keys.sense_pose(rd.robot), pose)):
                    if want is None or key in want:
                        self._send(key, msg)
        self._send(self.keys.world_clock(), Clock(ep.t, SENDER, ep.tick))
        st = w.state()
        self._send(self.keys.world_state(), WorldState(ep.t, SENDER, st["robots"], st["targets"], st["obstacles"]))
        self._unviewed = (ep.t, st)
        if self.lockstep:  # the modules compute now, and the log is written meanwhile
            self._record_tick()

    def _record_tick(self) -> None:
        """Write the tick's log: what the world sent, its views, and what other sessions
        sent since the last drain. In lockstep right after publishing (the robots are
        computing); in real time once every robot's command for the tick is in, or at
        :data:`RECORD_BY` of the tick, so it is not part of the tick's burst."""
        self._record_sent()
        if self._unviewed is not None:
            t, st = self._unviewed
            self._unviewed = None
            if self.views is not None:
                self.views.write_state(t, st)
                if self.tracking:
                    self.views.write_tracking(t, st, self.world.target_range, self.episode.observed_by)
        self._drain_records(self.now)

    def _republish(self, readings: list[TickReadings], waiting: list[str]) -> None:
        w = self.world
        for rd in readings:
            if rd.robot not in waiting:
                continue
            want = None if self.sends is None else self.sends[rd.robot]
            sense = self._sense(rd)
            for key, payload in sense[:len(w.sensor_angles)]:
                if want is None or key in want:
                    self._put(key, payload, rd.t)
            last = self.last_target.get(rd.robot)
            if last is not None and (want is None or self.keys.sense_target(rd.robot) in want):
                self._put(self.keys.sense_target(rd.robot), last, rd.t)
            sensed = self.last_tracking.get(rd.robot)
            if sensed is not None:  # tracking: the latest target tick's pose and targets
                for key, msg in ((self.keys.sense_targets(rd.robot), sensed[1]), (self.keys.sense_pose(rd.robot), sensed[0])):
                    if want is None or key in want:
                        self._send(key, msg)
        self._record_sent()
        self.republished += 1

    # ------------------------------------------------------------------ loops

    async def _lockstep_commands(self, readings: list[TickReadings]) -> dict[str, tuple[float, float]]:
        t = self.episode.t
        loop = asyncio.get_running_loop()
        next_republish = loop.time() + self.config.republish
        while True:
            waiting = self._waiting(t)
            if not waiting:
                return {r: (self.latest[r].v_l, self.latest[r].v_r) for r in self.robots}
            if self.stop.is_set():
                raise asyncio.CancelledError
            self.arrived.clear()
            timeout = next_republish - loop.time()
            if timeout <= 0:
                self._event("republish", {"waiting": waiting})
                self._republish(readings, waiting)
                next_republish = loop.time() + self.config.republish
                continue
            try:  # woken when the tick is answered, or by a stop (_request_stop sets both)
                await asyncio.wait_for(self.arrived.wait(), timeout)
            except asyncio.TimeoutError:
                pass

    async def _await_answers(self, until: float) -> None:
        """Wait until every robot's command for the current tick is in, the run is stopped,
        or the loop's clock reaches ``until`` (woken by :meth:`_on_command` once per tick)."""
        loop = asyncio.get_running_loop()
        while not self._tick_answered() and not self.stop.is_set() and loop.time() < until:
            self.arrived.clear()
            if self._tick_answered():  # a command in between: its wake-up came before the clear
                break
            try:
                await asyncio.wait_for(self.arrived.wait(), max(0.0, until - loop.time()))
            except asyncio.TimeoutError:
                pass

    async def _first_answers(self) -> float:
        """Real time, with ``--wait-modules`` (the launcher's way: every module is known to
        listen): wait (at most :data:`FIRST_TICK_WAIT_S`) until every robot's command
        for tick 0 is in, and return the loop time at which the wall clock starts: tick 0's
        deadline is then a tick later. The first message every process handles, and the
        router's first routing of every key, cost a start-up burst of a few hundred ms (16
        robots: 0.3 s), which otherwise made robots miss the first ticks' deadlines one
        after another. How long it took is ``first_tick_ms`` in ``outcome.json``."""
        loop = asyncio.get_running_loop()
        await self._await_answers(loop.time() + FIRST_TICK_WAIT_S)
        waiting = self._waiting(self.now)
        if waiting and not self.stop.is_set():
            self._event("first_tick_unanswered", {"after_s": FIRST_TICK_WAIT_S, "waiting": waiting})
        self.first_tick_s = time.monotonic() - self.sent_at.get(self.now, time.monotonic())
        return loop.time()

    async def _realtime_commands(self, start: float) -> dict[str, tuple[float, float]]:
        loop = asyncio.get_running_loop()
        ep = self.episode
        boundary = start + (ep.tick + 1) * TICK_S
        await self._await_answers(boundary - (1 - RECORD_BY) * TICK_S)  # the tick's burst
        self._record_tick()
        try:
            await asyncio.wait_for(self.stop.wait(), max(0.0, boundary - loop.time()))
            raise asyncio.CancelledError
        except asyncio.TimeoutError:
            pass
        now = time.monotonic()
        commands = {}
        for r in self.robots:
            c = self.latest.get(r)
            if c is None or c.stamp < ep.t:
                self.deadline_misses += 1
                if ep.tick in self.missed_ticks or len(self.missed_ticks) < MISSED_TICKS_KEPT:
                    self.missed_ticks[ep.tick] = self.missed_ticks.get(ep.tick, 0) + 1
            stop, newly = self.deadman.check(r, now, TICK_S)
            if stop or c is None:
                commands[r] = (0.0, 0.0)
                if newly:
                    self._event("deadman", {"robot": r, "silent_s": round(now - self.deadman.last[r], 4),
                                            "limit_s": self.deadman.limit, "wall": time.time()})
            else:
                commands[r] = (c.v_l, c.v_r)
        return commands

    def _event(self, kind: str, doc: dict[str, Any]) -> None:
        doc = {"event": kind, "t": self.episode.t, **doc}
        self.events.append(doc)
        emit("EVENT", doc)

    def _progress(self) -> None:
        ep = self.episode
        robots = {}
        for r in self.robots:
            x, y, _ = self.world.pose(r)
            p = ep.progress[r]
            to_goal = None
            if not self.tracking:
                gx, gy = self.world.goal_of(r)
                to_goal = round(math.hypot(gx - x, gy - y), 3)
            robots[r] = {"x": round(x, 3), "y": round(y, 3), "to_goal": to_goal,
                         "reached": p.reached, "stopped": self.deadman.stopped.get(r, False)}
        emit("PROGRESS", {"t": ep.t, "tick": ep.tick, "robots": robots, "republished": self.republished,
                          "deadline_misses": self.deadline_misses})

    def _request_stop(self) -> None:
        """End the run: the tick loop sees ``stop`` at its next wait (waking a lockstep wait)."""
        self.stop.set()
        self.arrived.set()

    async def run(self) -> dict[str, Any]:
        cfg = self.config
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            try:
                loop.add_signal_handler(sig, self._request_stop)
            except (NotImplementedError, RuntimeError):  # pragma: no cover
                pass
        self._loop = loop
        self.deadman = Deadman(self.robots, cfg.deadman, time.monotonic())
        geometry = self.world.static_geometry()
        self.recorder, self.views = open_run_log(self.out / "run.mcap", self.scenario.name, self.world.seed, cfg.mode,
                                                 geometry, self.world.body_radius)
        try:
            session = open_world_session(cfg)
        except BaseException:
            self.recorder.close()
            raise
        t_wall0 = time.perf_counter()  # set again once the modules are alive: wall_seconds is the run's own
        aborted = False
        try:
            self.pubs = Publishers(session, block=True, express=False)
            self.record_sub = session.declare_subscriber(self.keys.everything(), zenoh.handlers.RingChannel(RECORD_QUEUE),
                                                         allowed_origin=zenoh.Locality.REMOTE)
            answers_on = ([self.keys.cmd_wheels_all()] if all(k == self.keys.cmd_wheels(r) for k, r in self.cmd_keys.items())
                          else list(self.cmd_keys))
            self.cmd_subs = [InlineSubscription(session, k, self._on_command) for k in answers_on]
            token = declare_alive(session, self.keys.alive("world", "server"))
            scene = serve_geometry(session, self.keys.world_geometry(), geometry)  # for `cekm record`
            graph_q = None if self.spec is None else serve_json(session, self.keys.world_graph(), self.spec.to_dict())
            emit("READY", {"endpoint": cfg.listen or cfg.connect, "router": bool(cfg.listen)})
            if cfg.wait_modules > 0 and not await self._wait_for_modules(session, cfg.wait_modules):
                self._request_stop()
            t_wall0 = time.perf_counter()
            # Every module's subscription must be known before tick 0 is published.
            for r in self.robots:
                if self.plan is not None:
                    keys = self.plan.world_keys(r)
                else:
                    first = ([self.keys.sense_targets(r), self.keys.sense_pose(r)] if self.tracking
                             else [self.keys.sense_target(r)])
                    keys = first + [self.keys.sense_range(r, j) for j in range(self.keys.range_sensors)]
                for k in keys:
                    if self.stop.is_set():
                        break
                    if not await wait_matching_async(self.pubs.publisher(k), cfg.match_timeout):
                        log.warning("no subscriber on %s after %.0f s; starting anyway", k, cfg.match_timeout)
            start = loop.time()
            last_progress = -1e9
            ep = self.episode
            try:
                if self.stop.is_set():  # interrupted (or modules missing) before tick 0
                    raise asyncio.CancelledError
                freeze_startup_heap()  # no full collection walks the world, its log and its session mid-run
                emit("START", {"mode": cfg.mode, "robots": self.robots, "scenario": self.scenario.name,
                               "seed": self.world.seed})
                while True:
                    readings = ep.readings()
                    self._publish_tick(readings)
                    if self.lockstep:
                        commands = await self._lockstep_commands(readings)
                    else:
                        if ep.tick == 0:  # the wall clock starts once tick 0 is answered (or now,
                            # when the world was not told to wait for the modules: none may listen yet)
                            clock0 = await self._first_answers() if cfg.wait_modules > 0 else loop.time()
                        commands = await self._realtime_commands(clock0)
                    self._collect_latency(ep.t)
                    ep.apply(commands)
                    now = time.monotonic()
                    if now - last_progress >= cfg.progress_every:
                        last_progress = now
                        self._progress()
                    if ep.done or ep.tick >= self.max_ticks:
                        break
                    ep.advance()
            except asyncio.CancelledError:
                aborted = True
                self._event("stopped", {"reason": self.stop_reason})
            self.tick_loop_seconds = loop.time() - start
            self._progress()
            # what is still in flight gets recorded
            await asyncio.sleep(0.05)
            for sub in self.cmd_subs:
                sub.close()
            self._record_tick()
            token.undeclare()
            scene.undeclare()
            if graph_q is not None:
                graph_q.undeclare()
            self.record_sub.undeclare()
            self.pubs.close()
        finally:
            session.close()
            self.recorder.close()
        return self._write_outputs(time.perf_counter() - t_wall0, aborted)

    async def _wait_for_modules(self, session: zenoh.Session, timeout: float) -> bool:
        """Hold tick 0 until every module of every robot holds its liveliness token (at most
        ``timeout`` s, or until SIGTERM); False, with an event naming the missing ones, if
        some never came."""
        if self.plan is not None:
            expected = self.plan.tokens(self.robots)
        else:  # no run spec: the nodes of the default controller's graph (cekm)
            names = default_nodes("tracking" if self.tracking else "navigation", self.keys.range_sensors)
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
            self._event("modules_missing", {"after_s": timeout, "missing": sorted(missing)})
            log.error("%d of %d modules not alive after %.0f s: %s", len(missing), len(expected), timeout,
                      ", ".join(sorted(missing)[:8]))
            return False
        return True

    def _collect_latency(self, t: float) -> None:
        """Each robot's latency for tick ``t``: to the last command stamped ``t`` heard so far
        (in real time the motor may send several per tick)."""
        seen = self._lat_seen
        while self._lat_pending:
            robot, stamp, lat = self._lat_pending.popleft()
            seen[(robot, stamp)] = lat
        first = not self.lockstep and self.episode.tick == 0  # the start-up burst: first_tick_ms
        for r in self.robots:
            lat = seen.pop((r, t), None)
            if lat is not None and not first:
                self.latencies.append(lat)
        for k in [k for k in seen if k[1] <= t]:
            del seen[k]

    def _write_outputs(self, wall: float, aborted: bool) -> dict[str, Any]:
        ep = self.episode
        lat = sorted(self.latencies)

        def q(p: float) -> float | None:
            return None if not lat else round(lat[min(len(lat) - 1, int(p * len(lat)))] * 1000, 3)

        doc = {"scenario": self.scenario.name, "controller": self.controller,
               "graph": None if self.spec is None else self.spec.graph.name, "seed": self.world.seed, "robots": ep.outcome(),
               "wall_seconds": round(wall, 3), "tick_loop_seconds": round(self.tick_loop_seconds, 3),
               "mode": self.config.mode, "sim_seconds": ep.t, "ticks": ep.tick,
               "aborted": aborted, "republished": self.republished, "deadline_misses": self.deadline_misses,
               "deadline_miss_ticks": {str(k): v for k, v in self.missed_ticks.items()},
               "first_tick_ms": None if self.first_tick_s is None else round(1000 * self.first_tick_s, 3),
               "sense_to_command_ms": {"p50": q(0.5), "p99": q(0.99), "n": len(lat)},
               "dropped_messages": self.drops.total + self.record_drops.total, "recorded_messages": self.recorded,
               "drops": {"commands": self.drops.by_source(), "recorder": self.record_drops.by_source()},
               "late_commands": self.late_commands,
               "events": self.events}
        if self.tracking:
            doc["tracking"] = ep.meter.summary()
        (self.out / "outcome.json").write_text(json.dumps(doc, indent=1))
        traj = {}
        for r, p in ep.progress.items():
            t, x, y, th = (list(c) for c in zip(*p.path)) if p.path else ([], [], [], [])
            traj[r] = {"t": t, "x": x, "y": y, "theta": th, "v_l": [c[0] for c in p.commands],
                       "v_r": [c[1] for c in p.commands], "checkpoints": [list(c) for c in p.checkpoints],
                       "checkpoint_times": list(p.checkpoint_times)}
        (self.out / "trajectory.json").write_text(json.dumps(traj))
        emit("DONE", {k: doc[k] for k in ("sim_seconds", "wall_seconds", "aborted", "robots")})
        return doc


def open_world_session(cfg: WorldConfig) -> zenoh.Session:
    """The world's Zenoh session: the router itself with ``--listen``, else a client of
    ``--connect``."""
    if cfg.listen:
        host, port = tcp_host_port(cfg.listen)
        return open_embedded_router(port, host)
    return open_client(cfg.connect, config_file=cfg.zenoh_config)


WORLD_PARAMS: tuple[Param, ...] = (
    Param("scenario", positional=True, help="scenario name (world/scenarios) or .toml path"),
    Param("spec", help="the run spec (cekm launch writes OUT/run-spec.json): the controller's graph, from which the "
                       "world takes the nodes it waits for, the readings it publishes and the keys it records "
                       "(default: every reading of the scenario's task, commands on cmd/wheels)"),
    Param("connect", default=DEFAULT_ENDPOINT, exclusive="where",
          help="join this router as a client (default %(default)s)"),
    Param("listen", metavar="tcp/HOST:PORT", exclusive="where",
          help="host the router here (the embedded default) instead of joining one"),
    Param("zenoh_config", help="Zenoh client config file (credentials, TLS; see deploy/)"),
    Param("wait_modules", float, 0.0, metavar="S",
          help="hold tick 0 until every robot's modules are alive, at most S s (0: do not wait)"),
    Param("root", default=DEFAULT_ROOT),
    Param("run_id", run_id_arg, help="the launch's run id: the world's token carries it, and it waits only for modules of this run"),
    Param("out", required=True, help="directory for run.mcap, outcome.json, trajectory.json"),
    Param("mode", default="realtime", choices=("realtime", "lockstep")),
    Param("seed", int),
    Param("max_time", float, DEFAULT_MAX_TIME),
    Param("checkpoints", help="JSON {robot: [[x, y], ...]} or a file holding it"),
    Param("deadman", float, DEADMAN_S, "s without commands before a robot is stopped"),
    Param("republish", float, REPUBLISH_S, "lockstep: s before re-publishing a tick"),
    Param("match_timeout", float, 20.0),
    Param("progress_every", float, 1.0, "wall s between PROGRESS lines"),
    Param("log_level", default="INFO"),
)
"""The world server's parameters: its parser, the launcher's argv and :class:`WorldConfig`
all come from here."""


def _field_type(p: Param) -> Any:
    """A config field's type: the parameter's parsed type (a validating function such as
    ``run_id_arg`` gives a str), optional when the parameter may be absent."""
    kind = p.type if isinstance(p.type, type) else str
    return kind if p.required or p.positional or p.default is not None else kind | None


def _from_args(cls: type, args: argparse.Namespace) -> Any:
    """The config of a parsed command line (a parser built from :data:`WORLD_PARAMS`)."""
    return cls(**{p.name: getattr(args, p.name) for p in WORLD_PARAMS})


WorldConfig = make_dataclass(
    "WorldConfig", [(p.name, _field_type(p)) for p in WORLD_PARAMS], frozen=True,
    namespace={"from_args": classmethod(_from_args),
               "__doc__": "The world server's settings, one frozen field per parameter of WORLD_PARAMS "
                          "(built from them, not declared twice): WorldConfig.from_args(parser().parse_args())."})
WorldConfig.__module__ = __name__


def parser() -> argparse.ArgumentParser:
    return add_params(argparse.ArgumentParser(description="cekm world server"), WORLD_PARAMS)


def server_argv(**values: Any) -> list[str]:
    """The command line that starts the world server with ``values`` of :data:`WORLD_PARAMS`."""
    return [sys.executable, "-m", "world.server", *to_argv(WORLD_PARAMS, **values)]


def main(argv: list[str] | None = None) -> int:
    die_with_parent()  # started by a launcher: stop (writing the outcome) when it dies, whatever kills it
    p = parser()
    args = p.parse_args(argv)
    if args.listen:
        try:
            host, _ = tcp_host_port(args.listen)
        except CekmError as exc:
            p.error(f"--listen: {exc}")
        if args.zenoh_config:
            p.error("--zenoh-config is a client's config; with --listen the world hosts the router")
        if is_loopback(host):
            use_zenoh_runtime(ROUTER_RUNTIME)  # one thread routes a message; sending on a thread of its own
    logging.basicConfig(level=args.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s.%(msecs)03d %(name)s %(levelname)s %(message)s", datefmt="%H:%M:%S")
    try:
        server = WorldServer(WorldConfig.from_args(args))
    except (ScenarioError, CheckpointsError, GraphError) as exc:  # refused before anything starts
        p.error(str(exc))
    try:
        doc = asyncio.run(server.run())
    except CekmError as exc:  # e.g. the router's port is taken: one clear line for the launcher's log
        log.error("cannot run: %s", exc)
        return 2
    return 0 if not doc["aborted"] else 3


if __name__ == "__main__":
    raise SystemExit(main())
