"""Cooperative EKMs (sections 3.2-3.4): modules as pure functions of their inputs.

Each module is what one process of the distributed runtime runs:

* target localization (every 0.256 s): the sensed target u -> winner s and target field a;
* obstacle localization j (every 0.128 s, one per distance sensor): u_j -> winner and
  obstacle field b_j, or nothing when the sensor sees nothing;
* motor integration (once per tick of fields): e = a - sum_j b_j (Eq. 9), k = argmax e
  (Eq. 10), c by Eq. 11 with M_k; at the goal state c = 0. What the wheels execute is c
  clipped to c*.

All localization EKMs and the motor EKM share the trained input weights w (section 3.3).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from ..angles import wrap_scalar
from ..models.competition import winner
from ..models.fields import obstacle_field, target_field
from ..models.networks import IndirectEKM
from ..models.params import FieldParams
from .readings import RangeReading, TargetReading

WINNER_MEMO = 4096
"""Inputs whose winner a controller remembers before it starts again (a bound on memory)."""


@dataclass(frozen=True)
class TargetActivity:
    """Output of target localization: the input u, its winner s and the target field a."""

    stamp: float
    alpha: float
    d: float
    winner: int | None  # None: no target sensed
    a: np.ndarray | None
    at_goal: bool = False


@dataclass(frozen=True)
class ObstacleActivity:
    """Output of obstacle localization j: its winner and field b_j, None when nothing is sensed."""

    stamp: float
    index: int
    winner: int | None
    b: np.ndarray | None


@dataclass(frozen=True)
class MotorOutput:
    """The motor EKM's decision: the command c (clipped to c*), the motor winner k, and the
    target winner s it was compared with."""

    v_l: float
    v_r: float
    k: int | None
    s: int | None


def motor_candidates(model: IndirectEKM, allow_reverse: bool = False, reverse_min_d: float = 0.02) -> np.ndarray:
    """The neurons that may win the motor competition (Eq. 10) in obstacle navigation.

    * Only converged neurons (``model.converged``, checked after training: M_i w_i moves
      the robot by w_i). A neuron stranded between the learned clusters has control
      parameters fitted to its neighbours' data; its command does not do what its input
      weight says, and as a motor winner it drives the robot into what it should avoid.
    * Unless ``allow_reverse``: no neuron encoding a reverse displacement (|alpha_i| >
      pi/2 and d_i > reverse_min_d). The target field is angle-insensitive (sigma_a_alpha
      = 2.475 rad), so a reverse move keeps 45 % of the target activity, and nothing
      behind a forward-driving robot inhibits it: in a concave obstacle or at a doorway it
      always beats the edge neuron of Fig. 4F (about 0.43) and the robot backs out and
      re-enters. The paper's G9 and G12 maps have no reverse cluster (section 4.1), so
      this never arises for them; maps learned from untrained M with exploration noise do
      have one. Turning in place (d_i <= reverse_min_d) stays available.
    This is the project's resolution (README), not the paper's text.
    """
    w = model.w
    ok = np.ones(w.shape[0], dtype=np.bool_)
    converged = getattr(model, "converged", None)
    if converged is not None:
        ok &= converged
    if not allow_reverse:
        ok &= ~((np.abs(w[:, 0]) > np.pi / 2) & (w[:, 1] > reverse_min_d))
    if not ok.any():
        ok[:] = True
    return ok


def motor_command(M: np.ndarray, w: np.ndarray, alpha: float, d: float, k: int, s: int | None, v_max: float,
                  d_scale: float) -> tuple[float, float]:
    """Eq. 11 then clipped to c*: c = M_k u if k = s and |M_k u| <= c*, else M_k w_k.

    Plain float arithmetic, the same operations as the numpy reference
    (:func:`cekm_swarm.models.fields.motor_control`) and the numba kernel, in the same order.
    """
    Mk = M[k]
    if k == s:
        x0 = float(w[k, 0]) + wrap_scalar(alpha - float(w[k, 0]))
        x1 = d_scale * d
        c0 = float(Mk[0, 0]) * x0 + float(Mk[0, 1]) * x1
        c1 = float(Mk[1, 0]) * x0 + float(Mk[1, 1]) * x1
        if abs(c0) <= v_max and abs(c1) <= v_max:
            return c0, c1
    x0 = float(w[k, 0])
    x1 = d_scale * float(w[k, 1])
    c0 = float(Mk[0, 0]) * x0 + float(Mk[0, 1]) * x1
    c1 = float(Mk[1, 0]) * x0 + float(Mk[1, 1]) * x1
    return min(max(c0, -v_max), v_max), min(max(c1, -v_max), v_max)


def face_turn(v_l: float, v_r: float, gain: float, v_max: float, turn_only: bool = False) -> tuple[float, float]:
    """A turn-in-place command of Eq. 11 executed faster (tracking's face_turn_gain, the
    navigation field-policy motor's turn_gain): c scaled by min(gain, c* / max |c|), its
    direction kept, no wheel beyond c*; ``turn_only``: only its turn part (v_r - v_l) / 2
    scaled, by min(gain, (c* - |v|) / |turn|), its mean speed v = (v_l + v_r) / 2 kept."""
    if turn_only:
        v, h = 0.5 * (v_l + v_r), 0.5 * (v_r - v_l)
        f = min(gain, (v_max - abs(v)) / abs(h)) if h != 0.0 else 1.0
        return (v - f * h, v + f * h) if f > 1.0 else (v_l, v_r)
    top = max(abs(v_l), abs(v_r))
    f = min(gain, v_max / top) if top > 0.0 else 1.0
    return (v_l * f, v_r * f) if f > 1.0 else (v_l, v_r)


def turns_to_rear(w: np.ndarray, k: int, reverse_min_d: float = 0.02) -> bool:
    """Whether motor neuron k turns the robot in place toward its rear half (|alpha_k| > pi/2,
    d_k <= reverse_min_d): the only rear neurons :func:`motor_candidates` keeps without
    ``allow_reverse``, and the winner left when every forward neuron is inhibited."""
    return bool(abs(float(w[k, 0])) > np.pi / 2 and float(w[k, 1]) <= reverse_min_d)


class FieldRows(dict[int, np.ndarray]):
    """A field's rows by winner s, each computed when first asked for (read-only): the
    values a tabulated row holds, for a map that changes too often to tabulate."""

    def __init__(self, w: np.ndarray, fields: FieldParams,
                 field_of: Callable[[np.ndarray, int, FieldParams], np.ndarray]) -> None:
        super().__init__()
        self.w, self.fields, self.field_of = w, fields, field_of

    def __missing__(self, s: int) -> np.ndarray:
        row = self.field_of(self.w, s, self.fields)
        row.flags.writeable = False
        self[s] = row
        return row


@dataclass
class CooperativeEKM:
    """The cooperative-EKM controller of one robot, from a trained indirect-mapping EKM.

    ``backend`` chooses how winners are found: "numba" (the in-process runner: fast) or
    "numpy" (the module processes: no numba in the process, about a third of the memory).
    Both compute the same arithmetic and give the same winners bit for bit (tested); the
    fields are tabulated with numpy either way, so every output is identical.
    """

    model: IndirectEKM
    fields: FieldParams = field(default_factory=FieldParams)
    allow_reverse: bool = False
    reverse_min_d: float = 0.02
    backend: str = "numba"
    tabulate: bool = True  # every field row at once (False: each when first asked for, the same values)

    def __post_init__(self) -> None:
        if self.backend not in ("numba", "numpy"):
            raise ValueError(f"CooperativeEKM.backend must be 'numba' or 'numpy', got {self.backend!r}")
        self.w = np.ascontiguousarray(self.model.w)
        self._M = np.ascontiguousarray(self.model.M)
        self.n = self.w.shape[0]
        self.eligible = motor_candidates(self.model, self.allow_reverse, self.reverse_min_d)
        if self.tabulate:
            # A field depends only on its winner s (Eqs. 6, 8), so both are tabulated once per model.
            self._A = np.stack([target_field(self.w, s, self.fields) for s in range(self.n)])
            self._B = np.stack([obstacle_field(self.w, s, self.fields) for s in range(self.n)])
            self._A.flags.writeable = False
            self._B.flags.writeable = False
            # one read-only row object per winner, made once: each call hands out the same array
            # (no view made per message; a field message takes a read-only array as it is)
            self._A_rows: tuple[np.ndarray, ...] | FieldRows = tuple(self._A[s] for s in range(self.n))
            self._B_rows: tuple[np.ndarray, ...] | FieldRows = tuple(self._B[s] for s in range(self.n))
        else:  # a map that changes as it learns (docs/learning.md): the rows it meets, when it meets them
            self._A_rows = FieldRows(self.w, self.fields, target_field)
            self._B_rows = FieldRows(self.w, self.fields, obstacle_field)
        if self.backend == "numba":
            from ..models import fast  # noqa: PLC0415 -- lazy: numba costs ~0.15 s; only this backend needs it

            params = fast.pack_params(self.model.comp, self.model.learn_p, self.model.v_max, 1e-3)
            self._compete: Callable[[float, float], int] = lambda alpha, d: int(fast.winner(alpha, d, self.w, params))
        else:
            self._compete = lambda alpha, d: winner(np.array([alpha, d]), self.w, self.model.comp)
        self._winners: dict[tuple[float, float], int] = {}

    def winner(self, alpha: float, d: float) -> int:
        """The winner for input (alpha, d) (Eqs. 2-4), remembered per exact input: the
        competition is a pure function of the input, and a distance sensor's readings
        are quantised (5 mm steps at a fixed direction), so an obstacle module meets the
        same few dozen inputs again and again. Exact keys: the answer is the same bit for bit."""
        key = (alpha, d)
        s = self._winners.get(key)
        if s is None:
            s = self._compete(alpha, d)
            if len(self._winners) >= WINNER_MEMO:
                self._winners.clear()
            self._winners[key] = s
        return s

    def target_activity(self, s: int) -> np.ndarray:
        """The target field a_i of winner s (Eqs. 5-6), tabulated; read-only."""
        return self._A_rows[s]

    def obstacle_activity(self, s: int) -> np.ndarray:
        """The obstacle field b_i of winner s (Eqs. 7-8), tabulated; read-only."""
        return self._B_rows[s]

    def localize_target(self, reading: TargetReading, stamp: float) -> TargetActivity:
        """Target localization (section 3.2): s = winner(u) (Eqs. 2-4), a_i = G_a(w_s, w_i) (Eqs. 5-6)."""
        if not reading.usable:
            return TargetActivity(stamp, float("nan"), float("nan"), None, None)
        if reading.at_goal:
            return TargetActivity(stamp, reading.alpha, reading.d, None, None, at_goal=True)
        s = self.winner(reading.alpha, reading.d)
        return TargetActivity(stamp, reading.alpha, reading.d, s, self._A_rows[s])

    def localize_obstacle(self, reading: RangeReading, stamp: float) -> ObstacleActivity:
        """Obstacle localization j (section 3.3): winner for u_j = (alpha_j, d_j), b_i = G_b (Eqs. 7-8)."""
        if reading.d is None:
            return ObstacleActivity(stamp, reading.index, None, None)
        s = self.winner(reading.alpha, reading.d)
        return ObstacleActivity(stamp, reading.index, s, self._B_rows[s])

    def localize_obstacles(self, readings: list[RangeReading], stamp: float) -> list[ObstacleActivity]:
        """Every obstacle localization module at once (the in-process path): the same as
        :meth:`localize_obstacle` for each reading."""
        return [self.localize_obstacle(r, stamp) for r in readings]

    def integrate(self, target: TargetActivity | None, obstacles: Iterable[ObstacleActivity]) -> MotorOutput:
        """Neural integration and motor control (section 3.4, Eqs. 9-11): e = a - sum_j b_j in
        sensor order, k = the first largest e among the motor candidates, c by Eq. 11.

        No target sensed yet, or the goal state: the robot stops.
        """
        if target is None or target.at_goal or target.a is None:
            return MotorOutput(0.0, 0.0, None, None)
        e = target.a.copy()
        for ob in obstacles:
            if ob.b is not None:
                e -= ob.b
        k = int(np.argmax(np.where(self.eligible, e, -np.inf)))
        m = self.model
        v_l, v_r = motor_command(self._M, self.w, target.alpha, target.d, k, target.winner, m.v_max,
                                 m.learn_p.d_scale)
        return MotorOutput(v_l, v_r, k, target.winner)
