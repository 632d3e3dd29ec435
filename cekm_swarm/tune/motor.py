"""The motor nodes of cooperative EKMs with field parameters chosen per tick (docs/fields.md).

They integrate exactly as :mod:`cekm_swarm.modules.motor_integration` and
:mod:`cekm_swarm.modules.tracking_motor` do (Eqs. 9-11, the same code), with one
difference: the obstacle fields b_j are Eq. 8 of each localization module's winner with
the widths the field policy chooses from what the fields see (:mod:`.features`) -- one set
for the tick, or with a policy's per-field weights V each field's own -- and for
tracking the teammate fields' sum is scaled by the policy's gain. A field is a pure
function of its winner and its widths, so computing it here is exact, and the
localization modules and the message protocol are unchanged: with the base widths and
``turn_gain`` 1 this node's commands equal the plain motor node's, bit for bit (tested).

One thing the navigation node executes differently (``turn_gain``, default inf; not a
field parameter, as tracking's ``face_turn_gain``): when every forward neuron is inhibited
and the detour winner k turns the robot in place toward its rear (|alpha_k| > pi/2, d_k <=
reverse_min_d), its command's turn part is scaled up to c*, its mean speed kept. As Eq. 11
gives it the turn is about 0.25 rad/s, slow enough that the rear neuron on the other side
wins a few degrees later and turns it back: the robot swings in a narrow U or in front of
a disc instead of turning round (docs/fields.md, the sixth round).

One field the navigation node adds (``trail_gain``, default :data:`TRAIL_GAIN`; 0: none):
the trail field of :mod:`cekm_swarm.controller.trail`, the robot's memory of where it has
been, among the obstacle fields of Eq. 9 once the target has come no nearer for a while. It
leads a robot out of a deep U it would circle in (docs/fields.md, the seventh round). While
it acts, the field widths take turns (``alternate``, default :data:`ALTERNATE` s): the
policy's, then the paper's constants, and so on until the robot progresses again. The learned
widths take the robot up to a wall met head-on and the paper's keep it at their range, so each
leaves a stall the other circles in: a deep wide U, a long shallow one (the tenth round).
And one check of its command (``keep_clear``, default :data:`KEEP_CLEAR`): the moving
obstacles :class:`cekm_swarm.controller.movers.MoverDetector` finds in the distance sensors'
raw readings (its ``ranges`` input), and :func:`~cekm_swarm.controller.movers.keep_clear`'s
velocity-obstacle choice when the command would bring the body within 1 cm of one
(docs/fields.md, "The movers" and the eighth round). Keeping clear, it also keeps its
command off what the ranges hit in the last ticks (``guard``, default :data:`GUARD`;
:mod:`cekm_swarm.controller.guard`): a doorway's jamb end that falls between two rays is still
there (docs/fields.md, the ninth round). :data:`PLAIN` turns them all off: the plain motor
node's Eqs. 9-11, bit for bit.

Why the motor node: it is the one node that sees every field of a tick at once, which
the policy's input needs; a separate policy node would need a new message to every
localization module for the same result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cekm_swarm.controller.cooperative import ObstacleActivity, TargetActivity, face_turn, turns_to_rear
from cekm_swarm.controller.dead_reckoning import DeadReckoning, executed
from cekm_swarm.controller.guard import Guard, GuardParams
from cekm_swarm.controller.movers import MoverDetector, MoverParams, keep_clear
from cekm_swarm.controller.trail import Trail, TrailParams, paper_turn
from cekm_swarm.models.fields import obstacle_field, target_field
from cekm_swarm.models.params import FieldParams, TrackingParams, narrowed
from cekm_swarm.modules.ekm import cooperative_ekm
from cekm_swarm.modules.motor_integration import target_activity
from cekm_swarm.modules.tracking_localization import tracking_activity, tracking_ekm
from cekm_swarm.node import In, Node, NodeError, Out
from cekm_swarm.protocol import ObstacleField, SenseRange, TargetField, TrackingField, WheelCommand
from cekm_swarm.protocol.checks import lattice_misfit
from cekm_swarm.ticks import tick_of

from .features import ClosingSpeeds, Stall, field_features, obstacle_features
from .policy import FieldChoice, FieldPolicy, shipped_policy

KEEP_CLEAR = True
"""Whether the default navigation motor keeps clear of the movers it detects
(:mod:`cekm_swarm.controller.movers`; docs/fields.md, "The movers")."""
GUARD = True
"""Whether, keeping clear, it keeps its command off the hits of the last ticks as well
(:mod:`cekm_swarm.controller.guard`; docs/fields.md, "The ninth round")."""
TRAIL_GAIN = 0.3
"""The trail field's peak in the default navigation motor (chosen on validation seeds by the
selection rule of docs/fields.md, the seventh round)."""
ALTERNATE = 20.0
"""s: once the trail field acts, the default navigation motor's field widths go from the
policy's to the paper's and back every this many seconds (chosen on validation seeds,
docs/fields.md, the tenth round)."""
PLAIN: dict[str, float | bool] = {"turn_gain": 1.0, "trail_gain": 0.0, "keep_clear": False}
"""The navigation node's parameters that make it the plain motor node (Eq. 11's turns as they
are, no trail field and so no paper's widths in turn, no keeping clear of movers): with W = 0,
``cekm run --fields tuned`` exactly."""

PAPER = FieldChoice(FieldParams.paper())
"""The paper's constants as a tick's choice: the widths that stand in for the policy's in
their turn (:func:`~cekm_swarm.controller.trail.paper_turn`)."""

ROWS_KEPT = 256
"""Obstacle-field rows a node remembers (keyed by winner and widths: exact for any widths)."""


class _PolicyFields:
    """What both motor nodes share: the policy (or the environment's choice) and Eq. 8's rows."""

    task = "navigation"
    params: Any  # the node's (cekm_swarm.node.api.Node)
    ctx: Any

    def _load_policy(self) -> FieldPolicy:
        """The policy the parameters name: ``weights`` if given, else the ``policy`` file
        (default: the one shipped for the task)."""
        p = self.params
        self._source = (p.policy, p.weights)
        if p.weights:
            return FieldPolicy.from_flat(self.task, p.weights)
        path = p.policy or shipped_policy(self.task)
        return FieldPolicy.load(path).check_task(self.task, path)

    def _follow_params(self) -> None:
        """A ``policy`` or ``weights`` changed while the node runs (``cekm param set``):
        the new policy from this step on; one that cannot be read is refused in the node's
        log, naming it, and the policy before it stays."""
        if (self.params.policy, self.params.weights) == self._source:
            return
        try:
            self.policy = self._load_policy()
        except Exception as exc:  # noqa: BLE001 -- a bad file or weight count: logged, the run goes on
            self.ctx.log.error("%s: field policy %s refused: %s; the policy before it stays", self.ctx.sender,
                               self.params.policy or "weights", exc)

    def _setup_policy(self) -> None:
        try:
            self.policy = self._load_policy()
        except Exception as exc:  # a bad file, weight count or task: the node names it and stops
            raise NodeError(f"{self.ctx.sender}: field policy: {exc}") from None
        self.override: FieldChoice | None = None  # set by the environments (cekm_swarm.tune.env_core)
        self._fixed = False  # whether the tick's choice is one set for every field (not the policy's)
        self.last_features: np.ndarray | None = None
        self.last_choice: FieldChoice | None = None
        self.last_widths: list[tuple[float, float, float]] | None = None  # each obstacle field's, last tick
        self._rows: dict[tuple[int, float, float, float], np.ndarray] = {}
        base = self.policy.base_fields
        self._target_widths = (base.sigma_a_alpha, base.sigma_a_d)  # the target module's widths (Eq. 6)
        self._closing = ClosingSpeeds()  # each sensor's last reading (the feature "closing")
        self._executed = (0.0, 0.0)  # the last command sent, as the wheels execute it
        self._stall = Stall()  # the commands sent lately (the feature "stalled")

    def _stalled(self, t: float) -> float:
        return self._stall.value(t, self.ctx.body.v_max)

    def _sent(self, t: float, v_l: float, v_r: float) -> None:
        """Remember the command sent, as this robot's wheels execute it (clamped to its body's
        v_max): the robot's own approach, which ``closing`` discounts."""
        self._executed = executed(v_l, v_r, self.ctx.body.v_max)
        self._stall.update(t, self._forward)

    @property
    def _forward(self) -> float:
        """The robot's forward speed (m/s), from the last command sent."""
        return (self._executed[0] + self._executed[1]) / 2.0

    def _choose(self, features: np.ndarray, instead: FieldChoice | None = None) -> FieldChoice:
        """The tick's field parameters: an environment's action (``override``), else ``instead``
        if given, else the policy's."""
        self._follow_params()
        self.last_features = features
        fixed = self.override if self.override is not None else instead
        self._fixed = fixed is not None
        choice = fixed if fixed is not None else self.policy.choose(features)
        self.last_choice = choice
        return choice

    def _target(self, w: np.ndarray, act: TargetActivity | None, choice: FieldChoice) -> TargetActivity | None:
        """The target field a with the choice's sigma_a_alpha and sigma_a_d (Eq. 6): the target
        module's own row when they are the base widths (so W = 0 is today's run, bit for bit),
        else recomputed from its winner (a pure function of winner and widths: exact). Rows
        cached as Eq. 8's."""
        sa, sd = choice.fields.sigma_a_alpha, choice.fields.sigma_a_d
        if act is None or act.a is None or act.winner is None or (sa, sd) == self._target_widths:
            return act
        key = (-1 - act.winner, sd, sa, 0.0)  # winners as negative keys: apart from the obstacle rows
        a = self._rows.get(key)
        if a is None:
            a = self._rows[key] = target_field(w, act.winner, choice.fields)
        return replace(act, a=a)

    def _obstacles(self, w: np.ndarray, fields, choice: FieldChoice, target: tuple[float, float] | None,
                   features: np.ndarray) -> list[ObstacleActivity]:
        """b_j of each winner with its widths (Eq. 8), in sensor order: the tick's choice for
        every field, or each field's own when the policy has per-field weights (and neither an
        environment's action nor the paper's widths in their turn stand in for it). Rows are
        cached by (winner, widths): exact."""
        fp: FieldParams | None = None  # the tick's, when every field has them
        if not self._fixed and self.policy.per_field:
            closing = self._closing.update(w, [(f.stamp, f.index, f.winner) for f in fields], self._forward)
            g = obstacle_features(w, [f.winner for f in fields], [f.index for f in fields], target, closing)
            widths = [(a, b, c) for a, b, c in self.policy.field_widths(features, g).tolist()]
        else:
            fp = choice.fields
            widths = [(fp.sigma_b_alpha, fp.sigma_b_d_beyond, fp.sigma_b_d_near)] * len(fields)
        self.last_widths = widths
        if len(self._rows) > ROWS_KEPT:
            self._rows = {}
        out = []
        for f, wd in zip(fields, widths, strict=True):
            b = None
            if f.winner is not None:
                key = (f.winner, *wd)
                b = self._rows.get(key)
                if b is None:
                    b = self._rows[key] = obstacle_field(w, f.winner, fp or self.policy.widths_params(wd))
            out.append(ObstacleActivity(f.stamp, f.index, f.winner, b))
        return out


