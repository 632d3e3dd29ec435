"""Moving obstacles seen from the raw ranges, and the command that keeps clear of them
(docs/fields.md, "The movers").

A moving disc that hits a robot side-on is sensed as a wall would be: the obstacle fields
say where something is, not that it moves. Closing speeds of the fields' winners cannot tell
the two apart (their lattice steps and the rays sweeping along walls look like motion).
:class:`MoverDetector` does it from the distance sensors' raw readings and the robot's
dead-reckoned pose. A ray's reading says that the space along the ray up to the hit is free.
A hit inside space that a ray of the last few ticks saw free, well short of where that ray
hit (noise allowed for), is something that moved in: a mover is found there.

A mover is then a disc of known radius moving at a constant velocity. Its centre and
velocity are the least-squares fit to the rays of the last ``window`` ticks
(:func:`fit_disc`): the hits near it lie on its rim, and the rays near it that saw free space
do not cross it. One ray in twelve is 30 degrees wide of the next, so a small disc is often
hit by one ray only, and a centre guessed from each hit jumps between rays; the fit uses the
rays that miss it as well, and recovers the velocity that the velocity obstacle needs.
:func:`keep_clear` is a velocity-obstacle choice. If the motor EKM's command would bring the
body within ``margin`` of a tracked mover within ``horizon`` seconds, the command is replaced
by whichever of stop, back, forward or a turn in place at c* keeps the most clearance.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .bounds import check_bounds
from .dead_reckoning import Pose

Mover = tuple[float, float, float, float]  # x, y, vx, vy in the dead-reckoned frame


@dataclass(frozen=True)
class MoverParams:
    """history: ticks of rays the free-space check remembers; eps: how near (m) a hit must be
    to an earlier ray's line; slack: a hit must lie short of that ray's own hit by slack +
    noise * its length (m; noise: the readings' relative error); radius: a mover's radius
    (m); window: ticks of rays a mover's disc is fitted to; gate: how far (m) from the
    predicted rim a hit joins the fit; sigma: the hits' and free rays' residual scale (m);
    v_prior: the velocity's prior scale (m/s; the fit leans to standing still when the rays
    say little); v_max: the fitted speed's cap (m/s); forget: seconds a mover lives without
    a hit that moved in on its rim (a still thing wrongly found is soon dropped); confirm:
    ticks with such hits before a track is a mover (one grazing ray on a wall makes one);
    min_speed: a mover slower than this (m/s) is not returned; horizon: seconds of motion
    checked; margin: the clearance (m) a command must keep; still_horizon: seconds of motion
    in which a replacing command must not bring the body nearer than ``margin`` to what the
    ranges see now (when it is not that near already)."""

    history: int = 4
    eps: float = 0.006
    slack: float = 0.02
    noise: float = 0.1
    radius: float = 0.04
    window: int = 6
    gate: float = 0.025
    sigma: float = 0.01
    v_prior: float = 0.3
    v_max: float = 0.4
    forget: float = 0.5
    confirm: int = 2
    min_speed: float = 0.0
    horizon: float = 1.5
    margin: float = 0.01
    still_horizon: float = 0.5

    def check(self) -> MoverParams:
        """Itself, or ValueError naming the first parameter out of range."""
        check_bounds("mover", self, ticks=("history", "window", "confirm"),
                     positive=("eps", "radius", "gate", "sigma", "v_prior", "v_max", "forget", "horizon",
                               "still_horizon"),
                     nonnegative=("slack", "noise", "margin", "min_speed"))
        return self


FIT_STEPS = 4
"""Levenberg-Marquardt steps of one fit (it starts from the last fit's prediction)."""
NEAR_RAY = 0.05
"""m beyond a disc's rim within which a free ray joins its fit."""


@dataclass
class _Tick:
    """One tick's rays (free lengths already short of the noise) and hit points."""

    t: float
    rays: np.ndarray  # (n, 5): origin x, y, direction x, y, free length short of the noise
    hits: np.ndarray  # (m, 2): the hit points


@dataclass
class _Track:
    """A mover's disc as last fitted."""

    q: np.ndarray  # centre x, y and velocity x, y at time t
    t: float
    moved: float  # when a hit that moved in last lay on its rim
    moves: int = 1  # ticks with such hits
    ticks: int = 0  # ticks of the window with a hit on its rim


def seen_free(points: np.ndarray, rays: np.ndarray, eps: float) -> np.ndarray:
    """For each point (rows x, y), whether a ray (rows origin x, y, direction x, y, the length
    surely free) passes within ``eps`` of it short of its free length: space that ray saw
    free. Movers are hits in such space; the guard forgets remembered hits in it."""
    if not len(points) or not len(rays):
        return np.zeros(len(points), dtype=bool)
    wx = points[:, 0][:, None] - rays[:, 0][None, :]
    wy = points[:, 1][:, None] - rays[:, 1][None, :]
    along = wx * rays[:, 2] + wy * rays[:, 3]
    return ((along > 0.0) & (along < rays[:, 4]) & (np.abs(wx * rays[:, 3] - wy * rays[:, 2]) < eps)).any(axis=1)


def fit_disc(q: np.ndarray, hits: np.ndarray, rays: np.ndarray, radius: float, sigma: float,
             v_prior: float, steps: int = FIT_STEPS) -> np.ndarray:
    """Centre and velocity (x, y, vx, vy at dt = 0) of a disc of ``radius`` moving straight:
    least squares from ``q`` over the hits (rows x, y, dt) on its rim, the free rays (rows
    origin x, y, direction x, y, free length, dt) that must not cross it, and the prior
    velocity ~ N(0, v_prior^2)."""
    lam = 1e-3

    def residuals(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cx, cy = q[0] + q[2] * hits[:, 2], q[1] + q[3] * hits[:, 2]
        wx, wy = cx - hits[:, 0], cy - hits[:, 1]
        n = np.maximum(np.hypot(wx, wy), 1e-9)
        r_hit = (n - radius) / sigma
        j_hit = np.stack([wx / n, wy / n, wx / n * hits[:, 2], wy / n * hits[:, 2]], axis=1) / sigma
        fx, fy = q[0] + q[2] * rays[:, 5], q[1] + q[3] * rays[:, 5]
        zx, zy = fx - rays[:, 0], fy - rays[:, 1]
        a = np.clip(zx * rays[:, 2] + zy * rays[:, 3], 0.0, rays[:, 4])
        zx, zy = zx - a * rays[:, 2], zy - a * rays[:, 3]  # from the ray's nearest point to the centre
        ds = np.maximum(np.hypot(zx, zy), 1e-9)
        inside = ds < radius
        r_free = np.where(inside, (radius - ds) / sigma, 0.0)
        j_free = np.where(inside[:, None], -np.stack([zx / ds, zy / ds, zx / ds * rays[:, 5], zy / ds * rays[:, 5]],
                                                     axis=1) / sigma, 0.0)
        r_v = q[2:] / v_prior
        j_v = np.array([[0.0, 0.0, 1.0 / v_prior, 0.0], [0.0, 0.0, 0.0, 1.0 / v_prior]])
        return np.concatenate([r_hit, r_free, r_v]), np.concatenate([j_hit, j_free, j_v])

    r, jac = residuals(q)
    cost = float(r @ r)
    for _ in range(steps):
        a = jac.T @ jac
        step = np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-9), -(jac.T @ r))
        r_new, jac_new = residuals(q + step)
        cost_new = float(r_new @ r_new)
        if cost_new < cost:
            q, r, jac, cost, lam = q + step, r_new, jac_new, cost_new, lam * 0.3
        else:
            lam *= 10.0
    return q


