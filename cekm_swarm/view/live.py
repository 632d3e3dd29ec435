"""What the live view shows, from (key, payload): the world's ground truth (poses,
targets, moving obstacles), each robot's path, and for the chosen robot the fields of
whatever graph runs: its target field a (a target module's ``TargetField``, or a tracking
module's ``TrackingField`` with its teammate fields), its obstacle fields b_j (every
``ObstacleField`` it sends, on whatever keys its graph gives them) and the motor-EKM
activity e = a - sum b (Eq. 9) with the winners s (target) and k = argmax e (Eq. 10). A
controller that sends no fields (command fusion, A-CMOMMT) shows none, and says so. A
learning robot (docs/learning.md) also shows its map learning: the version, the updates so
far, the running error of its learner's last run, and the lattice's input weights as the
displacements they stand for (Fig. 6), from its ``MapVersion`` messages.

A new run (the world's token carries a new run id, or sim time jumps back: a replay
started again) starts the view afresh: no path of one run is joined to the next.

Messages are decoded with the protocol's validating decoders; a malformed one is
dropped and counted (``drops``), never a crash. Everything handed out is plain JSON data.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cekm_swarm.protocol import (
    DEFAULT_KEYS,
    DropCounter,
    KeySpace,
    MapVersion,
    ObstacleField,
    TargetField,
    TrackingField,
    WorldState,
)

PATH_STEP = 0.004
"""A path point is kept when the robot has moved this far (m) since the last one."""
PATH_MAX = 5000


def _r(x: float, nd: int = 4) -> float:
    return round(float(x), nd)


class LiveView:
    """The view's state. ``geometry`` is the world's static geometry (as
    ``world.World.static_geometry()`` gives it); ``w`` the motor map's input weights
    (n x 2: alpha in rad, d in m) used to place neurons, None to place them by index;
    ``ranges`` the sensing radii drawn around each robot (m from the centre)."""

    def __init__(self, geometry: Mapping[str, Any], *, robot: str | None = None, w: np.ndarray | None = None,
                 ranges: Sequence[float] = (), colours: Mapping[str, str] | None = None,
                 keys: KeySpace = DEFAULT_KEYS) -> None:
        self.geometry = dict(geometry)
        self.keys = keys
        ids = [r["id"] for r in geometry.get("robots", [])]
        self.robot = robot if robot is not None else (ids[0] if ids else None)
        self.w = None if w is None else np.asarray(w, dtype=np.float64)
        self.ranges = [float(r) for r in ranges]
        self.colours = dict(colours or {})
        self.drops = DropCounter("view", keys=keys)
        self.time = math.nan
        self.poses: dict[str, dict[str, Any]] = {}
        self.targets: dict[str, Any] = {}
        self.obstacles: dict[str, Any] = {}
        self.paths: dict[str, list[list[float]]] = {}
        self.target_field: TargetField | TrackingField | None = None
        self.obstacle_fields: dict[str, ObstacleField] = {}  # by key
        self.map: MapVersion | None = None  # the chosen robot's latest map version (a learning robot)
        self.run: str | None = None  # the run id of the world server, when known
        self.graph: str | None = None  # the run's graph (controller), when the world serves it
        self.ended = False  # the run's world server is gone: the page says the run has ended
        self.version = 0
        self.changed = threading.Condition()

    def new_run(self, run: str | None, graph: str | None = None) -> None:
        """Start afresh: a new run (or a replay from its start) shares no path or field with the last."""
        with self.changed:
            self.run, self.graph = run, graph
            self.ended = False
            self.time = math.nan
            self.poses, self.targets, self.obstacles, self.paths = {}, {}, {}, {}
            self.target_field, self.obstacle_fields = None, {}
            self.map = None
            self.version += 1
            self.changed.notify_all()

    def run_seen(self, run: str) -> None:
        """The run id of the world on the router (its liveliness token): the first one names
        the run the view has shown since it joined, any other starts it afresh."""
        with self.changed:
            if self.run is None:
                self.run = run
                self.version += 1
                self.changed.notify_all()
            elif run != self.run:
                self.new_run(run)

    def set_geometry(self, geometry: Mapping[str, Any], ranges: Sequence[float], colours: Mapping[str, str]) -> None:
        """Draw another arena (the run's, when it is not the one the view started with)."""
        with self.changed:
            self.geometry = dict(geometry)
            ids = [r["id"] for r in geometry.get("robots", [])]
            if self.robot not in ids:
                self.robot = ids[0] if ids else None
            self.ranges = [float(r) for r in ranges]
            self.colours = dict(colours)
            self.version += 1
            self.changed.notify_all()

    def run_ended(self, run: str) -> None:
        """The world server of ``run`` is gone (its liveliness token went away)."""
        with self.changed:
            if run == self.run and not self.ended:
                self.ended = True
                self.version += 1
                self.changed.notify_all()

    def set_graph(self, graph: str | None) -> None:
        with self.changed:
            self.graph = graph
            self.version += 1
            self.changed.notify_all()

    # ------------------------------------------------------------------ input
    def observe(self, key: str, payload: bytes) -> None:
        """One received message (Zenoh's thread): decoded, or dropped and counted."""
        msg = self.drops.decode(key, payload)
        if msg is None:
            return
        if isinstance(msg, WorldState) and msg.stamp < self.time - 1.0:  # sim time went back: a run from its start
            self.new_run(self.run, self.graph)
        with self.changed:
            if isinstance(msg, WorldState):
                self._world(msg)
            elif isinstance(msg, (TargetField, TrackingField, ObstacleField)):
                if self.keys.parse(key).robot != self.robot:
                    return
                if isinstance(msg, ObstacleField):
                    self.obstacle_fields[key] = msg
                else:
                    self.target_field = msg
            elif isinstance(msg, MapVersion):
                if self.keys.parse(key).robot != self.robot or (
                        self.map is not None and msg.version < self.map.version):
                    return
                self.map = msg
            else:
                return
            self.version += 1
            self.changed.notify_all()

    def _world(self, msg: WorldState) -> None:
        """The typed ground truth (every pose finite: protocol.messages.WorldState), as JSON data."""
        self.time = msg.stamp
        self.targets = {tid: {"x": t.x, "y": t.y} for tid, t in msg.targets.items()}
        self.obstacles = {oid: {"x": o.x, "y": o.y, "theta": o.theta} for oid, o in msg.obstacles.items()}
        for rid, r in msg.robots.items():
            x, y, g = r.x, r.y, r.goal
            self.poses[rid] = {"x": _r(x), "y": _r(y), "theta": _r(r.theta), "in_contact": r.in_contact,
                               "goal": None if g is None else [_r(g[0]), _r(g[1])]}
            path = self.paths.setdefault(rid, [])
            if not path or math.hypot(x - path[-1][1], y - path[-1][2]) >= PATH_STEP:
                path.append([_r(msg.stamp, 3), _r(x), _r(y)])
                if len(path) > PATH_MAX:
                    del path[1:len(path) // 2:2]  # thin the older half, keep the start

    # ------------------------------------------------------------------ output
    def fields(self) -> dict[str, Any] | None:
        """The chosen robot's latest fields, as its motor module holds them: the latest
        target field a (the target sensor may run slower than the range sensors) and the
        obstacle fields of the newest range tick; sum_j b_j, e (Eq. 9), s, k (Eq. 10) and
        which sensors see something. None before any field."""
        tf = self.target_field
        obstacle_stamps = [f.stamp for f in self.obstacle_fields.values()]
        if tf is None and not obstacle_stamps:
            return None
        newest = max(obstacle_stamps + ([tf.stamp] if tf is not None else []))
        newest_b = max(obstacle_stamps, default=newest)
        b = [f for f in self.obstacle_fields.values() if f.stamp == newest_b and f.b is not None]
        bs = [f.b for f in b if f.b is not None]  # each one's activities (all of b's)
        a = tf.a if tf is not None else None
        at_goal = bool(isinstance(tf, TargetField) and tf.at_goal)
        n = a.shape[0] if a is not None else (bs[0].shape[0] if bs else 0)
        if n == 0:
            return {"stamp": newest, "n": 0, "seeing": [], "at_goal": at_goal}
        bsum = np.zeros(n)
        for fb in bs:
            if fb.shape[0] == n:
                bsum += fb
        team = False
        if isinstance(tf, TrackingField) and tf.b.shape[0] == n:
            team = True
            bsum += tf.b  # the teammate fields (docs/design.md section 5)
        out: dict[str, Any] = {"stamp": newest, "n": n, "seeing": sorted(f.index for f in b), "teammates": team,
                               "b": [_r(v) for v in bsum], "at_goal": at_goal}
        if a is not None:
            e = a - bsum  # Eq. 9
            s: Any = None
            if isinstance(tf, TargetField):
                s = tf.winner
            elif isinstance(tf, TrackingField) and tf.inputs:  # the localized point of most weight (a sensed
                s = max(tf.inputs, key=lambda row: row[3])[0]  # target, or the search goal)
            out.update(a=[_r(v) for v in a], e=[_r(v) for v in e], s=None if s is None else int(s),
                       k=int(np.argmax(e)))  # Eq. 10
        return out

    def learning(self) -> dict[str, Any] | None:
        """The chosen robot's map as it learns (None: no map version seen): version, updates
        applied so far (own and teammates'), steps seen and skipped, the running error
        (m/s, |c - M_s v| of the learner's last run, Eq. 13) and each neuron's input weight
        as the displacement it stands for, (d cos alpha, d sin alpha), on a size x size lattice."""
        m = self.map
        if m is None:
            return None
        n = m.w.shape[0] // 2
        w = m.w.reshape(n, 2)
        return {"version": m.version, "stamp": _r(m.stamp, 3), "updates": m.applied, "steps": m.steps,
                "skipped": m.skipped, "error": _r(m.error, 6), "size": math.isqrt(n),
                "points": [[_r(d * math.cos(a), 5), _r(d * math.sin(a), 5)] for a, d in w.tolist()]}

    def lattice(self) -> list[list[float]] | None:
        """Neuron positions (alpha, d) from the model's w, or None (placed by index)."""
        return None if self.w is None else [[_r(a), _r(d)] for a, d in self.w]

    def init(self) -> dict[str, Any]:
        """Everything a page needs to start: geometry, colours, lattice, ranges, paths so far."""
        with self.changed:
            return {"geometry": self.geometry, "colours": self.colours, "robot": self.robot, "lattice": self.lattice(),
                    "ranges": self.ranges, "paths": {k: list(v) for k, v in self.paths.items()}, **self._tick()}

    def tick(self) -> dict[str, Any]:
        """The current state (poses, targets, obstacles, fields, drop count, version)."""
        with self.changed:
            return self._tick()

    def _tick(self) -> dict[str, Any]:
        return {"version": self.version, "run": self.run, "graph": self.graph, "ended": self.ended,
                "arena": self.geometry.get("name"),
                "time": None if math.isnan(self.time) else _r(self.time, 3),
                "robots": dict(self.poses), "targets": self.targets, "obstacles": self.obstacles,
                "fields": self.fields(), "learning": self.learning(), "dropped": self.drops.total}

    def wait_change(self, version: int, timeout: float) -> bool:
        """Block until the version differs from ``version`` (True) or ``timeout`` s pass."""
        with self.changed:
            return self.changed.wait_for(lambda: self.version != version, timeout)
