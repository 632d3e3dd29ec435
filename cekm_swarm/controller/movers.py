"""Moving obstacles seen from the raw ranges, and the command that keeps clear of them
(docs/fields.md, "The movers").

A moving disc that hits a robot side-on is sensed as a wall would be: the obstacle fields
say where something is, not that it moves. Closing speeds of the fields' winners cannot tell
the two apart (their lattice steps and the rays sweeping along walls look like motion).
:class:`MoverDetector` does it from the distance sensors' raw readings and the robot's
dead-reckoned pose. A ray's reading says that the space along the ray up to the hit is free.
A hit inside space that a ray of the last few ticks saw free, well short of where that ray
hit (noise allowed for), is something that moved in. Such hits become tracks with a velocity
(an alpha-beta filter, as :class:`~.anticipation.TargetTracks` for targets).
:func:`keep_clear` is a velocity-obstacle choice. If the motor EKM's command would bring the
body within ``margin`` of a tracked mover within ``horizon`` seconds, the command is replaced
by whichever of stop, back, forward or a turn in place at c* keeps the most clearance.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

Pose = tuple[float, float, float]
Mover = tuple[float, float, float, float]  # x, y, vx, vy in the dead-reckoned frame


@dataclass(frozen=True)
class MoverParams:
    """history: ticks of rays remembered; eps: how near (m) a hit must be to an earlier ray's
    line; slack: a hit must lie short of that ray's own hit by slack + noise * its length
    (m; noise: the readings' relative error); radius: a mover's radius (m, its centre lies
    this far beyond the hit); assoc: how far (m) from a track's prediction a hit joins it;
    forget: seconds a track lives without a hit; gain_x, gain_v: the filter's gains;
    min_speed: a track slower than this (m/s) is no mover (a wall seen by a grazing ray can
    leave hits near an earlier ray's line; the obstacle fields keep clear of still things);
    horizon: seconds of motion checked; margin: the clearance (m) a command must keep."""

    history: int = 4
    eps: float = 0.006
    slack: float = 0.02
    noise: float = 0.1
    radius: float = 0.04
    assoc: float = 0.08
    forget: float = 0.5
    gain_x: float = 0.5
    gain_v: float = 0.3
    min_speed: float = 0.0
    horizon: float = 1.5
    margin: float = 0.01

    def check(self) -> MoverParams:
        """Itself, or ValueError naming the first parameter out of range."""
        if self.history < 1:
            raise ValueError(f"mover history must be >= 1 tick, got {self.history!r}")
        for name in ("eps", "assoc", "forget", "horizon"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"mover {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("slack", "noise", "radius", "margin", "gain_x", "gain_v", "min_speed"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"mover {name} must be >= 0, got {getattr(self, name)!r}")
        return self


Ray = tuple[float, float, float, float, float]  # origin x, y, direction x, y, free length


@dataclass
class MoverDetector:
    """The rays of the last ``history`` ticks and the movers tracked from them."""

    params: MoverParams = MoverParams()
    reach: float = 0.2  # m from the centre a ray sees (body radius + range): its free length seeing nothing
    rays: deque[list[Ray]] = field(default_factory=deque)
    tracks: list[list[float]] = field(default_factory=list)  # x, y, vx, vy, t, hits

    def update(self, t: float, pose: Pose, readings: Iterable[tuple[float, float | None]]) -> list[Mover]:
        """One tick: the readings (alpha, d from the centre, None when nothing is in range)
        taken at ``pose``; returns the movers tracked (seen on two ticks or more, at ``min_speed``
        or faster), at ``t``."""
        p = self.params
        x, y, th = pose
        now: list[Ray] = []
        hits: list[tuple[float, float]] = []
        for alpha, d in readings:
            ux, uy = math.cos(th + alpha), math.sin(th + alpha)
            now.append((x, y, ux, uy, self.reach if d is None else d))
            if d is not None and self._moved_in(x + d * ux, y + d * uy):
                hits.append((x + (d + p.radius) * ux, y + (d + p.radius) * uy))
        self.rays.append(now)
        while len(self.rays) > p.history:
            self.rays.popleft()
        for hx, hy in hits:
            self._track(t, hx, hy)
        self.tracks = [tr for tr in self.tracks if t - tr[4] <= p.forget]
        return [(tr[0] + tr[2] * (t - tr[4]), tr[1] + tr[3] * (t - tr[4]), tr[2], tr[3])
                for tr in self.tracks if tr[5] >= 2 and math.hypot(tr[2], tr[3]) >= p.min_speed]

    def _moved_in(self, px: float, py: float) -> bool:
        """Whether (px, py) lies in space a remembered ray saw free, short of its hit."""
        p = self.params
        for tick in self.rays:
            for ox, oy, ux, uy, free in tick:
                wx, wy = px - ox, py - oy
                along = wx * ux + wy * uy
                if 0.0 < along < free - (p.slack + p.noise * free) and abs(wx * uy - wy * ux) < p.eps:
                    return True
        return False

    def _track(self, t: float, hx: float, hy: float) -> None:
        p = self.params
        best: tuple[float, list[float]] | None = None
        for tr in self.tracks:
            dt = t - tr[4]
            gap = math.hypot(hx - (tr[0] + tr[2] * dt), hy - (tr[1] + tr[3] * dt))
            if gap < p.assoc and (best is None or gap < best[0]):
                best = (gap, tr)
        if best is None:
            self.tracks.append([hx, hy, 0.0, 0.0, t, 1.0])
            return
        tr = best[1]
        dt = t - tr[4]
        if dt <= 0.0:
            return
        ex, ey = tr[0] + tr[2] * dt, tr[1] + tr[3] * dt
        rx, ry = hx - ex, hy - ey
        tr[0], tr[1] = ex + p.gain_x * rx, ey + p.gain_x * ry
        tr[2], tr[3] = tr[2] + p.gain_v * rx / dt, tr[3] + p.gain_v * ry / dt
        tr[4], tr[5] = t, tr[5] + 1.0


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
               v_max: float, params: MoverParams) -> tuple[float, float]:
    """The command, or when it would come within ``margin`` of a mover within ``horizon``
    s, the one of stop, back, forward, turn left or right in place at ``v_max`` that keeps
    the most clearance (the command itself if none keeps more)."""
    if not movers:
        return command
    base = clearance(pose, command, movers, reach, axle, params.horizon)
    if base >= params.margin:
        return command
    options = [(0.0, 0.0), (-v_max, -v_max), (v_max, v_max), (-v_max, v_max), (v_max, -v_max)]
    scored = [(clearance(pose, o, movers, reach, axle, params.horizon), o) for o in options]
    best_clear, best = max(scored, key=lambda s: s[0])
    return best if best_clear > base else command
