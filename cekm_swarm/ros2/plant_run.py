"""The ROS 2 plant's run state as plain data: its configuration (``OUT/plant.json``, written
by the launcher), each robot's side, the launcher's stdout lines and ``outcome.json``."""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from cekm_swarm.protocol import SensePose, SenseTarget, SenseTargets
from cekm_swarm.runtime.mcap_record import SchemaSpec
from cekm_swarm.runtime.percentiles import Samples
from cekm_swarm.ticks import tick_time

from . import plant as P

SENDER = "world"
"""The sender of the readings: the nodes' graph reads them as the world's."""


@dataclass
class PlantConfig:
    """What the launcher writes into ``OUT/plant.json``."""

    scenario: str
    seed: int
    robots: dict[str, list[float] | None]  # robot -> goal (x, y) in its odometry frame, None: from goal_pose
    description: dict[str, Any]
    out: str
    spec: str
    root: str = "cekm"
    run_id: str | None = None
    domain: int = 0
    distro: str = "jazzy"
    listen: str | None = None
    connect: str | None = None
    zenoh_config: str | None = None
    max_time: float = 600.0
    deadman: float = 0.5
    wait_modules: float = 180.0
    progress_every: float = 1.0
    geometry: dict[str, Any] = field(default_factory=dict)
    goal_ids: dict[str, str] = field(default_factory=dict)
    task: str = "navigation"  # or tracking: the targets come on /targets
    target_ids: list[str] = field(default_factory=list)  # ... the i-th pose of /targets is the i-th of these

    def write(self, path: Path) -> Path:
        path.write_text(json.dumps(self.__dict__, indent=1))
        return path

    @classmethod
    def read(cls, path: str | Path) -> PlantConfig:
        return cls(**json.loads(Path(path).read_text()))


def emit(kind: str, doc: dict[str, Any]) -> None:
    """One line for the launcher (nowhere when it is gone)."""
    try:
        sys.stdout.write(f"{kind} {json.dumps(doc)}\n")
        sys.stdout.flush()
    except (BrokenPipeError, OSError):
        pass


@dataclass
class RobotPort:
    """One robot's side of the plant: its latest believed input, goal, command and progress."""

    robot: str
    goal: tuple[float, float] | None
    odom: P.Odom | None = None
    readings: list[float | None] | None = None  # d per sensor from the latest scan (or Ranges)
    scan_stamp: float = -math.inf  # the plant-clock stamp of the newest distance input
    scan_at: float = 0.0  # when it arrived (monotonic s)
    ranges: dict[int, tuple[float, float | None]] = field(default_factory=dict)  # range topics: j -> (stamp, d)
    reached: bool = False
    reached_time: float | None = None
    path_m: float = 0.0
    last_xy: tuple[float, float] | None = None
    heard: float | None = None  # monotonic s of the last wheel command
    stopped: bool = True  # the last Twist sent was a zero one
    tick_scan_at: dict[float, float] = field(default_factory=dict)  # tick -> arrival of the scan it used
    twists: int = 0
    answered: float = -1.0  # the stamp of the newest command taken


def latency_ms(s: Samples) -> dict[str, Any]:
    """p50 and p99 in ms, and how many."""
    if not len(s):
        return {"p50": None, "p99": None, "n": 0}
    return {"p50": round(1000 * s.percentile(0.5), 3), "p99": round(1000 * s.percentile(0.99), 3), "n": len(s)}


def outcome_doc(plant: Any, ticks: int, aborted: bool, wall: float, loop_s: float) -> dict[str, Any]:
    """``outcome.json`` of a plant run (:class:`.plant_server.PlantServer` ``plant``): per robot whether it
    reached its goal, its path from the odometry, its Twists; the latencies, the drops by topic and reason."""
    robots = {}
    for r, p in plant.ports.items():
        o = p.odom
        robots[r] = {"reached": None if plant.cfg.task == "tracking" else p.reached,
                     "time_s": p.reached_time if p.reached else tick_time(max(ticks - 1, 0)),
                     "path_length_m": round(p.path_m, 4), "collisions": None,
                     "final_distance_m": None if o is None or p.goal is None else
                     round(math.hypot(p.goal[0] - o.x, p.goal[1] - o.y), 4),
                     "goal": None if p.goal is None else list(p.goal), "twists": p.twists,
                     "final_pose": None if o is None else [o.x, o.y, o.theta]}
    drops = drop_doc(plant)
    doc = {"scenario": plant.cfg.scenario, "plant": "ros2", "controller": plant.spec.graph.controller,
           "graph": plant.spec.graph.name, "seed": plant.cfg.seed, "robots": robots, "mode": "realtime",
           "time_source": "ros /clock" if plant.use_clock else "wall clock", "wall_seconds": round(wall, 3),
           "tick_loop_seconds": round(loop_s, 3), "sim_seconds": tick_time(max(ticks - 1, 0)), "ticks": ticks,
           "aborted": aborted, "deadline_misses": sum(plant.misses.values()),
           "deadline_miss_ticks": {str(k): v for k, v in sorted(plant.misses.items())[:64]},
           "sense_to_command_ms": latency_ms(plant.sense_to_command),
           "scan_to_twist_ms": latency_ms(plant.scan_to_twist),
           "ros_received": dict(plant.received), "ros_dropped": drops,
           "dropped_messages": sum(n for v in drops.values() for n in v.values()) + plant.cmd_drops.total,
           "drops": {"commands": plant.cmd_drops.by_source()}, "recorded_messages": plant.recorded,
           "log": {"files": ["run.mcap"], "record": "full"}, "events": plant.events}
    return doc


