"""Motor integration module: e = a - sum_j b_j, k = argmax e, c by Eq. 11 (section 3.4),
published on ``cmd/wheels``.

Two ways of deciding when to integrate (:class:`MotorState`):

* real time: with the latest field of each source, leaving out a source whose field is
  older than its staleness limit (by default two of its periods: 0.256 s for an obstacle
  module, 0.512 s for the target module), measured in sim time against the newest stamp
  seen. A stale target means no target: the robot stops. When (``--integrate``):

  - ``tick`` (the default): once per stamp, as soon as every live source has delivered
    its field for the newest stamp (each obstacle module every tick, the target module on
    target ticks; a source silent past its staleness limit is not waited for); and if the
    first field of a newer stamp arrives first, at once for the stamp before, with what
    came. The world applies the latest command at each tick boundary, so the commands
    ``every`` sends before a tick's last field are overwritten unread: sending one per
    tick cut the motor's and the world's CPU per tick by a third to a half
    (``benchmarks/bench_runtime_scale.py``), which is what lets 16 robots run in real time
    on 2 cores.
  - ``every``: on every arriving field (13 commands a tick), as the project's first
    design had it.
* lockstep: exactly one command per tick, when every field expected for the tick's stamp
  t has arrived: the 12 obstacle fields stamped t and the target field of the latest
  target tick at or before t (t itself on even ticks). The fields are then exactly the
  ones ``RobotBrain.tick`` uses in one process, combined in the same order (obstacles by
  index), so the command is the same to the bit. Fields are kept per tick until their
  tick is answered, so a stray field of another tick (late, or a peer's with a stamp
  ahead) never displaces the one a tick needs. A field arriving again for the tick last
  answered (the world re-publishes a tick's readings after a timeout so a restarted
  module catches up) makes the module send that tick's command again; a field of an
  older tick is dropped and counted.

``python -m cekm_swarm.modules.motor --robot r1 --model M.npz --mode lockstep --connect ...``
"""

from __future__ import annotations

import argparse
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from cekm_swarm.protocol import (DEFAULT_RANGE_SENSORS, KeySpace, ObstacleField, TargetField, TrackingField, WheelCommand,
                                 encode)
from cekm_swarm.ticks import TARGET_EVERY, TICK_S
from cekm_swarm.protocol.hotpath import VectorCache, obstacle_field_values, target_field_values, unpack

from cekm_swarm.runtime.process_args import add_params

from .shell import TRACKING_RANGE_PARAM, ModuleSpec, base_parser, keyspace, load_controller, main_of

NAME = "motor"
INTEGRATE_ON = ("tick", "every")
"""Real-time integration policies (:class:`MotorState`): once per tick, or on every field."""
log = logging.getLogger("cekm_swarm.modules.motor")

# integrate(target_field | None, obstacle_fields in index order) -> (v_l, v_r)
Integrate = Callable[[TargetField | None, list[ObstacleField]], tuple[float, float]]


def tick_of(stamp: float, tick_s: float = TICK_S) -> int:
    """:func:`cekm_swarm.ticks.tick_of` for a configurable tick length."""
    return int(round(stamp / tick_s))


def stamp_of(tick: int, tick_s: float = TICK_S) -> float:
    """:func:`cekm_swarm.ticks.tick_time` for a configurable tick length."""
    return round(tick * tick_s, 9)


