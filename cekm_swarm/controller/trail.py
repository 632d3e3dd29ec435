"""The trail field: a robot's memory of where it has been, an inhibitory field over the motor
lattice once it stops getting nearer its target (docs/fields.md, "The seventh round").

A reactive field does not leave a deep U it has entered: the target field pulls the robot
back in each time it reaches the mouth, and it circles inside. The trail remembers the
places the robot passed (dead-reckoned from its own wheel commands, :mod:`~.dead_reckoning`,
so no node needs the world), and when the target has come no nearer for ``patience``
seconds, a field like an obstacle field (Eq. 8's b_j, subtracted in Eq. 9's sum) inhibits
the motor neurons whose direction points at a place visited earlier and near: the visited
inside of the U fills up, and the winner leads out of it. While the robot progresses, the field is absent, so
the integration is Eq. 9 as it was.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .bounds import check_bounds
from .dead_reckoning import Pose

SAME_PLACE = 0.02
"""m: a remembered place this near the robot has no bearing worth inhibiting."""


@dataclass(frozen=True)
class TrailParams:
    """gain: the field's peak (0: no field); sigma: its width in direction (rad); radius:
    places farther than this (m) are not inhibited; progress: a new best distance to the
    target by this much (m) is progress; patience: seconds without progress before the
    field acts; recent: places visited less than this long ago (s) are left alone (the
    robot's own wake); memory: how long a place is remembered (s); every: seconds between
    remembered places."""

    gain: float = 0.6
    sigma: float = 0.5
    radius: float = 0.4
    progress: float = 0.05
    patience: float = 8.0
    recent: float = 4.0
    memory: float = 120.0
    every: float = 0.5

    def check(self) -> TrailParams:
        """Itself, or ValueError naming the first parameter out of range."""
        check_bounds("trail", self, positive=("sigma", "radius", "every"),
                     nonnegative=("gain", "progress", "patience", "recent", "memory"))
        return self


@dataclass
class Trail:
    """The places the robot passed (in its dead-reckoned frame,
    :mod:`~.dead_reckoning`), and its best distance to the target with the time it was
    reached."""

    params: TrailParams = TrailParams()
    places: list[tuple[float, float, float]] = field(default_factory=list)  # (t, x, y)
    best: tuple[float, float] = (math.inf, 0.0)  # (distance to the target, when)
    _array: np.ndarray | None = None  # ``places`` as an array, made again when they change

    def update(self, t: float, pose: Pose, target_d: float | None) -> None:
        """Remember the robot's place at ``t`` (every ``every`` s), forget those past
        ``memory``, and note progress: a distance to the target ``progress`` below the best
        so far."""
        p = self.params
        if target_d is not None and target_d < self.best[0] - p.progress:
            self.best = (target_d, t)
        if not self.places or t - self.places[-1][0] >= p.every:
            self.places.append((t, pose[0], pose[1]))
            self._array = None
        while self.places and t - self.places[0][0] > p.memory:
            self.places.pop(0)
            self._array = None

    def acting_for(self, t: float) -> float:
        """Seconds since the field began to act at ``t`` (the target no nearer for ``patience``
        s); zero or less while the robot progresses."""
        return t - self.best[1] - self.params.patience

    def field(self, t: float, pose: Pose, w: np.ndarray) -> np.ndarray | None:
        """The trail field of the robot at ``pose`` over the motor lattice ``w`` (rows
        alpha_k, d_k), or None while the robot progresses (or has no place to avoid):
        b_k = gain * max over places q visited between ``memory`` and ``recent`` ago within
        ``radius`` of exp(-(alpha_k - bearing_q)^2 / (2 sigma^2)) * (1 - r_q / radius)."""
        p = self.params
        if p.gain == 0.0 or t - self.best[1] <= p.patience:
            return None
        x, y, th = pose
        if self._array is None:
            self._array = np.array(self.places, dtype=np.float64).reshape(-1, 3)
        old = self._array[t - self._array[:, 0] > p.recent, 1:]
        if len(old) == 0:
            return None
        r = np.hypot(old[:, 0] - x, old[:, 1] - y)
        near = (r < p.radius) & (r > SAME_PLACE)
        if not near.any():
            return None
        bearing = np.arctan2(old[near, 1] - y, old[near, 0] - x) - th
        off = (w[:, 0][:, None] - bearing[None, :] + np.pi) % (2.0 * np.pi) - np.pi
        closeness = 1.0 - r[near] / p.radius
        return p.gain * np.max(np.exp(-off ** 2 / (2.0 * p.sigma ** 2)) * closeness[None, :], axis=1)


def paper_turn(acting_for: float, period: float) -> bool:
    """Whether the paper's field widths are in their turn ``acting_for`` s after the trail began
    to act: the policy's widths for the first ``period`` s, then the paper's for ``period`` s,
    and so on until the robot progresses again (``period`` 0: never). A stall the learned widths
    do not leave (a long shallow U at a short range) the paper's leave, and the reverse (a deep
    wide U); docs/fields.md, the tenth round."""
    return period > 0.0 and acting_for > 0.0 and int(acting_for // period) % 2 == 1
