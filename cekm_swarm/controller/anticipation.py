"""Two additions to the cooperative-EKM tracker (docs/tracking.md), pure functions of plain
values: where a sensed target will be (:class:`TargetTracks`, an alpha-beta filter of its
world position, A-CMOMMT's "predictive" idea made explicit), and the point between the
targets one robot can hold together (:func:`held_group`), whose target field lets the
neuron between two parting targets win while both fit in the sensing range."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

Point = tuple[float, float]


@dataclass
class TargetTracks:
    """Per target, a filtered world position and velocity from this robot's own sightings
    (alpha-beta filter: gains ``gain_x`` on the position residual, ``gain_v`` on the velocity);
    a track not updated for ``forget_s`` starts afresh."""

    gain_x: float = 0.5
    gain_v: float = 0.1
    forget_s: float = 1.5
    tracks: dict[str, tuple[float, float, float, float, float]] = field(default_factory=dict)  # x, y, vx, vy, t

    def update(self, t: float, seen: dict[str, Point]) -> None:
        for tid in sorted(seen):
            zx, zy = seen[tid]
            tr = self.tracks.get(tid)
            if tr is None or t - tr[4] > self.forget_s or t <= tr[4]:
                self.tracks[tid] = (zx, zy, 0.0, 0.0, t)
                continue
            x, y, vx, vy, t0 = tr
            dt = t - t0
            px, py = x + vx * dt, y + vy * dt
            rx, ry = zx - px, zy - py
            self.tracks[tid] = (px + self.gain_x * rx, py + self.gain_x * ry,
                                vx + self.gain_v * rx / dt, vy + self.gain_v * ry / dt, t)
        for tid in [k for k, v in self.tracks.items() if t - v[4] > self.forget_s]:
            del self.tracks[tid]

    def speed(self, tid: str) -> float | None:
        """The target's estimated speed (m/s; None: no track)."""
        tr = self.tracks.get(tid)
        return None if tr is None else math.hypot(tr[2], tr[3])

    def predict(self, tid: str, ahead_s: float) -> Point | None:
        """The target's position ``ahead_s`` after its last update (None: no track)."""
        tr = self.tracks.get(tid)
        if tr is None:
            return None
        return (tr[0] + tr[2] * ahead_s, tr[1] + tr[3] * ahead_s)


def held_group(points: dict[str, Point], radius: float) -> tuple[Point, list[str]] | None:
    """The centroid of the largest group of at least two of ``points`` that all lie within
    ``radius`` of it, found by dropping the point farthest from the centroid until the rest
    fit; None when no two fit."""
    ids = sorted(points)
    while len(ids) >= 2:
        cx = sum(points[i][0] for i in ids) / len(ids)
        cy = sum(points[i][1] for i in ids) / len(ids)
        far = max(ids, key=lambda i: (math.hypot(points[i][0] - cx, points[i][1] - cy), i))
        if math.hypot(points[far][0] - cx, points[far][1] - cy) <= radius:
            return (cx, cy), ids
        ids.remove(far)
    return None