def progress_doc(plant: Any, k: int) -> dict[str, Any]:
    """A ``PROGRESS`` line: every robot's pose from its odometry and distance to its goal."""
    robots = {}
    for r, p in plant.ports.items():
        o = p.odom
        to_goal = None if o is None or p.goal is None else round(math.hypot(p.goal[0] - o.x, p.goal[1] - o.y), 3)
        robots[r] = {"x": round(o.x, 3) if o else 0.0, "y": round(o.y, 3) if o else 0.0, "to_goal": to_goal,
                     "reached": p.reached, "stopped": p.stopped and not p.reached}
    return {"t": tick_time(k), "tick": k, "robots": robots, "republished": 0,
            "deadline_misses": sum(plant.misses.values())}


def drain_log(plant: Any, recorder: Any) -> None:
    """Write what came since the last tick: the messages of other sessions (the nodes'),
    what the plant sent, and the robots' ROS messages (log time: the tick's sim time)."""
    t = plant.now_t
    handler = plant.record_sub.handler
    while (s := handler.try_recv()) is not None:
        if s.kind != zenoh.SampleKind.PUT or str(s.key_expr) in plant.answer:
            continue  # the commands are logged as they are taken
        recorder.write(str(s.key_expr), s.payload.to_bytes(), t)
        plant.recorded += 1
    with plant.lock:
        pending, plant.pending_log = plant.pending_log, []
    for key, payload, stamp in pending:
        recorder.write(key, payload, stamp)
        plant.recorded += 1
    while plant.ros_log:
        topic, kind, payload = plant.ros_log.popleft()
        schema = plant._schemas.get(kind)
        if schema is None:
            schema = plant._schemas[kind] = SchemaSpec(kind, "ros2msg", plant.ifc.definition(kind).encode())
        recorder.write_encoded(f"ros2{topic}", "cdr", schema, payload, t)
        plant.recorded += 1


def drop_doc(plant: Any) -> dict[str, Any]:
    """The robots' messages dropped: topic -> reason -> how many."""
    with plant.lock:
        out: dict[str, Any] = {}
        for (_robot, topic, reason), n in sorted(plant.drops.items()):
            out.setdefault(topic, {})[reason] = n
        return out


def wait_alive(session: zenoh.Session, key_expr: str, expected: set[str], timeout: float, stop: Any) -> set[str]:
    """Until every liveliness token of ``expected`` is up (at most ``timeout`` s, or until
    ``stop`` is set); the ones still missing (empty when stopped)."""
    alive: set[str] = set()

    def on_token(sample: zenoh.Sample) -> None:
        (alive.add if sample.kind == zenoh.SampleKind.PUT else alive.discard)(str(sample.key_expr))

    watcher = session.liveliness().declare_subscriber(key_expr, on_token, history=True)
    deadline = time.monotonic() + timeout
    try:
        while not stop.is_set() and not expected <= alive:
            if time.monotonic() > deadline:
                return expected - alive
            stop.wait(0.1)
    finally:
        watcher.undeclare()
    return set()


def target_messages(plant: Any, robot: str, odom: P.Odom, t: float) -> list[tuple[str, Any]]:
    """A target tick's readings of ``robot``: navigation, its goal (``sense/target``; not
    visible without a goal); tracking, its own pose and the targets of ``/targets`` within
    its target range (``sense/pose``, ``sense/targets``; none when ``/targets`` is stale)."""
    keys, body = plant.keys, plant.desc.body
    if plant.cfg.task == "tracking":
        with plant.lock:
            targets = plant.targets if plant.targets_stamp >= plant.now() - P.STALE_S else {}
        return [(keys.sense_pose(robot), SensePose(t, SENDER, (odom.x, odom.y, odom.theta))),
                (keys.sense_targets(robot), SenseTargets(t, SENDER, P.targets_seen(odom, targets, body.target_range)))]
    goal = plant.ports[robot].goal
    if goal is None:
        return [(keys.sense_target(robot), SenseTarget(t, SENDER, 0.0, 0.0, False))]
    alpha, d, visible = P.target_reading(odom, goal, body.target_range)
    return [(keys.sense_target(robot),
             SenseTarget(t, SENDER, alpha if visible else 0.0, d if visible else 0.0, visible))]
