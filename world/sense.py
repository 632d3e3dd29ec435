"""The world's sense messages of one robot's readings at one tick (what the world server
publishes): a range reading's ``d`` is the obstacle input u_j, the distance from the
robot's centre (surface range + body radius), None when nothing is in range; an
out-of-range target is sent as alpha = d = 0, visible False. :func:`sense_messages`
builds them as messages; :class:`SenseEncoder` gives their wire bytes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cekm_swarm.protocol import KeySpace, SenseRange, SenseTarget, encode
from cekm_swarm.robot import centre_distance


@dataclass
class TickReadings:
    """What one robot's modules receive at a tick."""

    robot: str
    t: float
    ranges: np.ndarray  # (12,) surface ranges, NaN = nothing seen
    target: tuple[float, float, bool] | None  # (alpha, d, visible), None when not due


SENDER = "world"
"""The sender of every message the world publishes."""


_KEYS: dict[tuple[KeySpace, str, int], tuple[list[str], str]] = {}


def _sense_keys(keys: KeySpace, robot: str, n: int) -> tuple[list[str], str]:
    """The robot's range keys and target key (built once: building a key validates it)."""
    hit = _KEYS.get((keys, robot, n))
    if hit is None:
        if len(_KEYS) > 4096:
            _KEYS.clear()
        hit = _KEYS[(keys, robot, n)] = ([keys.sense_range(robot, j) for j in range(n)], keys.sense_target(robot))
    return hit


def sense_messages(keys: KeySpace, rd: TickReadings, sensor_angles: Sequence[float] | np.ndarray,
                   body_radius: float) -> list[tuple[str, Any]]:
    """The sense messages of one robot's readings at one tick: 12 ranges (+ the target)."""
    out: list[tuple[str, Any]] = []
    t = rd.t
    range_keys, target_key = _sense_keys(keys, rd.robot, len(rd.ranges))
    for j, r in enumerate(rd.ranges):
        d = centre_distance(float(r), body_radius)
        out.append((range_keys[j], SenseRange(t, SENDER, j, float(sensor_angles[j]), d)))
    if rd.target is not None:
        out.append((target_key, target_message(t, rd.target)))
    return out


class SenseEncoder:
    """The wire bytes of one robot's sense messages: ``encoder(rd)`` equals ``[(key,
    encode(msg)) for key, msg in sense_messages(...)]`` (tested), with the robot's keys
    and sensor directions taken once."""

    def __init__(self, keys: KeySpace, robot: str, sensor_angles: Sequence[float], body_radius: float) -> None:
        self.keys, self.radius = keys, body_radius
        self.angles = [float(a) for a in sensor_angles]
        self.range_keys = [keys.sense_range(robot, j) for j in range(len(self.angles))]
        self.target_key = keys.sense_target(robot)

    def __call__(self, rd: TickReadings, leave_out: frozenset[str] | set[str] = frozenset()
                 ) -> list[tuple[str, bytes]]:
        """The readings' (key, bytes), but for the keys in ``leave_out``."""
        return self.encode(rd.t, self.contents(rd), leave_out)

    def encode(self, t: float, contents: list[tuple[str, Any]], leave_out: frozenset[str] | set[str] = frozenset()
               ) -> list[tuple[str, bytes]]:
        """The (key, bytes) at sim time ``t`` of readings already taken apart by
        :meth:`contents` (the world compares them for held readings, then sends them),
        but for the keys in ``leave_out``."""
        angles, n = self.angles, len(self.angles)
        out = []
        for j, (key, c) in enumerate(contents):
            if key in leave_out:
                continue
            if j < n:
                out.append((key, encode(SenseRange(t, SENDER, j, angles[j], c))))
            else:  # the target: (alpha, d, visible), already as target_message sends it
                out.append((key, encode(SenseTarget(t, SENDER, c[0], c[1], c[2]))))
        return out

    def contents(self, rd: TickReadings) -> list[tuple[str, Any]]:
        """Each reading's key and what it says but its stamp (a range's ``d``, the target's
        ``(alpha, d, visible)``): what "unchanged" compares."""
        radius = self.radius
        ranges = rd.ranges.tolist() if type(rd.ranges) is np.ndarray else [float(r) for r in rd.ranges]
        out: list[tuple[str, Any]] = [(self.range_keys[j], centre_distance(r, radius)) for j, r in enumerate(ranges)]
        if rd.target is not None:
            m = target_message(0.0, rd.target)
            out.append((self.target_key, (m.alpha, m.d, m.visible)))
        return out


def target_message(t: float, target: tuple[float, float, bool]) -> SenseTarget:
    """The target reading (alpha, d, visible) as a message; not visible (or not finite) is
    sent as alpha = d = 0, visible False."""
    alpha, d, visible = target
    if not (visible and math.isfinite(alpha) and math.isfinite(d)):
        return SenseTarget(t, SENDER, 0.0, 0.0, False)
    return SenseTarget(t, SENDER, float(alpha), float(d), True)
