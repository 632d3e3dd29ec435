"""Motor integration module: e = a - sum_j b_j, k = argmax e, c by Eq. 11 (section 3.4),
published on ``cmd/wheels``.

Two ways of deciding when to integrate (:class:`MotorState`):

* real time: on every arriving field, with the latest field of each source, leaving out
  a source whose field is older than its staleness limit (by default two of its periods:
  0.256 s for an obstacle module, 0.512 s for the target module), measured in sim time
  against the newest stamp seen. A stale target means no target: the robot stops.
* lockstep: exactly one command per tick, when every field expected for the tick's stamp
  t has arrived: the 12 obstacle fields stamped t and the target field of the latest
  target tick at or before t (t itself on even ticks). The fields are then exactly the
  ones ``RobotBrain.tick`` uses in one process, combined in the same order (obstacles by
  index), so the command is the same to the bit. A field arriving again for a tick
  already answered (the world re-publishes a tick's readings after a timeout so a
  restarted module catches up) makes the module send that tick's command again.

``python -m cekm_swarm.modules.motor --robot r1 --model M.npz --mode lockstep --connect ...``
"""

from __future__ import annotations

import argparse
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from cekm_swarm.controller.schedule import SCHEDULE
from cekm_swarm.protocol import (DEFAULT_RANGE_SENSORS, KeySpace, ObstacleField, TargetField, TrackingField, WheelCommand,
                                 encode)
from cekm_swarm.protocol.hotpath import VectorCache, obstacle_field_values, target_field_values, unpack

from cekm_swarm.runtime.process_args import add_params

from .shell import TRACKING_RANGE_PARAM, ModuleSpec, base_parser, keyspace, load_controller, main_of

NAME = "motor"
TICK_S = SCHEDULE.tick_s
TARGET_EVERY = SCHEDULE.target_every
log = logging.getLogger("cekm_swarm.modules.motor")

# integrate(target_field | None, obstacle_fields in index order) -> (v_l, v_r)
Integrate = Callable[[TargetField | None, list[ObstacleField]], tuple[float, float]]


def tick_of(stamp: float, tick_s: float = TICK_S) -> int:
    return int(round(stamp / tick_s))


def stamp_of(tick: int, tick_s: float = TICK_S) -> float:
    """Sim time of a tick, computed as the world computes it (``round(k * 0.128, 9)``)."""
    return round(tick * tick_s, 9)


