"""The world's odometry (world.odometry; docs/learning.md): every 8 ticks the motor
controller's record of the last 16 ticks, the speeds it held, the wheel encoders' travel
with the plant's slip noise, and the stall signal; never the pose."""

from __future__ import annotations

import numpy as np

from cekm_swarm.protocol import DEFAULT_KEYS, decode, encode
from cekm_swarm.ticks import ODOMETRY_EVERY, TICK_S
from world import World, load_scenario
from world.episode import Episode
from world.odometry import KEY
from world.sim import WHEEL_NOISE


def drive(episode: Episode, ticks: int, command) -> list:
    sent = []
    for _ in range(ticks):
        episode.readings()
        sent += [(episode.tick, m) for rel, m in episode.messages("r1") if rel == KEY]
        episode.apply({"r1": command})
        episode.advance()
    return sent


def test_every_8_ticks_the_record_of_the_last_16_ticks():
    ep = Episode(World(load_scenario("lone_obstacle"), seed=1))
    sent = drive(ep, 33, (0.04, 0.05))
    assert [k for k, _ in sent] == [0, 8, 16, 24, 32]
    assert sent[0][1].ticks == ()  # nothing travelled yet
    assert sent[1][1].ticks == tuple(range(1, 9)) and sent[4][1].ticks == tuple(range(17, 33))
    last = sent[-1][1]
    assert set(last.set_l) == {0.04} and set(last.set_r) == {0.05}  # the speeds held over each tick
    # each wheel's travel: the held speed times a tick, within the slip noise (per sub-step)
    assert all(abs(x - 0.04 * TICK_S) <= WHEEL_NOISE * 0.04 * TICK_S + 1e-12 for x in last.left)
    assert all(abs(x - 0.05 * TICK_S) <= WHEEL_NOISE * 0.05 * TICK_S + 1e-12 for x in last.right)
    assert len(set(last.left)) > 1  # noisy, not the command
    assert not any(last.blocked)
    assert decode(DEFAULT_KEYS.node_key("r1", KEY), encode(last)) == last
    assert last.stamp == 32 * TICK_S and ODOMETRY_EVERY == 8


def test_a_robot_pushing_against_a_wall_is_blocked_while_its_wheels_turn():
    sc = load_scenario("lone_obstacle")
    ep = Episode(World(sc, seed=1))
    sent = drive(ep, 8 * 12, (-0.08, -0.08))  # backwards into the wall 0.5 m behind
    last = sent[-1][1]
    assert all(last.blocked) and all(x < 0 for x in last.left)  # the encoders count, the body is stopped
    x, _, _ = ep.world.pose("r1")
    assert x < 0.1 and np.isfinite(x)