@dataclass
class MoverDetector:
    """The rays of the last ticks and the movers fitted to them."""

    params: MoverParams = MoverParams()
    reach: float = 0.2  # m from the centre a ray sees (body radius + range): its free length seeing nothing
    ticks: deque[_Tick] = field(default_factory=deque)  # the last max(history, window)
    tracks: list[_Track] = field(default_factory=list)

    def update(self, t: float, pose: Pose, readings: Iterable[tuple[float, float | None]]) -> list[Mover]:
        """One tick: the readings (alpha, d from the centre, None when nothing is in range)
        taken at ``pose``; returns the movers (fitted to hits on two ticks or more, with
        hits that moved in on ``confirm`` ticks, at ``min_speed`` or faster), at ``t``."""
        p = self.params
        x, y, th = pose
        rays = np.array([(x, y, math.cos(th + a), math.sin(th + a), self.reach if d is None else d)
                         for a, d in readings], dtype=np.float64).reshape(-1, 5)
        hit = rays[:, 4] < self.reach
        hits = rays[hit, :2] + rays[hit, 2:4] * rays[hit, 4:5]
        moved = self._moved_in(hits)
        moved_in = zip(hits[moved].tolist(), rays[hit, 2:4][moved].tolist(), strict=True)
        rays[:, 4] -= p.slack + p.noise * rays[:, 4]  # the length surely free
        self.ticks.append(_Tick(t, rays[rays[:, 4] > 0.0], hits))
        while len(self.ticks) > max(p.history, p.window):
            self.ticks.popleft()
        for tr in self.tracks:
            self._fit(tr, t)
        for (hx, hy), (ux, uy) in moved_in:
            near = [tr for tr in self.tracks if math.hypot(hx - tr.q[0], hy - tr.q[1]) - p.radius < p.gate]
            if near:
                for tr in near:
                    tr.moves += tr.moved < t
                    tr.moved = t
                continue
            tr = _Track(np.array([hx + p.radius * ux, hy + p.radius * uy, 0.0, 0.0]), t, moved=t)
            self._fit(tr, t)
            self.tracks.append(tr)
        self.tracks = [tr for tr in self.tracks if t - tr.moved <= p.forget]
        self._merge(t)
        return [(float(tr.q[0] + tr.q[2] * (t - tr.t)), float(tr.q[1] + tr.q[3] * (t - tr.t)), float(tr.q[2]),
                 float(tr.q[3])) for tr in self.tracks
                if tr.ticks >= 2 and tr.moves >= p.confirm and math.hypot(tr.q[2], tr.q[3]) >= p.min_speed]

    @property
    def hits(self) -> np.ndarray:
        """The points the ranges hit at the last update, rows x, y (what keeping clear must not
        drive into)."""
        return self.ticks[-1].hits if self.ticks else np.zeros((0, 2))

    def _merge(self, t: float) -> None:
        """Of two tracks whose discs overlap by more than half a radius now, the one whose
        rim a hit moved in on less recently goes (a mover's first guess left behind by its
        path)."""
        p = self.params
        keep: list[_Track] = []
        for tr in sorted(self.tracks, key=lambda tr: -tr.moved):
            x, y = tr.q[:2] + tr.q[2:] * (t - tr.t)
            if all(math.hypot(x - k.q[0] - k.q[2] * (t - k.t), y - k.q[1] - k.q[3] * (t - k.t)) > 1.5 * p.radius
                   for k in keep):
                keep.append(tr)
        self.tracks = keep

    def _moved_in(self, points: np.ndarray) -> np.ndarray:
        """For each point (rows x, y), whether it lies in space a ray of the last ``history``
        ticks saw free, short of its hit (by the slack and noise)."""
        recent = list(self.ticks)[-self.params.history:]
        rays = np.concatenate([tick.rays for tick in recent]) if recent else np.zeros((0, 5))
        return seen_free(points, rays, self.params.eps)

    def _fit(self, tr: _Track, t: float) -> None:
        """The track's disc fitted again to the window: to the hits within ``gate`` of its
        predicted rim (or inside it) and the free rays passing near it."""
        p = self.params
        q = tr.q.copy()
        q[:2] += q[2:] * (t - tr.t)
        hits, rays, tr.ticks = self._near(q, t)
        if not hits:
            return
        q = fit_disc(q, np.concatenate(hits), np.concatenate(rays) if rays else np.zeros((0, 6)), p.radius,
                     p.sigma, p.v_prior)
        speed = math.hypot(q[2], q[3])
        if speed > p.v_max:
            q[2:] *= p.v_max / speed
        tr.q, tr.t = q, t

    def _near(self, q: np.ndarray, t: float) -> tuple[list[np.ndarray], list[np.ndarray], int]:
        """The window's hits within ``gate`` of the rim of the disc ``q`` (rows x, y, dt), the
        free rays passing within ``NEAR_RAY`` of it (rows origin, direction, free length, dt), and
        the number of ticks with such hits."""
        p = self.params
        hits, rays, ticks = [], [], 0
        for tick in list(self.ticks)[-p.window:]:
            dt = tick.t - t
            cx, cy = q[0] + q[2] * dt, q[1] + q[3] * dt
            if len(tick.hits):
                on = np.hypot(tick.hits[:, 0] - cx, tick.hits[:, 1] - cy) - p.radius < p.gate
                if on.any():
                    ticks += 1
                    hits.append(np.column_stack([tick.hits[on], np.full(int(on.sum()), dt)]))
            r = tick.rays
            zx, zy = cx - r[:, 0], cy - r[:, 1]
            a = np.clip(zx * r[:, 2] + zy * r[:, 3], 0.0, r[:, 4])
            near = np.hypot(zx - a * r[:, 2], zy - a * r[:, 3]) < p.radius + NEAR_RAY
            if near.any():
                rays.append(np.column_stack([r[near], np.full(int(near.sum()), dt)]))
        return hits, rays, ticks