@dataclass
class MotorState:
    """The motor module's bookkeeping, free of Zenoh and of the controller (``integrate``
    is injected), so it can be tested alone.

    ``put(field)`` stores a field and returns the commands to send now, as
    ``(stamp, v_l, v_r)`` tuples (none, one, or in lockstep a repeat of the last)."""

    integrate: Integrate
    lockstep: bool = False
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

    # ------------------------------------------------------------------ storing

    def put(self, msg: TargetField | TrackingField | ObstacleField) -> list[tuple[float, float, float]]:
        if isinstance(msg, (TargetField, TrackingField)):  # the target module's output (tracking: its fields)
            if self.target is not None and msg.stamp < self.target.stamp:
                return []  # out of order: keep the newer one
            self.target = msg
        elif isinstance(msg, ObstacleField):
            if not 0 <= msg.index < self.sensors:
                return []
            old = self.obstacles.get(msg.index)
            if old is not None and msg.stamp < old.stamp:
                return []
            self.obstacles[msg.index] = msg
        else:
            return []
        self.newest = max(self.newest, msg.stamp)
        return self._lockstep(msg.stamp) if self.lockstep else [self._realtime()]

    # ------------------------------------------------------------------ real time

    def fresh(self) -> tuple[TargetField | None, list[ObstacleField]]:
        """The latest field of each source, without those older than their limit (counted
        in ``stale_drops`` once each time a source goes stale, and logged)."""
        newest = self.newest
        target = self.target
        if target is not None and newest - target.stamp > self.target_limit + 1e-9:
            self._stale("target", target.stamp)
            target = None
        else:
            self._stale_now.discard("target")
        obstacles = []
        for j in sorted(self.obstacles):
            f = self.obstacles[j]
            name = f"obstacle-{j}"
            if newest - f.stamp > self.obstacle_limit + 1e-9:
                self._stale(name, f.stamp)
                continue
            self._stale_now.discard(name)
            obstacles.append(f)
        return target, obstacles

    def _stale(self, name: str, stamp: float) -> None:
        if name not in self._stale_now:
            self._stale_now.add(name)
            self.stale_drops[name] = self.stale_drops.get(name, 0) + 1
            log.warning("stale field dropped: %s (stamp %.3f, newest %.3f)", name, stamp, self.newest)

    def _realtime(self) -> tuple[float, float, float]:
        target, obstacles = self.fresh()
        v_l, v_r = self.integrate(target, obstacles)
        self.commands += 1
        return (self.newest, v_l, v_r)

    # ------------------------------------------------------------------ lockstep

    def target_stamp_for(self, stamp: float) -> float:
        """The stamp of the target field a tick at ``stamp`` uses (the latest target tick)."""
        k = tick_of(stamp, self.tick_s)
        return stamp_of(k - k % self.target_every, self.tick_s)

    def missing(self, stamp: float) -> list[str]:
        """The fields still missing for the tick at ``stamp`` (empty: complete)."""
        out = []
        want = self.target_stamp_for(stamp)
        if self.target is None or self.target.stamp != want:
            out.append("target")
        for j in range(self.sensors):
            f = self.obstacles.get(j)
            if f is None or f.stamp != stamp:
                out.append(f"obstacle-{j}")
        return out

    def _lockstep(self, arrived: float) -> list[tuple[float, float, float]]:
        # The tick the obstacle fields are at (all 12 carry the same stamp when complete).
        if len(self.obstacles) < self.sensors:
            return []
        stamp = self.obstacles[0].stamp
        if stamp < self.sent_stamp:
            return []
        if stamp == self.sent_stamp:
            if arrived == stamp and self.sent is not None:  # a re-published tick: answer again
                self.repeats += 1
                return [(stamp, *self.sent)]
            return []
        if self.missing(stamp):
            return []
        v_l, v_r = self.integrate(self.target, [self.obstacles[j] for j in range(self.sensors)])
        self.sent_stamp, self.sent = stamp, (v_l, v_r)
        self.commands += 1
        return [(stamp, v_l, v_r)]


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
               obstacle_limit: float = 2 * TICK_S, target_limit: float = 4 * TICK_S) -> ModuleSpec:
    state = MotorState(integrate, lockstep=lockstep, sensors=keys.range_sensors, obstacle_limit=obstacle_limit,
                       target_limit=target_limit)
    out_key = keys.cmd_wheels(robot)
    sender = f"{robot}/{NAME}"
    seq = [0]

    def handle(msg, rec):
        out = []
        for stamp, v_l, v_r in state.put(msg):
            out.append((out_key, WheelCommand(stamp, sender, v_l, v_r, seq[0])))
            seq[0] += 1
        return out

    obstacle_keys = {keys.field_obstacle(robot, j): j for j in range(keys.range_sensors)}
    target_key = keys.field_target(robot)
    vectors = VectorCache()

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
        return [(k, encode(m)) for k, m in handle(msg, None)]

    def on_stop() -> None:
        log.info("%s: %d commands (%d repeats), stale drops %s", sender, state.commands, state.repeats,
                 state.stale_drops or "none")

    spec = ModuleSpec(NAME, robot, f"{keys.root}/{robot}/field/**", handle, keys, on_stop=on_stop, fast=fast,
                      outputs=(out_key,))
    spec.state = state  # type: ignore[attr-defined]  # for tests and logs
    return spec


def _build(args: argparse.Namespace) -> ModuleSpec:
    if args.tracking_range is not None:  # a tracking robot's motor
        from .tracking import load_model_arg, tracking_ekm

        integrate = tracking_integrate(tracking_ekm(load_model_arg(args.model), args.robot, args.tracking_range))
    else:
        integrate = controller_integrate(load_controller(args.model))
    return build_spec(integrate, args.robot, keyspace(args),
                      lockstep=args.mode == "lockstep", obstacle_limit=args.obstacle_stale,
                      target_limit=args.target_stale)


def main(argv: list[str] | None = None) -> int:
    p = base_parser("cekm motor integration module")
    p.add_argument("--obstacle-stale", type=float, default=2 * TICK_S,
                   help="drop an obstacle field older than this (s of sim time; default %(default)s)")
    p.add_argument("--target-stale", type=float, default=4 * TICK_S,
                   help="drop a target field older than this (s of sim time; default %(default)s)")
    add_params(p, (TRACKING_RANGE_PARAM,))
    return main_of(_build, p, argv)


if __name__ == "__main__":
    raise SystemExit(main())