class FieldMotor(_PolicyFields, Node):
    """Motor EKM with policy-chosen obstacle widths: target and obstacle fields -> wheel command."""

    inputs = {"target": In(TargetField, doc="the target field (the latest target tick's)"),
              "obstacles": In(ObstacleField, many=True, doc="every obstacle field of the tick (their winners)"),
              "ranges": In(SenseRange, many=True, doc="every distance sensor's raw reading (the movers' detector)")}
    outputs = {"command": Out(WheelCommand, doc="c = (v_l, v_r), clipped to c*")}
    uses_model = True
    warm_setup = True

    @dataclass(frozen=True)
    class Params:
        allow_reverse: bool = False  # as the shipped motor node's
        reverse_min_d: float = 0.02
        policy: str = ""  # a field policy file (cekm tune fields); "" = the one shipped for navigation
        weights: tuple[float, ...] = ()  # the policy's weights in place of a file (training): W, then V if any
        turn_gain: float = math.inf  # a detour's turn in place toward the rear, executed up to c* (1: as Eq. 11)
        trail_gain: float = TRAIL_GAIN  # the trail field's peak once progress stops (0: no trail field)
        keep_clear: bool = KEEP_CLEAR  # movers detected from the raw ranges are kept clear of (False: none)
        guard: bool = GUARD  # with keep_clear: the command kept off the hits of the last ticks (False: none)
        alternate: float = ALTERNATE  # s: with the trail acting, the policy's widths and the paper's in turn (0: never)

    def setup(self) -> None:
        if not self.params.turn_gain >= 1.0:
            raise NodeError(f"{self.ctx.sender}: turn_gain must be >= 1 (inf: up to c*), got {self.params.turn_gain!r}")
        if not 0.0 <= self.params.alternate < math.inf:
            raise NodeError(f"{self.ctx.sender}: alternate must be >= 0 s (0: never), got {self.params.alternate!r}")
        self.ekm = cooperative_ekm(self.ctx, None, self.params.allow_reverse, self.params.reverse_min_d)
        self.integrated: tuple[TargetActivity | None, list[ObstacleActivity]] | None = None
        try:
            self._trail = Trail(TrailParams(gain=self.params.trail_gain).check())
        except ValueError as exc:
            raise NodeError(f"{self.ctx.sender}: {exc}") from None
        self.reckoning = DeadReckoning()  # the pose from its own commands: the trail's places, the movers' rays
        self._trail_refused: float | None = None  # a trail gain set while running and refused
        body = self.ctx.body
        self._movers = MoverDetector(MoverParams().check(), reach=body.body_radius + body.sensor_range)
        self.last_movers: list[tuple[float, float, float, float]] = []  # tracked at the last step
        self._guard = Guard(GuardParams().check())
        self.last_guarded = False  # whether the guard replaced the last step's command
        self._setup_policy()

    def check_input(self, port, msg):
        return lattice_misfit(msg, self.ekm.n)

    def step(self, t, inputs):
        tf, fields = inputs["target"], list(inputs["obstacles"].values())
        target = None if tf is None or tf.a is None else (tf.alpha, tf.d)
        features = field_features(self.ekm.w, [f.winner for f in fields], target, stalled=self._stalled(t))
        choice = self._choose(features, PAPER if self._paper_turn(t) else None)
        self.integrated = (self._target(self.ekm.w, target_activity(tf), choice),
                           self._obstacles(self.ekm.w, fields, choice, target, features))  # as the plain motor's
        body = self.ctx.body
        self.reckoning.move(t, *self._executed, body.axle)  # the last tick's command, executed until now
        out = self.ekm.integrate(*self._with_trail(t, tf))  # Eqs. 9-11
        v_l, v_r = out.v_l, out.v_r
        if self.params.turn_gain != 1.0 and out.k is not None and out.k != out.s \
                and turns_to_rear(self.ekm.w, out.k, self.params.reverse_min_d):
            v_l, v_r = face_turn(v_l, v_r, self.params.turn_gain, self.ctx.body.v_max, turn_only=True)
        if self.params.keep_clear:
            readings = [(r.alpha, r.d) for _, r in sorted(inputs["ranges"].items(), key=lambda kv: kv[1].index)]
            self.last_movers = self._movers.update(t, self.reckoning.pose, readings)
            tick = self._movers.ticks[-1]
            self._guard.update(tick.hits, tick.rays)
            self.last_guarded = False
            if out.k is not None and self.params.guard:
                wanted = (v_l, v_r)
                v_l, v_r = self._guard.command(self.reckoning.pose, wanted, body.body_radius, body.axle, body.v_max)
                self.last_guarded = (v_l, v_r) != wanted
            if out.k is not None:  # a command of the motor EKM (not the stop of no target or the goal)
                v_l, v_r = keep_clear(self.reckoning.pose, (v_l, v_r), self.last_movers,
                                      body.body_radius + self._movers.params.radius, body.axle, body.v_max,
                                      self._movers.params, self._movers.hits)
        self._sent(t, v_l, v_r)
        return {"command": WheelCommand(t, self.ctx.sender, v_l, v_r, tick_of(t))}

    def _paper_turn(self, t: float) -> bool:
        """Whether the paper's widths stand in for the policy's on this tick: the trail acts
        (as of the last tick) and it is their turn (:func:`~cekm_swarm.controller.trail.paper_turn`)."""
        return self._trail.params.gain > 0.0 and paper_turn(self._trail.acting_for(t), self.params.alternate)

    def _with_trail(self, t: float, tf: TargetField | None) -> tuple[TargetActivity | None, list[ObstacleActivity]]:
        """The tick's fields with the trail field among the obstacle fields once the target has
        come no nearer for a while (:mod:`cekm_swarm.controller.trail`); as they are otherwise."""
        target, obstacles = self.integrated  # type: ignore[misc]
        gain = self.params.trail_gain
        if gain != self._trail.params.gain and gain != self._trail_refused:  # set while it runs (cekm param set)
            try:
                self._trail.params = replace(self._trail.params, gain=gain).check()
            except ValueError as exc:
                self._trail_refused = gain
                self.ctx.log.error("%s: %s; the trail gain before it stays", self.ctx.sender, exc)
        if self._trail.params.gain == 0.0:
            return target, obstacles
        self._trail.update(t, self.reckoning.pose, None if tf is None or tf.d is None else float(tf.d))
        b = self._trail.field(t, self.reckoning.pose, self.ekm.w)
        return (target, obstacles) if b is None else (target, [*obstacles, ObstacleActivity(t, -1, None, b)])


