"""The world server's sense encoder publishes the bytes of ``encode(sense_messages(...))``."""

import math

import numpy as np
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import MessageError, encode
from world import World, load_scenario
from world.episode import Episode
from world.sense import SenseEncoder, TickReadings, sense_messages


def general(world, rd):
    return [(k, encode(m)) for k, m in sense_messages(K, rd, world.sensor_angles, world.body_radius)]


@pytest.mark.parametrize("scenario", ["crossing", "lone_obstacle", "concave"])
def test_every_tick_of_a_run_encodes_as_the_general_path(scenario):
    world = World(load_scenario(scenario))
    episode = Episode(world)
    encoders = {}
    rng = np.random.default_rng(1)
    seen = targets = 0
    for _ in range(80):
        for rd in episode.readings():
            enc = encoders.setdefault(rd.robot, SenseEncoder(K, rd.robot, world.sensor_angles, world.body_radius))
            assert enc(rd) == general(world, rd)
            seen += int(np.isfinite(rd.ranges).sum())
            targets += rd.target is not None
        episode.apply({r: (float(rng.uniform(0, 0.2)), float(rng.uniform(0, 0.2))) for r in encoders})
        episode.advance()
    assert seen > 0 and targets > 0  # obstacles were in range and targets were sensed


def test_edge_readings_encode_as_the_general_path_or_fail_as_it_does():
    world = World(load_scenario("lone_obstacle"))
    enc = SenseEncoder(K, "r1", world.sensor_angles, world.body_radius)
    ranges = np.full(12, np.nan)
    ranges[3] = 0.0
    ranges[4] = 0.25
    for target in (
        None,
        (0.0, 0.0, True),
        (math.pi, 1.0, True),
        (-math.pi, 1e-9, True),
        (0.3, 1.0, False),
        (math.nan, 1.0, True),
        (np.float64(0.5), np.float64(2.0), np.bool_(True)),
        (math.pi + 5e-10, 1.0, True),
    ):
        rd = TickReadings("r1", 1.536, ranges, target)
        assert enc(rd) == general(world, rd), target
    bad = ranges.copy()
    bad[0] = -1.0  # a negative distance from the robot's centre: refused either way
    with pytest.raises(MessageError, match="'d'"):
        enc(TickReadings("r1", 1.536, bad, None))
    with pytest.raises(MessageError, match="'d'"):
        general(world, TickReadings("r1", 1.536, bad, None))