@dataclass
class MotorState:
    """The motor module's bookkeeping, free of Zenoh and of the controller (``integrate``
    is injected), so it can be tested alone.

    ``put(field)`` stores a field and returns the commands to send now, as
    ``(stamp, v_l, v_r)`` tuples (none, one, or in lockstep a repeat of the last)."""

    integrate: Integrate
    lockstep: bool = False
    integrate_on: str = "tick"
    """Real time: ``tick`` integrates once per stamp, when :meth:`complete`; ``every`` on every field."""
    sensors: int = DEFAULT_RANGE_SENSORS
    tick_s: float = TICK_S
    target_every: int = TARGET_EVERY
    obstacle_limit: float = 2 * TICK_S
    target_limit: float = 2 * TARGET_EVERY * TICK_S
    target: TargetField | None = None
    obstacles: dict[int, ObstacleField] = field(default_factory=dict)
    newest: float = -math.inf
    sent_stamp: float = -math.inf
    sent: tuple[float, float] | None = None
    commands: int = 0
    repeats: int = 0
    stale_drops: dict[str, int] = field(default_factory=dict)
    _stale_now: set[str] = field(default_factory=set)
    drop: Callable[[TargetField | ObstacleField, str], None] | None = None
    """Called with a field the state refuses and the reason (the module counts it)."""
    pending: dict[float, dict[int, ObstacleField]] = field(default_factory=dict)  # lockstep: tick -> fields
    targets: dict[float, TargetField] = field(default_factory=dict)  # lockstep: target fields by tick
    MAX_PENDING = 64  # ticks held at most (the modules' stamp window already bounds them)

    # ------------------------------------------------------------------ storing

    def _refuse(self, msg: TargetField | TrackingField | ObstacleField, why: str) -> list:
        if self.drop is not None:
            self.drop(msg, why)
        return []

    def put(self, msg: TargetField | TrackingField | ObstacleField) -> list[tuple[float, float, float]]:
        if isinstance(msg, ObstacleField) and not 0 <= msg.index < self.sensors:
            return self._refuse(msg, f"sensor index {msg.index} outside 0..{self.sensors - 1}")
        if not isinstance(msg, (TargetField, TrackingField, ObstacleField)):
            return []
        if self.lockstep:
            return self._put_lockstep(msg)
        return self._put_realtime(msg)

    # ------------------------------------------------------------------ real time

    def fresh(self) -> tuple[TargetField | None, list[ObstacleField]]:
        """The latest field of each source, without those older than their limit (counted
        in ``stale_drops`` once each time a source goes stale, and logged)."""
        target = self.target
        if target is not None and not self._live(target.stamp, self.target_limit):
            self._stale("target", target.stamp)
            target = None
        else:
            self._stale_now.discard("target")
        obstacles = []
        for j in sorted(self.obstacles):
            f = self.obstacles[j]
            name = f"obstacle-{j}"
            if not self._live(f.stamp, self.obstacle_limit):
                self._stale(name, f.stamp)
                continue
            self._stale_now.discard(name)
            obstacles.append(f)
        return target, obstacles

    def _live(self, stamp: float, limit: float) -> bool:
        """A source whose latest field has ``stamp`` is within its staleness ``limit`` of the newest stamp."""
        return self.newest - stamp <= limit + 1e-9

    def _stale(self, name: str, stamp: float) -> None:
        if name not in self._stale_now:
            self._stale_now.add(name)
            self.stale_drops[name] = self.stale_drops.get(name, 0) + 1
            log.warning("stale field dropped: %s (stamp %.3f, newest %.3f)", name, stamp, self.newest)

    def _put_realtime(self, msg: TargetField | TrackingField | ObstacleField) -> list[tuple[float, float, float]]:
        out = []
        every = self.integrate_on == "every"
        if not every and msg.stamp > self.newest > self.sent_stamp:
            out.append(self._realtime())  # a newer tick began before the last one was complete: send that now
        if isinstance(msg, (TargetField, TrackingField)):  # the target module's output (tracking: its fields)
            if self.target is not None and msg.stamp < self.target.stamp:
                return out + self._refuse(msg, f"stamp {msg.stamp} older than the latest target field's")
            self.target = msg
        else:
            old = self.obstacles.get(msg.index)
            if old is not None and msg.stamp < old.stamp:
                return out + self._refuse(msg, f"stamp {msg.stamp} older than the latest field of obstacle-{msg.index}")
            self.obstacles[msg.index] = msg
        self.newest = max(self.newest, msg.stamp)
        if every or (self.sent_stamp < self.newest and self.complete()):
            out.append(self._realtime())
        return out

    def complete(self) -> bool:
        """Real time: every live source has delivered its field for the newest stamp (an
        obstacle module each tick, the target module on target ticks). A source not heard
        from within its staleness limit is not waited for."""
        t = self.newest
        if any(f.stamp < t and self._live(f.stamp, self.obstacle_limit) for f in self.obstacles.values()):
            return False
        target = self.target
        return not (target is not None and target.stamp < t and self._live(target.stamp, self.target_limit)
                    and self.target_stamp_for(t) == t)

    def _realtime(self) -> tuple[float, float, float]:
        target, obstacles = self.fresh()
        v_l, v_r = self.integrate(target, obstacles)
        self.commands += 1
        self.sent_stamp = self.newest
        return (self.newest, v_l, v_r)

    # ------------------------------------------------------------------ lockstep

    def target_stamp_for(self, stamp: float) -> float:
        """The stamp of the target field a tick at ``stamp`` uses (the latest target tick)."""
        k = tick_of(stamp, self.tick_s)
        return stamp_of(k - k % self.target_every, self.tick_s)

    def missing(self, stamp: float) -> list[str]:
        """The fields still missing for the tick at ``stamp`` (empty: complete)."""
        out = []
        if self.target_stamp_for(stamp) not in self.targets:
            out.append("target")
        have = self.pending.get(stamp, {})
        out += [f"obstacle-{j}" for j in range(self.sensors) if j not in have]
        return out

    def _put_lockstep(self, msg: TargetField | TrackingField | ObstacleField) -> list[tuple[float, float, float]]:
        stamp = msg.stamp
        if stamp < self.sent_stamp:
            if isinstance(msg, (TargetField, TrackingField)) and stamp == self.target_stamp_for(self.sent_stamp):
                return []  # the world re-published the target reading the answered (odd) tick used
            return self._refuse(msg, f"field of tick {stamp} after tick {self.sent_stamp} was answered")
        self.newest = max(self.newest, stamp)
        if isinstance(msg, (TargetField, TrackingField)):
            self.targets[stamp] = msg
            self.target = msg
        else:
            self.obstacles[msg.index] = msg
            if stamp > self.sent_stamp:
                self.pending.setdefault(stamp, {})[msg.index] = msg
        if stamp == self.sent_stamp:
            if self.sent is not None:  # a re-published tick: answer again
                self.repeats += 1
                return [(stamp, *self.sent)]
            return []
        while len(self.pending) > self.MAX_PENDING:  # bounded whatever arrives
            del self.pending[min(self.pending)]
        for t in sorted(self.pending):
            if not self.missing(t):
                return [self._answer(t)]
        return []

    def _answer(self, stamp: float) -> tuple[float, float, float]:
        fields = self.pending[stamp]
        target = self.targets[self.target_stamp_for(stamp)]
        v_l, v_r = self.integrate(target, [fields[j] for j in range(self.sensors)])
        self.sent_stamp, self.sent = stamp, (v_l, v_r)
        self.commands += 1
        for t in [t for t in self.pending if t <= stamp]:
            del self.pending[t]
        keep = self.target_stamp_for(stamp)
        for t in [t for t in self.targets if t < keep]:
            del self.targets[t]
        return (stamp, v_l, v_r)


