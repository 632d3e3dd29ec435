"""Online learning through the runtime (section 3.5; docs/learning.md): the robot's one
map, learned while it moves and shared by all of its EKM nodes.

* :class:`Learner` (one per robot, every 8 ticks): for each tick of the motor
  controller's record (``sense/odometry``: the wheel speeds held, the encoders' travel,
  the stall signal) it has not learned from, it forms the displacement v
  (:func:`cekm_swarm.models.learning.wheel_displacement`) and applies one step of
  self-organized learning with the models' own rule
  (:meth:`cekm_swarm.models.networks.IndirectEKM.learn`: winner for v, Eq. 15 or Eqs.
  16-17, Eq. 12), except on a stopped step (c = 0, or wheels that did not turn) or a
  blocked one (the body touched something). A run that learned makes a new version of
  the map; every run sends the current version, whole
  (:class:`~cekm_swarm.protocol.MapVersion`: version, digest, w, M, R^-1).
* Every EKM node of the robot reads that message with ``delay = 1`` and uses the version
  of the learner's latest run before the tick (:class:`MapFollower`): version k from the
  tick after its stamp. A message whose version is older than the node's, whose digest does not match
  its arrays, or whose lattice is not the model's, is dropped and counted; a node that
  restarted or missed a version catches up from the next message, which holds the whole
  current map. (A restarted learner starts again from the run's model: docs/learning.md.)
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cekm_swarm.controller.cooperative import CooperativeEKM
from cekm_swarm.models.learning import map_digest, wheel_displacement
from cekm_swarm.models.networks import IndirectEKM
from cekm_swarm.node import Context, In, Inputs, Node, NodeError, Out
from cekm_swarm.protocol import Data, MapVersion, SenseOdometry

from .ekm import indirect_model

STEP_S = 1.024
"""s: one step of the map (section 4.1): v is the displacement over it."""
MAX_MAP_BYTES = 30_000
"""The largest map message a learner sends (under the runtime's 32 KB message limit): a
15 x 15 map is 10.8 KB."""


@dataclass
class LearnerCounts:
    """What one learner did: steps seen, learned from, skipped (stopped / blocked)."""

    applied: int = 0  # own steps learned from
    stopped: int = 0
    blocked: int = 0
    team: int = 0  # teammates' steps learned from (TeamLearner)
    error: float = 0.0  # m/s: |c - M_s v| of the last own step, before it was learned from

    @property
    def skipped(self) -> int:
        return self.stopped + self.blocked

    @property
    def learned(self) -> int:
        """Every update of the map: own steps and teammates'."""
        return self.applied + self.team

    @property
    def steps(self) -> int:
        return self.learned + self.skipped


def copy_model(model: IndirectEKM, w: np.ndarray | None = None, M: np.ndarray | None = None,
               Rinv: np.ndarray | None = None) -> IndirectEKM:
    """A private copy of ``model`` (the run's model is shared by every robot of a process),
    with the arrays given in place of its own."""
    n = model.lattice.n
    return IndirectEKM(model.lattice, model.rule,
                       np.array(model.w if w is None else np.reshape(w, (n, 2)), dtype=np.float64),
                       np.array(model.M if M is None else np.reshape(M, (n, 2, 2)), dtype=np.float64),
                       np.array(model.Rinv if Rinv is None else np.reshape(Rinv, (n, 2, 2)), dtype=np.float64),
                       model.comp, model.learn_p, model.v_max,
                       None if model.converged is None else model.converged.copy())


def winner_of(net: IndirectEKM, v: np.ndarray) -> int:
    """The winner for v (Eqs. 2-4) by numba's competition (``models.fast.winner``: the same
    winner as the models' numpy one bit for bit, tested; a few us instead of tens)."""
    from cekm_swarm.models import fast  # noqa: PLC0415 -- lazy: numba costs ~0.15 s at a node's start-up

    params = getattr(net, "_fast_params", None)
    if params is None:
        params = fast.pack_params(net.comp, net.learn_p, net.v_max, 1e-3)
        # the parameters do not change while it learns (only w, M, R^-1 do): kept on the network
        net._fast_params = params  # type: ignore[attr-defined]  # a cache set on the object, not a field
    return int(fast.winner(float(v[0]), float(v[1]), net.w, params))


def learn_step(net: IndirectEKM, left: float, right: float, dt: float, blocked: bool, c: tuple[float, float],
               t_learn: float, axle: float, counts: LearnerCounts) -> np.ndarray | None:
    """One learning step of section 3.5 from one tick of odometry (each wheel's travel over
    ``dt``, ``blocked``) and the command c the wheels held meanwhile: v, then the models'
    rule. Returns v, or None for a step not learned from (stopped: c = 0 or wheels that did
    not turn; blocked: the body touched something)."""
    c_exec = np.clip(np.array(c, dtype=np.float64), -net.v_max, net.v_max)  # what the wheels execute
    if (c_exec[0] == 0.0 and c_exec[1] == 0.0) or (left == 0.0 and right == 0.0):
        counts.stopped += 1
        return None
    if blocked:
        counts.blocked += 1
        return None
    v = wheel_displacement(left, right, dt, axle, STEP_S)
    s = winner_of(net, v)  # the rule's winner for v (Eqs. 2-4), as net.output finds it
    counts.error = float(np.hypot(*(c_exec - net.control(v, s, s))))  # how far the map was from c (Eq. 13), before
    net.learn(v, c_exec, t_learn)  # winner for v, Eq. 15 or Eqs. 16-17, Eq. 12
    counts.applied += 1
    return v


class Learner(Node):
    """The robot's learner: each run, one learning step per tick of odometry it has not
    learned from yet, then a new map version if it learned (docs/learning.md)."""

    inputs = {"odometry": In(SenseOdometry, doc="the motor controller's record of the last ticks")}
    outputs = {"map": Out(MapVersion, doc="the robot's current map version, whole")}
    uses_model = True
    stateful = False  # its state survives a restart: a launch keeps it on disk after every run (SNAPSHOT_DIR)

    @dataclass(frozen=True)
    class Params:
        start_step: int = 100_000  # the training step the neighbourhood schedule sigma(t) starts at (0: untrained)

    def setup(self) -> None:
        if self.params.start_step < 0:
            raise NodeError(f"{self.ctx.sender}: start_step must be >= 0")
        self.net = copy_model(indirect_model(self.ctx))
        winner_of(self.net, np.zeros(2))  # numba's competition loaded (and compiled once, cached) before the run
        size = 8 * 6 * self.net.lattice.n
        if size > MAX_MAP_BYTES:
            side = self.net.lattice.size
            raise NodeError(f"{self.ctx.sender}: a {side}x{side} map is {size} bytes, more than a map message may "
                            f"hold ({MAX_MAP_BYTES}); learn with a lattice of at most 25x25")
        self.counts = LearnerCounts()
        self.version = 0
        self.last_tick = 0  # the last tick of odometry learned from
        self.axle = self.ctx.body.axle
        self.history: list[tuple[int, float, str]] = []  # (version, sim time it was made, digest)
        self.error = 0.0  # m/s: the mean |c - M_s v| of the last run's own steps, before learning (Eq. 13)
        self.lost = 0  # steps a restart lost (older than the odometry record when it came back)
        self.snapshots = snapshot_path(self.ctx)
        self.resumed = self.snapshots is not None and resume(self, self.snapshots)
        self.saved_tick = self.last_tick
        if not self.resumed:
            self._publish(0.0)

    def _publish(self, t: float) -> None:
        net = self.net
        self.digest = map_digest(net.w, net.M)
        self.arrays = (net.w.reshape(-1).copy(), net.M.reshape(-1).copy())
        self.history.append((self.version, t, self.digest))

    def t_learn(self) -> float:
        """The training step the neighbourhood schedule sigma(t) is at."""
        return float(self.params.start_step + self.counts.learned)

    def learn_own(self, odo: SenseOdometry | None) -> list[list[float]]:
        """One step per new tick of odometry (section 3.5); the (v, c) pairs learned from."""
        pairs: list[list[float]] = []
        errors: list[float] = []
        if odo is None:
            return pairs
        if self.resumed and odo.ticks:  # the first run after a restart: what the record no longer holds is lost
            self.resumed = False
            self.lost = max(0, odo.ticks[0] - self.last_tick - 1)
            if self.lost:
                self.ctx.log.warning("%s: restarted from map version %d; %d steps (ticks %d-%d) were lost",
                                     self.ctx.sender, self.version, self.lost, self.last_tick + 1, odo.ticks[0] - 1)
            else:  # said either way, so a log always tells how many a restart lost
                self.ctx.log.warning("%s: restarted from map version %d; 0 steps were lost (the record still held "
                                     "tick %d on)", self.ctx.sender, self.version, self.last_tick + 1)
        for i, k in enumerate(odo.ticks):
            if k <= self.last_tick:
                continue
            self.last_tick = k
            c = (odo.set_l[i], odo.set_r[i])
            v = learn_step(self.net, odo.left[i], odo.right[i], odo.dt, odo.blocked[i], c, self.t_learn(), self.axle,
                           self.counts)
            if v is not None:
                errors.append(self.counts.error)
                pairs.append([float(v[0]), float(v[1]), *(float(x) for x in np.clip(c, -self.net.v_max,
                                                                                       self.net.v_max))])
        if errors:
            self.error = sum(errors) / len(errors)
        return pairs

    def map_message(self, t: float, learned: bool) -> MapVersion:
        """The current version: a new one when this run learned (kept on disk in a launch,
        with the counts and the last tick learned from, before it is sent)."""
        if learned:
            self.version += 1
            self._publish(t)
        if self.snapshots is not None and self.last_tick != self.saved_tick:
            save_snapshot(self, self.snapshots)
            self.saved_tick = self.last_tick
        c = self.counts
        w, M = self.arrays
        return MapVersion(t, self.ctx.sender, self.version, c.steps, c.learned, c.skipped, self.digest, w, M,
                          self.error)

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        pairs = self.learn_own(inputs["odometry"])
        return {"map": self.map_message(t, bool(pairs))}


class TeamLearner(Learner):
    """A learner that shares experience with its team (docs/learning.md): each run it
    learns first from its teammates' (v, c) pairs of their previous run, in robot-id order,
    then from its own ticks, and sends its own pairs to the team."""

    inputs = {**Learner.inputs, "team": In(Data, many=True, doc="each teammate's (v, c) pairs of its previous run"),
              "maps": In(MapVersion, many=True, doc="each teammate's map version of its previous run")}
    outputs = {**Learner.outputs, "experience": Out(Data, doc="this run's own (v, c) pairs")}

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        learned = self.catch_up(inputs["maps"])
        for robot in sorted(inputs["team"]):
            for v, c in experience_pairs(inputs["team"][robot]):
                self.net.learn(v, c, self.t_learn())  # the models' rule, as for an own step
                self.counts.team += 1
                learned = True
        pairs = self.learn_own(inputs["odometry"])
        return {"map": self.map_message(t, learned or bool(pairs)),
                "experience": Data(t, self.ctx.sender, {"pairs": pairs})}


    def catch_up(self, maps: dict[str, MapVersion]) -> bool:
        """A learner that has seen nothing yet (a robot that joins a running team, with no
        snapshot of its own) starts from the teammate map that has learned most (the first
        in robot-id order on a tie); its own R^-1 stays. Never at tick 0 (no teammate has
        run before it), so a run whose robots all start together is not changed."""
        if self.counts.steps or self.version:
            return False
        held = [(robot, m) for robot, m in sorted(maps.items()) if m is not None and m.applied > 0
                and m.w.shape[0] == 2 * self.net.lattice.n and map_digest(m.w, m.M) == m.digest]
        if not held:
            return False
        robot, best = max(held, key=lambda rm: rm[1].applied)  # max keeps the first of equals
        self.net = copy_model(self.net, best.w, best.M, self.net.Rinv)
        self.counts.team += best.applied
        self.ctx.log.warning("%s: joined late: starts from %s's map version %d (%d steps)", self.ctx.sender, robot,
                             best.version, best.applied)
        return True


def experience_pairs(msg: Data | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """A teammate's (v, c) pairs from its experience message, in its order; a row that is
    not four finite numbers (alpha_v, d_v, c_l, c_r) is left out."""
    out: list[tuple[np.ndarray, np.ndarray]] = []
    rows = None if msg is None else msg.values.get("pairs")
    for row in rows if isinstance(rows, list) else ():
        try:
            a = np.array(row, dtype=np.float64)
        except (TypeError, ValueError):
            continue
        if a.shape == (4,) and np.all(np.isfinite(a)):
            out.append((a[:2], a[2:]))
    return out


SNAPSHOT_DIR = "CEKM_LEARNER_DIR"
"""The environment variable naming the directory where a launch's learners keep their
latest version (``cekm launch`` sets it to ``OUT/maps``): a restarted learner goes on from it."""


def snapshot_path(ctx: Context) -> Path | None:
    """Where this learner keeps its latest version (None: nowhere, as in ``cekm run``)."""
    folder = os.environ.get(SNAPSHOT_DIR)
    if not folder or ctx.mode not in ("lockstep", "realtime"):
        return None
    return Path(folder) / f"{ctx.robot}.npy"


def save_snapshot(learner: Learner, path: Path) -> None:
    """The learner's whole state as one float64 vector, written atomically."""
    c, net = learner.counts, learner.net
    head = [learner.version, learner.last_tick, c.applied, c.stopped, c.blocked, c.team, learner.error]
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.save(fh, np.concatenate([np.array(head, dtype=np.float64), net.w.reshape(-1), net.M.reshape(-1),
                                    net.Rinv.reshape(-1)]))
    os.replace(tmp, path)


def resume(learner: Learner, path: Path) -> bool:
    """Go on from the snapshot at ``path`` (False: none, or not this map's)."""
    try:
        a = np.load(path)
    except (OSError, ValueError):
        return False
    n = learner.net.lattice.n
    h = 7
    if a.shape != (h + 10 * n,):
        return False
    version, last_tick, applied, stopped, blocked, team = (int(x) for x in a[:6])
    learner.error = float(a[6])
    learner.net = copy_model(learner.net, a[h:h + 2 * n], a[h + 2 * n:h + 6 * n], a[h + 6 * n:])
    learner.version, learner.last_tick = version, last_tick
    learner.counts = LearnerCounts(applied, stopped, blocked, team)
    net = learner.net
    learner.digest = map_digest(net.w, net.M)
    learner.arrays = (net.w.reshape(-1).copy(), net.M.reshape(-1).copy())
    learner.ctx.log.warning("%s: restarted from map version %d (%s), %d steps learned", learner.ctx.sender, version,
                            learner.digest, applied + team)
    return True


def model_of(base: IndirectEKM, msg: MapVersion, reader: bool = False) -> IndirectEKM:
    """The map a version message holds, on ``base``'s lattice and parameters: a private
    copy, or for an EKM node (``reader``) the least a version costs it: M the message's own
    read-only array (a reader never learns, and a write would raise), w a copy (numba's
    competition is compiled for writable arrays: a read-only one would compile it again),
    R^-1 and ``converged`` ``base``'s (a reader computes with neither)."""
    if not reader:
        return copy_model(base, msg.w, msg.M)
    n = base.lattice.n
    return IndirectEKM(base.lattice, base.rule, np.array(msg.w).reshape(n, 2), msg.M.reshape(n, 2, 2), base.Rinv,
                       base.comp, base.learn_p, base.v_max, base.converged)


def map_misfit(msg: MapVersion, version: int, n: int) -> str | None:
    """Why a node holding ``version`` of an n-neuron map cannot use ``msg`` (None: it can)."""
    if msg.w.shape[0] != 2 * n:
        return f"a map of {msg.w.shape[0] // 2} neurons, the model's lattice has {n}"
    if msg.version < version:
        return f"stale: version {msg.version}, this node has version {version}"
    if msg.version > version and map_digest(msg.w, msg.M) != msg.digest:
        return f"version {msg.version}: its digest {msg.digest} does not match its arrays"
    if not all(math.isfinite(x) for x in (msg.w[0], msg.M[0])):
        return "not finite"
    return None


def warm_winner(ekm: CooperativeEKM) -> None:
    """Load numba's competition (``models.fast.winner``, compiled and cached on disk) and
    run it once, so that a map version's first winners cost no compilation."""
    from cekm_swarm.models import fast  # noqa: PLC0415 -- lazy: numba costs ~0.15 s at a node's start-up

    params = fast.pack_params(ekm.model.comp, ekm.model.learn_p, ekm.model.v_max, 1e-3)
    fast.winner(0.0, 0.05, np.ascontiguousarray(ekm.model.w), params)


class MapFollower(Node):
    """What an EKM node of a learning robot adds: its ``map`` input, the learner's latest
    version before the tick, used from that tick on (``self.ekm`` rebuilt on a new version,
    its field rows computed as they are needed). A malformed message or one of another
    lattice is refused on receipt (the shell drops and counts it); an older version than the
    node holds (a resend, or a learner restarted from its model) is dropped here and counted
    in ``dropped``, and the node keeps its version, so a lockstep run never waits on it."""

    version = 0
    dropped = 0
    _checked: tuple[int, str] | None = None  # the (version, digest) last checked on receipt
    ekm: CooperativeEKM  # the node's cooperative EKM (built by the node it is mixed into)
    digest: str  # of the version in use
    last_drop: str  # why the last map message was dropped

    def follow(self, msg: MapVersion | None) -> None:
        if msg is None or msg.version == self.version:
            return
        why = None if self._checked == (msg.version, msg.digest) else map_misfit(msg, self.version, self.ekm.n)
        if why is not None or msg.version < self.version:
            self.dropped += 1
            self.last_drop = why or f"stale: version {msg.version}, this node has version {self.version}"
            return
        # numba winners: a new version empties the winner memo, and numpy's competition
        # (tens of us) would then run again for every reading; numba's gives the same
        # winners bit for bit (tested) in about 1 us (docs/learning.md, cost)
        self.ekm = replace(self.ekm, model=model_of(self.ekm.model, msg, reader=True), tabulate=False, backend="numba")
        self.version = msg.version
        self.digest = msg.digest

    def setup(self) -> None:
        super().setup()
        warm_winner(self.ekm)  # in the launcher's fork server (warm_setup): its children find it compiled

    def check_input(self, port: str, msg: Any) -> str | None:
        if port != "map":
            return super().check_input(port, msg)
        if msg.version > self.version:
            why = map_misfit(msg, self.version, self.ekm.n)
            self._checked = (msg.version, msg.digest) if why is None else None
            return why
        return None

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        self.follow(inputs["map"])  # the version of the learner's latest run before t
        return super().step(t, inputs)

    def close(self) -> None:
        if self.dropped:
            self.ctx.log.warning("%s: dropped %d map messages older than its version %d (the last: %s)",
                                 self.ctx.sender, self.dropped, self.version, self.last_drop)
        super().close()
