"""The ROS 2 plant process: the world server's counterpart for robots that live in ROS 2
(``cekm launch SCENARIO --plant ros2``; docs/ros2.md, "Driving a ROS 2 robot").

It speaks ROS 2 over ``rmw_zenoh``'s wire format (:mod:`.wire`) on one side, as a node
``/cekm_plant``, and the project's protocol on the other, as the world server would:

- it reads each robot's ``/<robot>/odom`` and ``/<robot>/scan`` (or ``/<robot>/range_<j>``)
  and ``/<robot>/goal_pose``, checks them (:mod:`.plant`: a message it does not believe is
  dropped and counted by robot, topic and reason), and keeps the latest;
- every tick (0.128 s of the plant's clock: ROS time from ``/clock`` once one came before
  tick 0, else the wall clock) it publishes each robot's readings as the world does
  (``sense/range/<j>``, ``sense/target`` every other tick), then ``world/clock`` and
  ``world/state`` (poses from the odometry) for the tools; a robot whose odometry or
  scan is older than :data:`.plant.STALE_S` gets no readings (and is stopped);
- each wheel command of the graph becomes a Twist on ``/<robot>/cmd_vel`` at once;
- a zero Twist stops a robot when its commands stop for the dead-man limit (checked on
  its own deadline, not only at tick boundaries), when its input is stale, when it reached
  its goal (within :data:`GOAL_TOLERANCE_M`), at the run's end, on SIGINT/SIGTERM;
- ``OUT/run.mcap`` holds the protocol's messages (msgpack, as a world's log) and the robots' ROS 2
  messages it believed and its Twists (CDR, ``ros2msg`` schemas); ``OUT/outcome.json`` what happened.

Stdout lines ``READY``, ``START``, ``PROGRESS``, ``EVENT``, ``DONE`` (JSON) as the world server's. It
imports neither the world nor controller code: the launcher writes what it needs into ``OUT/plant.json``.

``python -m cekm_swarm.ros2.plant_server OUT/plant.json``
"""

from __future__ import annotations

import json
import logging
import math
import queue
import signal
import sys
import threading
import time
from collections import Counter, deque
from pathlib import Path
from typing import Any

import zenoh

from cekm_swarm.graph.runspec import RunSpec
from cekm_swarm.protocol import (
    Clock,
    DropCounter,
    KeySpace,
    RobotState,
    SenseRange,
    TargetState,
    WheelCommand,
    WorldState,
    encode,
)
from cekm_swarm.protocol.stamps import PAST_S, stamp_problem
from cekm_swarm.runtime.bridge import Publishers, declare_alive, wait_matching
from cekm_swarm.runtime.config import open_embedded_router, tcp_host_port
from cekm_swarm.runtime.lifetime import die_with_parent
from cekm_swarm.runtime.mcap_record import SchemaSpec
from cekm_swarm.runtime.mcap_sets import open_recorder
from cekm_swarm.runtime.percentiles import Samples
from cekm_swarm.runtime.record import serve_geometry, serve_json
from cekm_swarm.runtime.wait import open_client_when_ready
from cekm_swarm.ticks import TARGET_EVERY, TICK_S, tick_time

from . import plant as P
from .bridge import _RosPublisher
from .interfaces import interfaces
from .mapping import RosOut, ros_name
from .plant_run import (
    SENDER,
    PlantConfig,
    RobotPort,
    drain_log,
    drop_doc,
    emit,
    outcome_doc,
    progress_doc,
    target_messages,
    wait_alive,
)
from .wire import SUBSCRIPTION, Node, Qos, topic_key

log = logging.getLogger("cekm_swarm.ros2.plant")

NODE_NAME = "cekm_plant"
GOAL_TOLERANCE_M = 0.03
"""A robot whose odometry is this close to its goal has reached it (the checkpoint radius
of the simulated world, and like Nav2's ``xy_goal_tolerance``): it is stopped."""
DEADMAN_MARGIN_S = 0.025
FIRST_INPUT_WAIT_S = 30.0
"""s the plant waits before tick 0 for every robot's first odometry and scan."""
ROS_LOG_QUEUE = 4096
INPUT_QUEUE = 65536
"""Robot messages waiting to be checked; beyond it one is dropped and counted (``input queue full``)."""