class FieldTrackingMotor(_PolicyFields, Node):
    """The tracking motor module with policy-chosen obstacle widths and teammate gain."""

    task = "tracking"
    inputs = {"tracking": In(TrackingField, doc="the tracking fields of the latest target tick"),
              "obstacles": In(ObstacleField, many=True, doc="every obstacle field of the tick (their winners)")}
    outputs = {"command": Out(WheelCommand)}
    uses_model = True
    warm_setup = True

    @dataclass(frozen=True)
    class Params(TrackingParams):  # the tracking motor's (face_turn_gain is executed here), and:
        policy: str = ""  # a field policy file; "" = the one shipped for tracking
        weights: tuple[float, ...] = ()

    def setup(self) -> None:
        self.tekm = tracking_ekm(self.ctx, narrowed(self.params, TrackingParams))
        self._setup_policy()

    def check_input(self, port, msg):
        return lattice_misfit(msg, self.tekm.ekm.n)

    def step(self, t, inputs):
        f, fields = inputs["tracking"], list(inputs["obstacles"].values())
        act = None if f is None else tracking_activity(f)
        w = self.tekm.ekm.w
        target, team = None, 0.0
        if act is not None:
            if act.inputs:
                _, alpha, d, _ = max(act.inputs, key=lambda x: x[3])
                target = (alpha, d)
            team = float(np.max(act.b_team)) if len(act.b_team) else 0.0
        features = field_features(w, [o.winner for o in fields], target, team, self._stalled(t))
        choice = self._choose(features)
        if act is not None and choice.teammate_gain != 1.0:
            act = replace(act, b_team=choice.teammate_gain * act.b_team)
        out = self.tekm.integrate(act, self._obstacles(w, fields, choice, target, features))  # Eqs. 9-11
        self._sent(t, out.v_l, out.v_r)
        return {"command": WheelCommand(t, self.ctx.sender, out.v_l, out.v_r, tick_of(t))}