def controller_integrate(ekm) -> Integrate:
    """``integrate`` through the cooperative EKM, as ``RobotBrain.tick`` calls it."""
    from cekm_swarm.controller.cooperative import ObstacleActivity, TargetActivity

    nan = math.nan

    def integrate(target: TargetField | None, obstacles: Iterable[ObstacleField]) -> tuple[float, float]:
        act = None
        if target is not None:
            act = TargetActivity(target.stamp, nan if target.alpha is None else target.alpha,
                                 nan if target.d is None else target.d, target.winner, target.a, target.at_goal)
        obs = [ObstacleActivity(f.stamp, f.index, f.winner, f.b) for f in obstacles]
        out = ekm.integrate(act, obs)
        return out.v_l, out.v_r

    return integrate


def tracking_integrate(tekm) -> Integrate:
    """``integrate`` of a tracking robot (Eqs. 9-11 with the teammate fields), through
    :meth:`TrackingEKM.integrate` as ``TrackingRobot.command`` calls it; the target
    module's output is a :class:`TrackingField`."""
    from cekm_swarm.controller.cooperative import ObstacleActivity

    from .tracking import tracking_activity

    def integrate(target: TrackingField | None, obstacles: Iterable[ObstacleField]) -> tuple[float, float]:
        act = None if target is None else tracking_activity(target)
        out = tekm.integrate(act, [ObstacleActivity(f.stamp, f.index, f.winner, f.b) for f in obstacles])
        return out.v_l, out.v_r

    return integrate


