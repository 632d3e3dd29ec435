"""The world's command inbox: a tick is answered once every robot's latest command is
stamped with it, counted per command (not a scan of the team per command), and a count
made wrong by a tick turning over mid-command is caught by the whole check."""

from __future__ import annotations

import time

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import DropCounter, WheelCommand, encode
from cekm_swarm.runtime.bridge import Received
from world.deadman import Deadman
from world.inbox import CommandInbox

ROBOTS = ["r1", "r2", "r3"]


def inbox() -> CommandInbox:
    return CommandInbox(ROBOTS, {K.cmd_wheels(r): r for r in ROBOTS}, DropCounter("test", keys=K),
                        Deadman(ROBOTS, 1.0, time.monotonic()))


def command(box: CommandInbox, robot: str, stamp: float) -> None:
    key = K.cmd_wheels(robot)
    box.on_command(Received(key, encode(WheelCommand(stamp, "motor", 0.1, 0.1, 1)), "put", "application/msgpack",
                            time.monotonic()))


def test_a_tick_is_answered_when_every_robot_answered_it_and_only_then():
    box, woken = inbox(), []
    box.wake = lambda: woken.append(box.now)
    box.opened(0.0)
    command(box, "r1", 0.0)
    command(box, "r1", 0.0)  # twice: still one robot
    command(box, "r2", 0.0)
    assert not box.answered() and not woken and box.waiting(0.0) == ["r3"]
    command(box, "r3", 0.0)
    assert box.answered() and woken == [0.0]
    box.opened(0.128)
    assert not box.answered()
    for r in ROBOTS:
        command(box, r, 0.0)  # late answers to the tick before: superseded, not this tick's
    assert not box.answered() and box.waiting(0.128) == ROBOTS
    for r in ROBOTS:
        command(box, r, 0.128)
    assert box.answered() and woken == [0.0, 0.128]


def test_a_robot_counted_for_the_wrong_tick_does_not_answer_it():
    box = inbox()
    box.opened(0.0)
    for r in ROBOTS:
        command(box, r, 0.0)
    box.opened(0.128)
    command(box, "r1", 0.128)
    command(box, "r2", 0.128)
    box._answered.add("r3")  # as when r3's command for tick 0 was counted just as tick 1 opened
    assert not box.answered()
    command(box, "r3", 0.128)
    assert box.answered() and box.commands() == {r: (0.1, 0.1) for r in ROBOTS}
