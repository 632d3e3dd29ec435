"""Teleop: ROS 2 ``geometry_msgs/msg/Twist`` messages on ``/<robot>/cmd_vel`` become the
robot's wheel command ``cekm/<robot>/cmd/wheels``, the world's only way to move a robot.

A Twist goes through the same kind of checks as every message of the protocol
(:func:`twist_command`): the payload must be exactly a little- or big-endian CDR Twist
(52 bytes), all six numbers finite, and the wheel speeds of the differential drive
(v_l = v - omega * axle / 2, v_r = v + omega * axle / 2, the inverse of docs/design.md
section 2) within c* = +-v*, or it is **refused** (dropped and counted by reason), never
clipped: a teleop asking for 0.5 m/s gets no motion rather than a different one. The
linear y, z and angular x, y a differential drive cannot follow are ignored.

The world believes a command only when its stamp is a tick's sim time no later than its
clock and at most 8 ticks older (:mod:`cekm_swarm.protocol.stamps`). :class:`Teleop`
stamps each command with the newest tick of ``cekm/world/clock`` it has seen and sends at
most one command per robot per tick: the first Twist of a tick at once, a later one at the
next tick (if it is younger than :data:`HOLD_S` by then). Nothing is repeated: when the
Twists stop, the commands stop, and the world's dead-man stops the robot
(``world/deadman.py``: 0.5 s without a command in a real-time run).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cekm_swarm.protocol import WheelCommand
from cekm_swarm.robot import KHEPERA, Khepera

from .interfaces import Interfaces

TWIST = "geometry_msgs/msg/Twist"
TWIST_CDR_BYTES = 4 + 6 * 8
"""A CDR Twist: the encapsulation header, then six float64 (no padding)."""
_HEADERS = (b"\x00\x01", b"\x00\x00")  # CDR little-endian, CDR big-endian
HOLD_S = 0.5
"""Wall seconds a Twist that came during an answered tick may wait for the next tick."""

NOT_TWIST, NOT_FINITE, OUT_OF_RANGE, NO_CLOCK = "not a CDR Twist", "not finite", "out of range", "no world clock yet"
REASONS = (NOT_TWIST, NOT_FINITE, OUT_OF_RANGE, NO_CLOCK)
"""Why a Twist is refused (the keys of the bridge's drop counts)."""


class TwistRefused(ValueError):
    """A Twist that does not become a command; ``reason`` is one of :data:`REASONS`."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


def wheel_speeds(v: float, omega: float, robot: Khepera = KHEPERA) -> tuple[float, float]:
    """(v_l, v_r) of the differential drive for forward speed ``v`` (m/s) and turn rate
    ``omega`` (rad/s); :class:`TwistRefused` when a wheel would exceed v*."""
    half = omega * robot.axle / 2
    v_l, v_r = v - half, v + half
    limit = robot.v_max * (1 + 1e-9)
    if not (abs(v_l) <= limit and abs(v_r) <= limit):
        raise TwistRefused(OUT_OF_RANGE, f"v {v:g} m/s, omega {omega:g} rad/s need wheels ({v_l:.4g}, {v_r:.4g}) m/s, "
                                         f"beyond +-{robot.v_max:g} m/s")
    return v_l, v_r


def twist_command(ifc: Interfaces, payload: bytes, robot: Khepera = KHEPERA) -> tuple[float, float]:
    """The wheel speeds (v_l, v_r) a Twist's CDR ``payload`` asks for, or :class:`TwistRefused`."""
    if len(payload) != TWIST_CDR_BYTES or payload[:2] not in _HEADERS:
        raise TwistRefused(NOT_TWIST, f"{len(payload)} bytes starting {payload[:4].hex() or 'with nothing'}, "
                                      f"expected {TWIST_CDR_BYTES} bytes of CDR")
    try:
        msg = ifc.from_cdr(payload, TWIST)
    except Exception as exc:  # rosbags raises its SerdeError (and struct errors) on bytes it cannot read
        raise TwistRefused(NOT_TWIST, str(exc)) from None
    values = (msg.linear.x, msg.linear.y, msg.linear.z, msg.angular.x, msg.angular.y, msg.angular.z)
    if not all(math.isfinite(x) for x in values):
        raise TwistRefused(NOT_FINITE, f"linear ({values[0]}, {values[1]}, {values[2]}), angular ({values[3]}, "
                                       f"{values[4]}, {values[5]})")
    return wheel_speeds(float(msg.linear.x), float(msg.angular.z), robot)


@dataclass
class _Pending:
    v_l: float
    v_r: float
    at: float


class Teleop:
    """One teleoperated robot: turns its accepted Twists into stamped wheel commands (see
    the module's docstring). ``on_clock`` and ``on_twist`` return the command to publish
    on ``cekm/<robot>/cmd/wheels``, or None."""

    def __init__(self, robot: str, hold: float = HOLD_S) -> None:
        self.robot = robot
        self.sender = f"{robot}/ros2-teleop"
        self.hold = hold
        self.now: float | None = None  # the newest tick's sim time seen on cekm/world/clock
        self.sent_for: float | None = None  # the tick of the last command sent
        self.pending: _Pending | None = None
        self.seq = 0
        self.sent = 0

    def _send(self, v_l: float, v_r: float) -> WheelCommand:
        assert self.now is not None
        self.sent_for = self.now
        self.seq += 1
        self.sent += 1
        return WheelCommand(self.now, self.sender, v_l, v_r, self.seq)

    def on_clock(self, stamp: float, wall: float) -> WheelCommand | None:
        """A world clock message for the tick at sim time ``stamp`` (received at ``wall``, monotonic s)."""
        if self.now is not None and stamp <= self.now:
            return None
        self.now = stamp
        p, self.pending = self.pending, None
        if p is not None and wall - p.at <= self.hold:
            return self._send(p.v_l, p.v_r)
        return None

    def on_twist(self, v_l: float, v_r: float, wall: float) -> WheelCommand | None:
        """An accepted Twist's wheel speeds (received at ``wall``); :class:`TwistRefused`
        (``no world clock yet``) before the first clock message."""
        if self.now is None:
            raise TwistRefused(NO_CLOCK, "the world's clock (cekm/world/clock) has not been seen yet")
        if self.sent_for == self.now:
            self.pending = _Pending(v_l, v_r, wall)
            return None
        return self._send(v_l, v_r)