def build_spec(integrate: Integrate, robot: str, keys: KeySpace = KeySpace(), *, lockstep: bool = False,
               obstacle_limit: float = 2 * TICK_S, target_limit: float = 4 * TICK_S,
               neurons: int | None = None, integrate_on: str = "tick") -> ModuleSpec:
    """The motor module; with ``neurons`` (the lattice size) a field whose vector or
    winner does not fit the lattice is dropped and counted instead of reaching Eq. 9."""
    out_key = keys.cmd_wheels(robot)
    sender = f"{robot}/{NAME}"
    seq = [0]
    obstacle_keys = {keys.field_obstacle(robot, j): j for j in range(keys.range_sensors)}
    target_key = keys.field_target(robot)
    spec = ModuleSpec(NAME, robot, f"{keys.root}/{robot}/field/**", lambda msg, rec: handle(msg, rec), keys,
                      outputs=(out_key,))

    def source_key(msg) -> str:
        if isinstance(msg, TrackingField):
            return keys.field_tracking(robot)
        return target_key if isinstance(msg, TargetField) else keys.field_obstacle(robot, msg.index)

    state = MotorState(integrate, lockstep=lockstep, integrate_on=integrate_on, sensors=keys.range_sensors,
                       obstacle_limit=obstacle_limit, target_limit=target_limit,
                       drop=lambda msg, why: spec.drops.drop(source_key(msg), why))

    def misfit(msg) -> str | None:
        if isinstance(msg, TrackingField):  # a and b have one length (checked on decode); winners per input
            if msg.a.shape[0] != neurons:
                return f"field of {msg.a.shape[0]} neurons, the lattice has {neurons}"
            return None
        vec = msg.a if isinstance(msg, TargetField) else msg.b
        if vec is not None and vec.shape[0] != neurons:
            return f"field of {vec.shape[0]} neurons, the lattice has {neurons}"
        if msg.winner is not None and not 0 <= msg.winner < neurons:
            return f"winner {msg.winner} outside the lattice's 0..{neurons - 1}"
        return None

    def handle(msg, rec):
        if neurons is not None and isinstance(msg, (TargetField, TrackingField, ObstacleField)) and (why := misfit(msg)):
            spec.drops.drop(source_key(msg), why)
            return []
        out = []
        for stamp, v_l, v_r in state.put(msg):
            out.append((out_key, WheelCommand(stamp, sender, v_l, v_r, seq[0])))
            seq[0] += 1
        return out

    vectors = VectorCache(length=neurons)

    def fast(key: str, payload: bytes) -> list[tuple[str, bytes]] | None:
        """The hot path of ``handle``: a well-formed field with its vector read once per
        distinct vector (:class:`VectorCache`); anything else goes the general way."""
        j = obstacle_keys.get(key)
        if j is not None:
            u = obstacle_field_values(unpack(payload), j, vectors)
            if u is None:
                return None
            msg = ObstacleField(u[0], u[1], j, u[2], u[3])
        elif key == target_key:
            u = target_field_values(unpack(payload), vectors)
            if u is None:
                return None
            msg = TargetField(*u)
        else:
            return None
        if not spec.admit(key, msg.stamp):
            return []
        return [(k, encode(m)) for k, m in handle(msg, None)]

    def on_stop() -> None:
        log.info("%s: %d commands (%d repeats), stale drops %s", sender, state.commands, state.repeats,
                 state.stale_drops or "none")

    spec.on_stop, spec.fast = on_stop, fast
    spec.state = state  # type: ignore[attr-defined]  # for tests and logs
    return spec


def _build(args: argparse.Namespace) -> ModuleSpec:
    if args.tracking_range is not None:  # a tracking robot's motor
        from .tracking import load_model_arg, tracking_ekm

        tekm = tracking_ekm(load_model_arg(args.model), args.robot, args.tracking_range)
        integrate, neurons = tracking_integrate(tekm), int(tekm.model.w.shape[0])
    else:
        ekm = load_controller(args.model)
        integrate, neurons = controller_integrate(ekm), int(ekm.w.shape[0])
    return build_spec(integrate, args.robot, keyspace(args), lockstep=args.mode == "lockstep",
                      obstacle_limit=args.obstacle_stale, target_limit=args.target_stale, neurons=neurons,
                      integrate_on=args.integrate)


def main(argv: list[str] | None = None) -> int:
    p = base_parser("cekm motor integration module")
    p.add_argument("--obstacle-stale", type=float, default=2 * TICK_S,
                   help="drop an obstacle field older than this (s of sim time; default %(default)s)")
    p.add_argument("--target-stale", type=float, default=4 * TICK_S,
                   help="drop a target field older than this (s of sim time; default %(default)s)")
    p.add_argument("--integrate", choices=INTEGRATE_ON, default="tick",
                   help="real time: integrate once per tick when its fields are in (default), or on every field")
    add_params(p, (TRACKING_RANGE_PARAM,))
    return main_of(_build, p, argv)


if __name__ == "__main__":
    raise SystemExit(main())
