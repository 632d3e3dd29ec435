"""What a robot's fields see, as a few numbers for the field policy (docs/fields.md).

Everything is read off the winners the localization EKMs send (w_s = (alpha, d) of each
obstacle field's and the target field's winner, Eqs. 2-4) and, for tracking, the
teammate fields' sum: no raw sensor reading, no world state. Every feature lies in
[0, 1] except the bias (1), so a linear policy over them is well conditioned.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from itertools import chain, pairwise

import numpy as np

from ..angles import wrap_scalar

FEATURES = ("bias", "front", "left", "right", "seen", "toward_target", "target_angle", "target_near", "teammates",
            "pocket", "stalled")
"""Names of the feature vector's entries, in order."""
FEATURES_V3 = FEATURES[:9]
"""The features of a policy file of format version 1 to 3 (no ``pocket``)."""
FEATURES_V5 = FEATURES[:10]
"""The features of a policy file of format version 4 or 5 (no ``stalled``)."""

N_FEATURES = len(FEATURES)
FRONT = math.pi / 4  # |alpha| below: in front
SIDE = 3 * math.pi / 4  # pi/4 <= |alpha| < 3 pi/4: beside
TOWARD = math.pi / 6  # an obstacle within this of the target's direction stands toward it
STALL_WINDOW = 4.0  # s of the robot's own commands that ``stalled`` looks back over
STALL_PACE = 0.5  # of v_max: a mean forward pace at least this over the window is not stalled at all


def proximity(d: float, d_max: float) -> float:
    """1 at the robot's centre, 0 at the lattice's farthest distance."""
    return min(max(1.0 - d / d_max, 0.0), 1.0)


def field_features(w: np.ndarray, obstacle_winners: Iterable[int | None], target: tuple[float, float] | None,
                   teammates: float = 0.0, stalled: float = 0.0) -> np.ndarray:
    """The feature vector (:data:`FEATURES`) of one tick.

    front, left, right: the proximity of the nearest obstacle winner ahead (|alpha| < 45
    degrees), on the left and on the right (45-135 degrees); pocket: the least of the
    three, nonzero only with something ahead and on both sides at once (a U's pocket, a
    dead end), which a linear policy cannot form from the three by itself.

    ``w``: the map's input weights (alpha_i, d_i); ``obstacle_winners``: each distance
    sensor's obstacle winner (None: it sees nothing); ``target``: the target input (alpha,
    d) the target field localizes, None when there is none; ``teammates``: the largest
    entry of the teammate fields' sum (tracking; 0 otherwise); ``stalled``: how little the
    robot's own commands have moved it lately (:class:`Stall`; 0 when not known).
    """
    d_max = float(np.max(w[:, 1])) or 1.0
    front = left = right = toward = 0.0
    seen = 0
    n = 0
    t_alpha = None if target is None else target[0]
    for s in obstacle_winners:
        n += 1
        if s is None:
            continue
        seen += 1
        a, d = float(w[s, 0]), float(w[s, 1])
        p = proximity(d, d_max)
        if abs(a) < FRONT:
            front = max(front, p)
        elif abs(a) < SIDE:
            if a > 0:
                left = max(left, p)
            else:
                right = max(right, p)
        if t_alpha is not None and abs(wrap_scalar(a - t_alpha)) < TOWARD:
            toward = max(toward, p)
    if target is None or not (math.isfinite(target[0]) and math.isfinite(target[1])):
        t_angle, t_near = 0.0, 0.0
    else:
        t_angle, t_near = abs(wrap_scalar(target[0])) / math.pi, proximity(target[1], d_max)
    return np.array([1.0, front, left, right, seen / n if n else 0.0, toward, t_angle, t_near,
                     min(max(teammates, 0.0), 1.0), min(front, left, right), min(max(stalled, 0.0), 1.0)],
                    dtype=np.float64)


class Stall:
    """The feature ``stalled``: 1 - (the robot's net forward travel over the last
    :data:`STALL_WINDOW` seconds) / (:data:`STALL_PACE` x v_max x the window), clipped to
    [0, 1], from the commands its motor sent (what its wheels execute, clamped to v_max).
    Turning back and forth in place, or forward and back, nets nothing: 1. Before a whole
    window has passed it is 0 (a run's first turn toward the goal is not a stall)."""

    def __init__(self) -> None:
        self.sent: deque[tuple[float, float]] = deque()  # (t, forward speed from t on), oldest first

    def value(self, t: float, v_max: float) -> float:
        """``stalled`` at time ``t`` (before this step's command)."""
        start = t - STALL_WINDOW
        while len(self.sent) > 1 and self.sent[1][0] <= start:
            self.sent.popleft()
        if not self.sent or self.sent[0][0] > start + 1e-9 or v_max <= 0:
            return 0.0
        travel = sum(v * (t1 - max(t0, start)) for (t0, v), (t1, _) in pairwise(chain(self.sent, [(t, 0.0)])))
        return 1.0 - min(abs(travel) / (STALL_PACE * v_max * STALL_WINDOW), 1.0)

    def update(self, t: float, forward: float) -> None:
        """The forward speed of the command sent at ``t``."""
        self.sent.append((t, forward))


