"""Tracking target module (tracking scenarios, docs/tracking.md): on the robot's
``sense/pose`` and ``sense/targets`` (every 0.256 s) and its teammates' ``share``
messages, the weighted target fields, the teammate fields and their inputs (one
``field/tracking`` message for the motor) and the robot's own ``share``.

It runs :meth:`TrackingRobot.on_sense` of :mod:`cekm_swarm.controller.tracking`, the
function the in-process runner calls. Which shares a tick uses (:class:`TrackingModuleState`):

* lockstep: the tick at sim time t waits for the share stamped at the previous target
  tick (t - 0.256 s) from every teammate still alive, and uses exactly the shares stamped
  before t (a teammate's share stamped t that arrives early waits for the next tick); so
  the fields equal the in-process run's to the bit;
* real time: it computes as soon as the pose and the targets of t are in, with every
  share stamped before t that has arrived.

A teammate whose liveliness tokens have all vanished (its processes died) is dropped
from the team view at once (out of every field); it is logged as a ``DROP {json}`` line
with the wall time, and a lockstep tick waiting for its share goes on without it.

The module's liveliness token is ``target`` (it is the robot's target module).

``python -m cekm_swarm.modules.tracking --robot r1 --model M.npz --team r1,r2 --target-range 0.5 --connect ...``
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from dataclasses import dataclass, field

from cekm_swarm.controller.tracking import TrackingActivity, TrackingRobot
from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import KeySpace, Message, SensePose, SenseTargets, Share, TrackingField

from cekm_swarm.runtime.process_args import add_params

from .shell import TARGET_RANGE_PARAM, TEAM_PARAM, ModuleSpec, base_parser, keyspace, main_of

NAME = "target"
TARGET_PERIOD_S = 0.256
MAX_PENDING = 64  # sense messages or shares held per source before the oldest go
log = logging.getLogger("cekm_swarm.modules.tracking")


def tracking_field(act: TrackingActivity, sender: str) -> TrackingField:
    """The message of one tracking-target-module output."""
    return TrackingField(act.stamp, sender, act.a, act.b_team, act.inputs, act.weights, act.searching)


def tracking_activity(msg: TrackingField) -> TrackingActivity:
    """The activity the motor integrates, from its message (the inverse of :func:`tracking_field`)."""
    return TrackingActivity(msg.stamp, msg.a, msg.b, msg.inputs, msg.weights, msg.searching)


def same_stamp(a: float, b: float) -> bool:
    return abs(a - b) < 1e-6


@dataclass
class TrackingModuleState:
    """The module's bookkeeping, free of Zenoh: ``put(msg)`` and ``teammate_alive(robot,
    alive)`` return the messages to publish now, as ``[(key, message)]``."""

    brain: TrackingRobot
    team: tuple[str, ...]  # every robot of the scenario, in scenario order (own id included or not)
    keys: KeySpace = field(default_factory=KeySpace)
    lockstep: bool = False
    period: float = TARGET_PERIOD_S
    poses: dict[float, SensePose] = field(default_factory=dict)
    targets: dict[float, SenseTargets] = field(default_factory=dict)
    pending: dict[str, list[Share]] = field(default_factory=dict)
    used: dict[str, float] = field(default_factory=dict)  # newest share stamp handed to the view, per teammate
    dropped: set[str] = field(default_factory=set)
    done: float = -math.inf
    computed: int = 0
    drops: list[dict] = field(default_factory=list)
    ignored_shares: int = 0
    last_field: TrackingField | None = None

    def __post_init__(self) -> None:
        self.robot = self.brain.robot
        self.mates = tuple(r for r in self.team if r != self.robot)
        self.sender = f"{self.robot}/{NAME}"
        self.out_field = self.keys.field_tracking(self.robot)
        self.out_share = self.keys.share(self.robot)

    # ------------------------------------------------------------------ inputs

    def put(self, msg: Message, source: str | None = None) -> list[tuple[str, Message]]:
        """``source``: the robot whose key a share came on (default: its sender)."""
        if isinstance(msg, (SensePose, SenseTargets)):
            if msg.stamp == self.done and self.last_field is not None:
                return [(self.out_field, self.last_field)]  # the world re-published a stalled tick: answer again
            if msg.stamp > self.done:
                self._hold(self.poses if isinstance(msg, SensePose) else self.targets, msg)
        elif isinstance(msg, Share):
            robot = source or msg.sender.split("/", 1)[0]
            if robot == self.robot:
                return []
            if robot not in self.mates or robot in self.dropped:
                self.ignored_shares += 1
                return []
            q = self.pending.setdefault(robot, [])
            q.append(msg)
            if len(q) > MAX_PENDING:
                del q[0]
        else:
            return []
        return self._compute()

    @staticmethod
    def _hold(store: dict, msg: Message) -> None:
        store[msg.stamp] = msg
        while len(store) > MAX_PENDING:
            del store[min(store)]

    def teammate_alive(self, robot: str, alive: bool) -> list[tuple[str, Message]]:
        """A teammate's processes are all gone (``alive`` False: drop it from every field
        now) or one of them is back (``alive`` True)."""
        if robot not in self.mates:
            return []
        if alive:
            self.dropped.discard(robot)
            return []
        if robot in self.dropped:
            return []
        self.dropped.add(robot)
        self.pending.pop(robot, None)
        self.brain.drop(robot)
        self.drops.append({"robot": self.robot, "dropped": robot, "wall": time.time()})
        return self._compute()

    # ------------------------------------------------------------------ computing

    def _ready(self, t: float) -> bool:
        """Lockstep: every live teammate's share of the previous target tick is in. The
        first tick after a (re)start waits for none: shares published before it will not
        come again."""
        if not self.lockstep or t < self.period - 1e-6 or self.computed == 0:
            return True
        prev = round(t - self.period, 9)
        for r in self.mates:
            if r in self.dropped:
                continue
            if any(same_stamp(s.stamp, prev) for s in self.pending.get(r, ())):
                continue
            if same_stamp(self.used.get(r, -1.0), prev):
                continue
            return False
        return True

    def _compute(self) -> list[tuple[str, Message]]:
        out: list[tuple[str, Message]] = []
        while True:
            both = sorted(s for s in self.poses if s in self.targets and s > self.done)
            if not both:
                return out
            t = both[0]
            if not self._ready(t):
                return out
            for r in self.mates:  # the shares stamped before t, in stamp order
                q = self.pending.get(r)
                if not q:
                    continue
                early = []
                for s in sorted(q, key=lambda s: s.stamp):
                    if s.stamp < t:
                        self.brain.receive(r, s)
                        self.used[r] = max(self.used.get(r, -1.0), s.stamp)
                    else:
                        early.append(s)
                self.pending[r] = early
            pose, seen = self.poses.pop(t), self.targets.pop(t)
            for store in (self.poses, self.targets):
                for s in [s for s in store if s < t]:
                    del store[s]
            share = self.brain.on_sense(pose, seen)
            self.done = t
            self.computed += 1
            act = self.brain.activity
            if isinstance(act, TrackingActivity):
                self.last_field = tracking_field(act, self.sender)
                out.append((self.out_field, self.last_field))
            out.append((self.out_share, share))


def build_spec(brain: TrackingRobot, team: tuple[str, ...], keys: KeySpace = KeySpace(), *,
               lockstep: bool = False) -> ModuleSpec:
    state = TrackingModuleState(brain, team, keys, lockstep)
    robot = brain.robot
    tokens: dict[str, set[str]] = {}

    def handle(msg, rec):
        source = None
        if isinstance(msg, Share):
            try:
                source = keys.parse(rec.key).robot
            except CekmError:
                return []
        return state.put(msg, source)

    def liveliness(key: str, alive: bool) -> list[tuple[str, Message]]:
        try:
            owner = keys.parse(key).robot
        except CekmError:
            return []
        if owner is None or owner == robot or owner not in state.mates:
            return []
        held = tokens.setdefault(owner, set())
        if alive:
            held.add(key)
            return state.teammate_alive(owner, True)
        held.discard(key)
        if held:
            return []
        out = state.teammate_alive(owner, False)
        if state.drops and state.drops[-1]["dropped"] == owner:
            sys.stdout.write("DROP " + json.dumps(state.drops[-1]) + "\n")
            sys.stdout.flush()
            log.warning("%s: teammate %s dropped (its liveliness tokens vanished)", state.sender, owner)
        return out

    def on_stop() -> None:
        log.info("%s: %d ticks computed, %d teammates dropped, %d shares ignored", state.sender, state.computed,
                 len(state.drops), state.ignored_shares)

    spec = ModuleSpec(NAME, robot, keys.sense_pose(robot), handle, keys, on_stop=on_stop,
                      outputs=(keys.field_tracking(robot), keys.share(robot)),
                      also=(keys.sense_targets(robot), keys.share_all()), liveliness=liveliness)
    spec.state = state  # type: ignore[attr-defined]  # for tests and logs
    return spec


def tracking_ekm(model, robot: str, target_range: float):
    """The robot's cooperative-EKM tracking controller, as ``cekm run`` builds it
    (:func:`cekm_swarm.experiments.tracking.make_robot`), on the numpy backend."""
    from cekm_swarm.controller.tracking import TrackingEKM
    from cekm_swarm.models.params import FieldParams, TrackingParams

    return TrackingEKM(robot, model, target_range, TrackingParams(), FieldParams.paper(), backend="numpy")


def load_model_arg(source):
    from cekm_swarm.models.io import load_model, load_model_bytes

    if isinstance(source, tuple):
        where, blob = source
        return load_model_bytes(blob, where)
    return load_model(source)


def _build(args: argparse.Namespace) -> ModuleSpec:
    from cekm_swarm.controller.team import TeamView
    from cekm_swarm.models.params import TrackingParams

    team = tuple(r.strip() for r in args.team.split(",") if r.strip())
    tp = TrackingParams()
    ctl = tracking_ekm(load_model_arg(args.model), args.robot, args.target_range)
    brain = TrackingRobot(args.robot, ctl, TeamView(args.robot, tp.share_timeout_s, tp.memory_s))
    return build_spec(brain, team, keyspace(args), lockstep=args.mode == "lockstep")


def parser() -> argparse.ArgumentParser:
    return add_params(base_parser("cekm tracking target module"), (TEAM_PARAM, TARGET_RANGE_PARAM))


def main(argv: list[str] | None = None) -> int:
    return main_of(_build, parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