class PlantServer:
    """One run against ROS 2 robots (see the module's docstring)."""

    def __init__(self, cfg: PlantConfig) -> None:
        self.cfg = cfg
        self.desc = P.RobotDescription.from_dict(cfg.description)
        self.spec = RunSpec.read(cfg.spec).with_(run_id=cfg.run_id)
        self.plan = self.spec.plan()
        self.keys = KeySpace(cfg.root, self.desc.body.sensors, cfg.run_id)
        self.ifc = interfaces(cfg.distro)
        self.robots = list(cfg.robots)
        self.ports = {r: RobotPort(r, None if g is None else (float(g[0]), float(g[1])))
                      for r, g in cfg.robots.items()}
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.wake = threading.Event()
        self.ros_time: float | None = None  # the newest /clock
        self.use_clock = False  # ROS time from /clock: one came before tick 0
        self.started = False
        self.ended = False  # the run is over: commands are no longer taken
        self.targets: dict[str, tuple[float, float]] = {}  # a tracking run's targets (from /targets)
        self.targets_stamp = -math.inf
        self.drops: Counter[tuple[str, str, str]] = Counter()  # (robot, topic, reason) -> n
        self.cmd_drops = DropCounter("plant commands", keys=self.keys)
        self.received: Counter[str] = Counter()  # topic -> messages
        self.now_t = 0.0  # the sim time of the tick whose readings are out
        self.sent_at: dict[float, float] = {}
        self.sense_to_command = Samples()
        self.scan_to_twist = Samples()
        self.events: list[dict[str, Any]] = []
        self.ros_log: deque[tuple[str, str, bytes]] = deque(maxlen=ROS_LOG_QUEUE)
        self.answer = {self.plan.answer_key(r): r for r in self.robots}
        self.misses: Counter[int] = Counter()
        self.recorded = 0
        self.pending_log: list[tuple[str, bytes, float]] = []
        self._schemas: dict[str, SchemaSpec] = {}
        self.inbox: queue.SimpleQueue[tuple[str, str, str, bytes, float] | None] = queue.SimpleQueue()
        self.input_thread = threading.Thread(target=self._input_loop, name="plant-input", daemon=True)

    # ------------------------------------------------------------------ time

    def now(self) -> float:
        """The plant's clock (s): ROS time from /clock when the robots publish it, else the wall clock."""
        return self.ros_time if self.use_clock and self.ros_time is not None else time.time()

    def event(self, name: str, t: float, extra: dict[str, Any]) -> None:
        doc = {"event": name, "t": t, **extra}
        self.events.append(doc)
        emit("EVENT", doc)

    # ------------------------------------------------------------------ ROS input (Zenoh threads)

    def _refused(self, robot: str, topic: str, exc: P.Refused) -> None:
        with self.lock:
            self.drops[(robot, topic, exc.reason)] += 1
            first = self.drops[(robot, topic, exc.reason)] == 1
        if first:
            log.warning("dropped a message on %s (further ones are only counted): %s", topic, exc)

    def on_sample(self, robot: str, topic: str, kind: str, payload: bytes) -> None:
        """A robot's message, on Zenoh's receiving thread: only queued (with its arrival
        time), so a burst of bad input never holds up the graph's commands."""
        if self.inbox.qsize() >= INPUT_QUEUE:
            with self.lock:
                self.drops[(robot, topic, "input queue full")] += 1
            return
        self.inbox.put((robot, topic, kind, payload, time.monotonic()))

    def _input_loop(self) -> None:
        while (item := self.inbox.get()) is not None:
            try:
                self.on_ros(*item)
            except Exception as exc:  # noqa: BLE001 - one message must not end the plant's input
                log.exception("handling a message on %s failed: %s", item[1], exc)

    def on_ros(self, robot: str, topic: str, kind: str, payload: bytes, at: float) -> None:
        """One ROS message from a robot: checked, kept when believed, logged either way."""
        with self.lock:
            self.received[topic] += 1
        now = self.now()
        try:
            if kind == P.POSE_ARRAY:  # a tracking run's targets
                targets = P.decode_targets(self.ifc, payload, self.desc, self.cfg.target_ids, now)
                with self.lock:
                    self.targets, self.targets_stamp = targets, now
            else:  # a robot's own topic (subscribed for the robots the plant drives only)
                self._robot_reading(robot, self.ports[robot], topic, kind, payload, at, now)
        except P.Refused as exc:
            self._refused(robot, topic, exc)
            return
        self.ros_log.append((topic, kind, payload))  # the log holds what the plant believed

    def _robot_reading(self, robot: str, port: RobotPort, topic: str, kind: str, payload: bytes, at: float,
                       now: float) -> None:
        """A robot's odometry, scan, range or goal, decoded (P.Refused when not believed) and kept."""
        if kind == P.ODOMETRY:
            odom = P.decode_odometry(self.ifc, payload, self.desc, ros_name(robot), now)
            with self.lock:
                port.odom = odom
        elif kind == P.LASER_SCAN:
            scan = P.decode_scan(self.ifc, payload, self.desc, ros_name(robot), now)
            readings = P.scan_readings(scan, self.desc.body)
            with self.lock:
                port.readings, port.scan_stamp, port.scan_at = readings, scan.stamp, at
        elif kind == P.RANGE:
            j = int(topic.rsplit("_", 1)[1])
            stamp, d = P.decode_range(self.ifc, payload, self.desc, ros_name(robot), j, now)
            with self.lock:
                port.ranges[j] = (stamp, d)
                if len(port.ranges) == self.desc.body.sensors:
                    port.readings = [port.ranges[i][1] for i in range(self.desc.body.sensors)]
                    port.scan_stamp, port.scan_at = min(s for s, _ in port.ranges.values()), at
        elif kind == P.POSE_STAMPED:
            goal = P.decode_goal(self.ifc, payload, self.desc, ros_name(robot))
            with self.lock:
                port.goal, port.reached, port.reached_time = goal, False, None
            emit("EVENT", {"event": "goal", "t": self.now_t, "robot": robot, "goal": list(goal)})

    def on_clock(self, payload: bytes) -> None:
        try:
            t = P.decode_clock(self.ifc, payload)
        except P.Refused as exc:
            self._refused("-", "/clock", exc)
            return
        if math.isfinite(t) and (self.ros_time is None or t >= self.ros_time):
            self.ros_time = t
            self.use_clock = self.use_clock or not self.started  # a /clock before tick 0: ROS time for the run
            self.wake.set()

    # ------------------------------------------------------------------ commands (Zenoh thread)

    def on_command(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        robot = self.answer.get(key)
        if robot is None or sample.kind != zenoh.SampleKind.PUT:
            return
        msg = self.cmd_drops.decode(key, sample.payload.to_bytes())
        if not isinstance(msg, WheelCommand):
            return
        why = stamp_problem(msg.stamp, self.now_t, PAST_S, 0.0)
        if why is not None:
            self.cmd_drops.drop(key, why)
            return
        self.log_msg(key, sample.payload.to_bytes(), msg.stamp)
        port, at = self.ports[robot], time.monotonic()
        with self.lock:
            if port.reached:
                return
            port.heard, port.answered = at, max(port.answered, msg.stamp)
            scan_at = port.tick_scan_at.get(msg.stamp)
            sent = self.sent_at.get(msg.stamp)
        self.send_twist(robot, *P.twist_of(msg.v_l, msg.v_r, self.desc.body), command=True)
        with self.lock:
            if sent is not None and msg.stamp == self.now_t:
                self.sense_to_command.append(at - sent)
            if scan_at is not None and msg.stamp == self.now_t:
                self.scan_to_twist.append(time.monotonic() - scan_at)

    def send_twist(self, robot: str, v: float, omega: float, command: bool = False) -> None:
        """A Twist to ``robot``; a ``command``'s is not sent once the run is over (the nodes may still answer)."""
        payload = P.twist_cdr(self.ifc, v, omega)
        port = self.ports[robot]
        with self.lock:
            if command and self.ended:
                return
            port.stopped = v == 0.0 and omega == 0.0
            port.twists += 1
            self.cmd_vel[robot].put(payload)
        self.ros_log.append((f"/{ros_name(robot)}/cmd_vel", P.TWIST, payload))

    def log_msg(self, key: str, payload: bytes, t: float) -> None:
        with self.lock:
            self.pending_log.append((key, payload, t))

    # ------------------------------------------------------------------ set-up

    def _declare(self, session: zenoh.Session) -> None:
        cfg, ifc = self.cfg, self.ifc
        self.node = Node(cfg.domain, str(session.info.zid()), 0, NODE_NAME)
        self.tokens = [session.liveliness().declare_token(self.node.token())]
        self.subs: list[Any] = []
        entity = 0

        def subscribe(topic: str, kind: str, fn: Any) -> None:
            nonlocal entity
            entity += 1
            h = ifc.hash(kind)
            self.tokens.append(session.liveliness().declare_token(
                self.node.entity_token(entity, SUBSCRIPTION, topic, kind, h, Qos())))
            self.subs.append(session.declare_subscriber(topic_key(cfg.domain, topic, kind, h),
                                                        lambda s: fn(s.payload.to_bytes())))

        subscribe("/clock", P.CLOCK, self.on_clock)
        if cfg.task == "tracking":
            subscribe("/targets", P.POSE_ARRAY, lambda b: self.on_sample("-", "/targets", P.POSE_ARRAY, b))
        self.cmd_vel: dict[str, _RosPublisher] = {}
        for r in self.robots:
            ns = f"/{ros_name(r)}"
            topics = [(f"{ns}/odom", P.ODOMETRY), (f"{ns}/goal_pose", P.POSE_STAMPED)]
            topics += ([(f"{ns}/scan", P.LASER_SCAN)] if self.desc.sensors == "scan" else
                       [(f"{ns}/range_{j}", P.RANGE) for j in range(self.desc.body.sensors)])
            for topic, kind in topics:
                subscribe(topic, kind, lambda b, r=r, t=topic, k=kind: self.on_sample(r, t, k, b))
            entity += 1
            self.cmd_vel[r] = _RosPublisher(session, self.node, entity, RosOut(f"{ns}/cmd_vel", P.TWIST, None, 0),
                                            ifc, cfg.domain)
        self.subs += [session.declare_subscriber(k, self.on_command) for k in self.answer]
        self.record_sub = session.declare_subscriber(self.keys.everything(), zenoh.handlers.RingChannel(1 << 13),
                                                     allowed_origin=zenoh.Locality.REMOTE)

    def _wait_ready(self, session: zenoh.Session) -> bool:
        """Before tick 0: every node alive, every reading's subscriber matched, every
        robot's first odometry and distance input in. False when stopped or timed out."""
        expected = self.plan.tokens(self.robots)
        missing = wait_alive(session, self.keys.alive_all(), expected, self.cfg.wait_modules, self.stop)
        if missing:
            self.event("modules_missing", 0.0, {"missing": sorted(missing)})
            return False
        for r in self.robots:
            for k in self.plan.world_keys(r):
                if not self.stop.is_set() and not wait_matching(self._pubs.publisher(k), 30.0):
                    log.warning("no subscriber on %s after 30 s; starting anyway", k)
        deadline = time.monotonic() + FIRST_INPUT_WAIT_S
        said = False
        while not self.stop.is_set():
            with self.lock:
                silent = [r for r, p in self.ports.items() if p.odom is None or p.readings is None]
            if not silent:
                break
            if not said:
                emit("EVENT", {"event": "waiting_for_robots", "t": 0.0, "robots": silent})
                said = True
            if time.monotonic() > deadline:
                self.event("robots_silent", 0.0, {"robots": silent, "after_s": FIRST_INPUT_WAIT_S,
                                                 "drops": drop_doc(self)})
                return False
            self.stop.wait(0.1)
        self.started = True  # the clock chosen now stays the run's
        return not self.stop.is_set()

    def put(self, key: str, msg: Any) -> None:
        payload = encode(msg)
        self._pubs.put(key, payload)
        self.log_msg(key, payload, msg.stamp)

    # ------------------------------------------------------------------ ticks

    def _tick(self, k: int) -> None:
        t = tick_time(k)
        now, mono = self.now(), time.monotonic()
        self.now_t = t
        self.sent_at[t] = mono
        if len(self.sent_at) > 64:
            self.sent_at.pop(next(iter(self.sent_at)))
        robots = {}
        for r, port in self.ports.items():
            with self.lock:
                odom, readings, scan_stamp, scan_at = port.odom, port.readings, port.scan_stamp, port.scan_at
            fresh = odom is not None and readings is not None and min(odom.stamp, scan_stamp) >= now - P.STALE_S
            if odom is not None:
                if port.last_xy is not None:
                    port.path_m += math.hypot(odom.x - port.last_xy[0], odom.y - port.last_xy[1])
                port.last_xy = (odom.x, odom.y)
                robots[r] = RobotState(odom.x, odom.y, odom.theta, goal=port.goal)
                if port.goal is not None and not port.reached and \
                        math.hypot(port.goal[0] - odom.x, port.goal[1] - odom.y) <= GOAL_TOLERANCE_M:
                    port.reached, port.reached_time = True, t
                    self.event("reached", t, {"robot": r})
            if port.reached or not fresh:
                if not fresh and not port.stopped:
                    self.event("stale_input", t, {"robot": r})
                if not port.stopped or port.reached:
                    self.send_twist(r, 0.0, 0.0)
                continue
            assert odom is not None and readings is not None  # fresh
            with self.lock:
                port.tick_scan_at[t] = scan_at
                if len(port.tick_scan_at) > 16:
                    port.tick_scan_at.pop(next(iter(port.tick_scan_at)))
            for j, (a, d) in enumerate(zip(self.desc.body.sensor_angles, readings, strict=True)):
                self.put(self.keys.sense_range(r, j), SenseRange(t, SENDER, j, float(a), d))
            if k % TARGET_EVERY == 0:
                for key, msg in target_messages(self, r, odom, t):
                    self.put(key, msg)
        self.put(self.keys.world_clock(), Clock(t, SENDER, k))
        targets = dict(self.targets) if self.cfg.task == "tracking" else {
            self.cfg.goal_ids.get(r, f"{r}-goal"): p.goal for r, p in self.ports.items() if p.goal}
        states = {i: TargetState(*xy) for i, xy in targets.items()}
        self.put(self.keys.world_state(), WorldState(t, SENDER, robots, states, {}))

    def _wait_boundary(self, boundary: float) -> None:
        """Until the plant's clock reaches ``boundary``, stopping a robot on its dead-man
        deadline meanwhile (the last command plus the limit, less a margin)."""
        limit = self.cfg.deadman
        while not self.stop.is_set():
            mono = time.monotonic()
            due = [(r, p.heard) for r, p in self.ports.items()
                   if not p.stopped and not p.reached and p.heard is not None
                   and mono >= p.heard + limit - DEADMAN_MARGIN_S]
            for r, heard in due:
                silent = mono - heard
                self.send_twist(r, 0.0, 0.0)
                self.event("deadman", self.now_t, {"robot": r, "silent_s": round(silent, 4), "limit_s": limit,
                                                   "wall": time.time()})
            now = self.now()
            if now >= boundary:
                return
            deadlines = [p.heard + limit - DEADMAN_MARGIN_S - mono for p in self.ports.values()
                         if not p.stopped and not p.reached and p.heard is not None]
            wait = min([boundary - now] + deadlines)
            if self.use_clock:
                wait = min(wait, 0.05)  # ROS time may jump: look again soon
            self.wake.wait(max(0.0, wait))
            self.wake.clear()

    def run(self) -> dict[str, Any]:
        cfg = self.cfg
        def on_signal(*_: Any) -> None:
            self.stop.set()
            self.wake.set()

        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, on_signal)
        if cfg.listen:
            host, port = tcp_host_port(cfg.listen)
            self.session = open_embedded_router(port, host)
        else:
            assert cfg.connect is not None  # the launcher gives the plant listen or connect
            self.session = open_client_when_ready(cfg.connect, cfg.zenoh_config, stop=self.stop)
        self._pubs = Publishers(self.session, block=True)  # the readings, as the world's (express: no)
        out = Path(cfg.out)
        recorder = open_recorder(out / "run.mcap", metadata={"scenario": cfg.scenario, "seed": str(cfg.seed),
                                                             "mode": "realtime", "record": "full", "root": cfg.root,
                                                             "plant": "ros2"}, keys=self.keys)
        recorder.add_metadata("geometry", {"json": json.dumps(cfg.geometry)})
        ticks, aborted, wall0, loop_s = 0, True, time.perf_counter(), 0.0
        self.input_thread.start()
        try:
            self._declare(self.session)
            alive = declare_alive(self.session, self.keys.alive("world", "server"))
            served = [serve_geometry(self.session, self.keys.world_geometry(), cfg.geometry),
                      serve_json(self.session, self.keys.world_graph(), self.spec.to_dict())]
            emit("READY", {"endpoint": cfg.listen or cfg.connect, "router": bool(cfg.listen), "plant": "ros2"})
            if self._wait_ready(self.session):
                emit("START", {"mode": "realtime", "robots": self.robots, "scenario": cfg.scenario, "seed": cfg.seed,
                               "cpu_s": time.process_time(), "time": "ros /clock" if self.use_clock else "wall clock"})
                wall0 = time.perf_counter()
                ticks, aborted = self._ticks(recorder)
                loop_s = time.perf_counter() - wall0
            with self.lock:
                self.ended = True
            for r in self.robots:  # the run's end, or a signal: every robot stops
                self.send_twist(r, 0.0, 0.0)
            time.sleep(0.05)
            drain_log(self, recorder)
            ended = declare_alive(self.session, self.keys.world_ended())
            alive.undeclare()
            for q in served:
                q.undeclare()
            ended.undeclare()
            for s in self.subs:
                s.undeclare()
            for p in self.cmd_vel.values():
                p.close()
            for tok in self.tokens:
                tok.undeclare()
        finally:
            self.inbox.put(None)
            self.input_thread.join(timeout=10)
            recorder.close()
            self.session.close()
        return self._outcome(ticks, aborted, time.perf_counter() - wall0, loop_s)

    def _ticks(self, recorder: Any) -> tuple[int, bool]:
        max_ticks = int(math.ceil(self.cfg.max_time / TICK_S))
        start, last_progress, k = self.now(), -1e9, 0
        while True:
            self._tick(k)
            self._wait_boundary(start + (k + 1) * TICK_S)
            for p in self.ports.values():  # a robot that had readings this tick and did not answer it
                if not p.reached and self.now_t in p.tick_scan_at and p.answered < self.now_t:
                    self.misses[k] += 1
            drain_log(self, recorder)
            if time.monotonic() - last_progress >= self.cfg.progress_every:
                last_progress = time.monotonic()
                emit("PROGRESS", progress_doc(self, k))
            if self.stop.is_set():
                self.event("stopped", self.now_t, {"reason": "signal"})
                return k + 1, True
            if all(p.reached for p in self.ports.values()) or k + 1 >= max_ticks:
                return k + 1, False
            k += 1

    def _outcome(self, ticks: int, aborted: bool, wall: float, loop_s: float) -> dict[str, Any]:
        doc = outcome_doc(self, ticks, aborted, wall, loop_s)
        (Path(self.cfg.out) / "outcome.json").write_text(json.dumps(doc, indent=1))
        emit("DONE", {"cpu_s": time.process_time(), "sim_seconds": doc["sim_seconds"],
                      "wall_seconds": doc["wall_seconds"], "aborted": aborted, "robots": doc["robots"]})
        return doc


def main(argv: list[str] | None = None) -> int:
    die_with_parent()
    args = sys.argv[1:] if argv is None else argv
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="%(asctime)s.%(msecs)03d %(name)s %(levelname)s %(message)s", datefmt="%H:%M:%S")
    if len(args) != 1:
        print("usage: python -m cekm_swarm.ros2.plant_server OUT/plant.json", file=sys.stderr)
        return 2
    doc = PlantServer(PlantConfig.read(args[0])).run()
    return 3 if doc["aborted"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
