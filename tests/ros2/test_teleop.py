"""Teleop's pure parts: a Twist's checks, the differential drive, and the stamping of the
commands on the world's tick grid."""

import math
import struct

import pytest

from cekm_swarm.protocol import WheelCommand, decode, encode
from cekm_swarm.protocol.stamps import stamp_problem
from cekm_swarm.robot import KHEPERA
from cekm_swarm.ros2.interfaces import interfaces
from cekm_swarm.ros2.teleop import (
    NO_CLOCK,
    NOT_FINITE,
    NOT_TWIST,
    OUT_OF_RANGE,
    TWIST_CDR_BYTES,
    Teleop,
    TwistRefused,
    twist_command,
    wheel_speeds,
)
from cekm_swarm.ticks import tick_time

IFC = interfaces()


def twist_cdr(vx=0.0, vy=0.0, vz=0.0, wx=0.0, wy=0.0, wz=0.0, big_endian=False) -> bytes:
    if big_endian:
        return b"\x00\x00\x00\x00" + struct.pack(">6d", vx, vy, vz, wx, wy, wz)
    v = lambda x, y, z: IFC.make("geometry_msgs/msg/Vector3", x=x, y=y, z=z)  # noqa: E731
    return IFC.cdr(IFC.make("geometry_msgs/msg/Twist", linear=v(vx, vy, vz), angular=v(wx, wy, wz)),
                   "geometry_msgs/msg/Twist")


def refused(payload: bytes) -> str:
    with pytest.raises(TwistRefused) as info:
        twist_command(IFC, payload)
    return info.value.reason


def test_the_differential_drive_both_ways():
    v_l, v_r = wheel_speeds(0.1, 0.5)
    assert (v_l, v_r) == (0.1 - 0.5 * KHEPERA.axle / 2, 0.1 + 0.5 * KHEPERA.axle / 2)
    assert (v_l + v_r) / 2 == pytest.approx(0.1) and (v_r - v_l) / KHEPERA.axle == pytest.approx(0.5)
    assert wheel_speeds(KHEPERA.v_max, 0.0) == (KHEPERA.v_max, KHEPERA.v_max)  # c* itself is in range
    assert wheel_speeds(0.0, -2 * KHEPERA.v_max / KHEPERA.axle) == pytest.approx((KHEPERA.v_max, -KHEPERA.v_max))
    for v, w in ((0.16, 0.0), (0.0, 6.0), (-0.5, 0.0), (0.15, 0.3)):
        with pytest.raises(TwistRefused, match="beyond"):
            wheel_speeds(v, w)


def test_a_twist_is_taken_only_when_it_is_a_finite_in_range_cdr_twist():
    assert len(twist_cdr()) == TWIST_CDR_BYTES
    assert twist_command(IFC, twist_cdr(0.1, wz=0.5)) == wheel_speeds(0.1, 0.5)
    assert twist_command(IFC, twist_cdr(0.1, vy=3.0, wx=1.0)) == (0.1, 0.1)  # what a diff drive cannot do is ignored
    assert twist_command(IFC, twist_cdr(0.1, wz=0.5, big_endian=True)) == wheel_speeds(0.1, 0.5)
    for bad in (twist_cdr(math.nan), twist_cdr(wz=math.inf), twist_cdr(vz=-math.inf)):
        assert refused(bad) == NOT_FINITE
    for bad in (twist_cdr(1e300), twist_cdr(0.5), twist_cdr(wz=100.0), twist_cdr(-1e-300 - 0.2)):
        assert refused(bad) == OUT_OF_RANGE
    string = IFC.cdr(IFC.make("std_msgs/msg/String", data="forward"), "std_msgs/msg/String")  # another type
    for bad in (b"", b"\x00", twist_cdr()[:-1], twist_cdr() + b"\x00", b"\x07\x07" + twist_cdr()[2:], string):
        assert refused(bad) == NOT_TWIST


def test_commands_are_stamped_with_the_world_clock_once_per_tick():
    t = Teleop("r1")
    with pytest.raises(TwistRefused) as info:
        t.on_twist(0.1, 0.1, wall=0.0)
    assert info.value.reason == NO_CLOCK
    assert t.on_clock(tick_time(5), wall=0.0) is None  # nothing waiting
    first = t.on_twist(0.1, 0.12, wall=0.01)
    assert isinstance(first, WheelCommand) and (first.stamp, first.v_l, first.v_r, first.seq) == (
        tick_time(5),
        0.1,
        0.12,
        1,
    )
    assert decode("cekm/r1/cmd/wheels", encode(first)) == first
    assert t.on_twist(0.05, 0.05, wall=0.02) is None and t.on_twist(0.07, 0.07, wall=0.03) is None  # same tick: held
    nxt = t.on_clock(tick_time(6), wall=0.13)
    assert (nxt.stamp, nxt.v_l, nxt.seq) == (tick_time(6), 0.07, 2)  # the latest held one, at the next tick
    assert t.on_clock(tick_time(6), wall=0.2) is None and t.on_clock(tick_time(4), wall=0.2) is None  # not new
    assert t.on_twist(0.1, 0.1, wall=0.3) is None  # tick 6 already answered
    assert t.on_clock(tick_time(7), wall=0.3 + t.hold + 0.01) is None  # held too long: dropped, not sent
    # what the world's check of a command requires: a tick's time, not ahead of its clock
    for c in (first, nxt):
        assert stamp_problem(c.stamp, c.stamp, 8 * 0.128, 0.0) is None