CHECK_STEP = 0.064
"""s between the instants :func:`clearance` checks."""


def clearance(pose: Pose, command: tuple[float, float], movers: Sequence[Mover], reach: float, axle: float,
              horizon: float) -> float:
    """The least distance (m) between the body and a mover's edge over ``horizon`` s: the
    robot on ``command`` (v_l, v_r) as a differential drive of ``axle``, the movers on
    straight lines; ``reach``: body radius + mover radius."""
    x, y, th = pose
    v, omega = 0.5 * (command[0] + command[1]), (command[1] - command[0]) / axle
    least = math.inf
    for k in range(int(horizon / CHECK_STEP) + 1):
        s = k * CHECK_STEP
        for mx, my, vx, vy in movers:
            least = min(least, math.hypot(mx + vx * s - x, my + vy * s - y) - reach)
        x, y, th = x + v * CHECK_STEP * math.cos(th), y + v * CHECK_STEP * math.sin(th), th + omega * CHECK_STEP
    return least


def keep_clear(pose: Pose, command: tuple[float, float], movers: Sequence[Mover], reach: float, axle: float,
               v_max: float, params: MoverParams, still: Sequence[tuple[float, float]] | np.ndarray = ()
               ) -> tuple[float, float]:
    """The command, or when it would come within ``margin`` of a mover within ``horizon``
    s, the one of stop, back, forward, turn left or right in place at ``v_max`` that keeps
    the most clearance (the command itself if none keeps more). A replacement must not
    bring the body within ``margin`` of a point of ``still`` (what the ranges hit now)
    within ``still_horizon`` s, unless it is that near already: keeping clear of a mover
    never drives the robot into a wall."""
    if not movers:
        return command
    base = clearance(pose, command, movers, reach, axle, params.horizon)
    if base >= params.margin:
        return command
    body = reach - params.radius
    points = [(px, py, 0.0, 0.0) for px, py in still]
    floor = min(params.margin, clearance(pose, (0.0, 0.0), points, body, axle, 0.0))
    options = [(0.0, 0.0), (-v_max, -v_max), (v_max, v_max), (-v_max, v_max), (v_max, -v_max)]
    scored = [(clearance(pose, o, movers, reach, axle, params.horizon), o) for o in options
              if o == (0.0, 0.0) or clearance(pose, o, points, body, axle, params.still_horizon) >= floor]
    best_clear, best = max(scored, key=lambda s: s[0])
    return best if best_clear > base else command