FIELD_FEATURES = ("near", "off_heading", "toward_target", "nearest", "lone", "closing")
"""Names of one obstacle field's own features g_j (:func:`obstacle_features`), in order."""

N_FIELD_FEATURES = len(FIELD_FEATURES)


CLOSING_SCALE = 0.3
"""m/s of closing speed beyond the robot's own approach that make the feature ``closing`` 1
(twice the robot's c* is 0.31 m/s: a mover crossing toward it)."""
CLOSING_DT_MAX = 1.0
"""s: readings farther apart than this are not differenced (a sensor that was blind)."""


def closing_speed(before: tuple[float, float] | None, now: tuple[float, float], alpha: float,
                  forward: float) -> float:
    """How fast a sensor's reading (stamp, d) closes in beyond what the robot's own forward
    speed explains for a still thing at bearing ``alpha`` (m/s, >= 0): (d_before - d_now) / dt
    - forward * cos(alpha). 0 with no earlier reading, or one older than CLOSING_DT_MAX.
    A wall the robot drives at closes at about its own speed and gives ~0; a mover coming
    at it from the side gives its speed."""
    if before is None:
        return 0.0
    dt = now[0] - before[0]
    if not 0.0 < dt <= CLOSING_DT_MAX:
        return 0.0
    return max((before[1] - now[1]) / dt - forward * max(math.cos(alpha), 0.0), 0.0)


class ClosingSpeeds:
    """Each sensor's last reading, to difference the next one against (:func:`closing_speed`).

    One per motor node: the only state of the features, and none of the fields' (a field is
    still a pure function of its winner and widths)."""

    def __init__(self) -> None:
        self._last: dict[int, tuple[float, float]] = {}

    def update(self, w: np.ndarray, readings: Sequence[tuple[float, int, int | None]], forward: float) -> list[float]:
        """Each reading's (stamp, sensor index, winner) closing speed, in order; remembers them.
        ``forward``: the robot's forward speed, the mean of its last wheel command (m/s)."""
        out = []
        for stamp, i, s in readings:
            if s is None:
                self._last.pop(i, None)
                out.append(0.0)
                continue
            now = (float(stamp), float(w[s, 1]))
            out.append(closing_speed(self._last.get(i), now, float(w[s, 0]), forward))
            self._last[i] = now
        return out


def obstacle_features(w: np.ndarray, obstacle_winners: Sequence[int | None], indices: Sequence[int],
                      target: tuple[float, float] | None, closing: Sequence[float] | None = None) -> np.ndarray:
    """g_j of each obstacle field of one tick (rows in the order given; zeros for a sensor
    that sees nothing), each in [0, 1]: what the per-field widths of the policy read.

    near: 1 - d_j/d_max of its winner; off_heading: |alpha_j|/pi; toward_target: 1 -
    |alpha_j - alpha_target|/pi (0 with no target); nearest: 1 for the nearest reading of
    the tick (ties all 1); lone: the share of its two neighbouring sensors (``indices``
    j - 1 and j + 1 around the ring of len(obstacle_winners) sensors, the world's 12 rays
    30 degrees apart) that see nothing -- 1/2 at a wall's end seen by one ray, 1 for a
    thin thing, 0 along a wall; closing: the field's ``closing`` speed (:class:`ClosingSpeeds`,
    m/s; none given: 0) over CLOSING_SCALE, at most 1 -- what tells a mover from a wall.
    """
    m = len(obstacle_winners)
    g = np.zeros((m, N_FIELD_FEATURES), dtype=np.float64)
    if m == 0:
        return g
    d_max = float(np.max(w[:, 1])) or 1.0
    seeing = {i for i, s in zip(indices, obstacle_winners, strict=True) if s is not None}
    ds = [float(w[s, 1]) for s in obstacle_winners if s is not None]
    nearest = min(ds) if ds else math.inf
    t_ok = target is not None and math.isfinite(target[0]) and math.isfinite(target[1])
    for row, (i, s) in enumerate(zip(indices, obstacle_winners, strict=True)):
        if s is None:
            continue
        a, d = float(w[s, 0]), float(w[s, 1])
        toward = 1.0 - abs(wrap_scalar(a - target[0])) / math.pi if t_ok and target is not None else 0.0
        lone = (((i - 1) % m) not in seeing) * 0.5 + (((i + 1) % m) not in seeing) * 0.5
        c = 0.0 if closing is None else min(max(closing[row] / CLOSING_SCALE, 0.0), 1.0)
        g[row] = (proximity(d, d_max), abs(wrap_scalar(a)) / math.pi, toward, float(d <= nearest), lone, c)
    return g
