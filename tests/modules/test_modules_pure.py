"""The modules' pure parts compute exactly what the in-process runner computes, through
the wire format; malformed messages are dropped, counted and survived."""

import math

import msgpack
import numpy as np
import pytest

from cekm_swarm.controller.cooperative import CooperativeEKM
from cekm_swarm.controller.readings import TargetReading, range_readings
from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.experiments.navigation import make_brain
from cekm_swarm.modules import motor, obstacle, target
from cekm_swarm.modules.shell import process_one
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import SenseRange, SenseTarget, decode, encode
from cekm_swarm.runtime.bridge import Received
from world import World, load_scenario
from world.episode import Episode
from world.server import sense_messages


@pytest.fixture(scope="module")
def model():
    return default_model(progress=False)


def wire(key, msg):
    return decode(key, encode(msg))


def test_modules_over_the_wire_equal_the_in_process_brain(model):
    """Step lone_obstacle with the in-process brain; at every tick feed the same readings,
    as the world server's messages, through encode/decode and the three modules' pure parts
    (lockstep motor): the commands are equal to the bit, and so is the whole path."""
    world = World(load_scenario("lone_obstacle"))
    episode = Episode(world)
    brain = make_brain("cekm", model, {"body_radius": world.body_radius, "sensor_range": world.sensor_range})
    ekm = CooperativeEKM(model)
    state = motor.MotorState(motor.controller_integrate(ekm), lockstep=True)
    n = 0
    for _ in range(60):
        (rd,) = episode.readings()
        ranges = range_readings(rd.ranges, world.sensor_angles, world.body_radius)
        tr = TargetReading(*rd.target) if rd.target is not None else None
        expected = brain.tick(rd.t, tr, ranges)
        sent = []
        for key, msg in sense_messages(K, rd, world.sensor_angles, world.body_radius):
            msg = wire(key, msg)
            if isinstance(msg, SenseRange):
                f = obstacle.obstacle_field(ekm, msg, "r1/obstacle")
                sent += state.put(wire(K.field_obstacle("r1", f.index), f))
            else:
                f = target.target_field(ekm, msg, "r1/target")
                sent += state.put(wire(K.field_target("r1"), f))
        assert len(sent) == 1 and sent[0][0] == rd.t
        assert sent[0][1:] == expected
        n += expected != (0.0, 0.0)
        episode.apply({"r1": expected})
        episode.advance()
    assert n > 50  # the robot was actually driving


def test_out_of_range_target_is_no_target(model):
    ekm = CooperativeEKM(model)
    f = target.target_field(ekm, SenseTarget(0.0, "world", 0.0, 0.0, False), "r1/target")
    assert f.winner is None and f.a is None and f.alpha is None and not f.at_goal
    in_process = ekm.localize_target(TargetReading(math.nan, math.nan, False), 0.0)
    assert in_process.a is None and in_process.winner is None


def test_goal_state_field(model):
    ekm = CooperativeEKM(model)
    f = target.target_field(ekm, SenseTarget(1.0, "world", 0.0, 0.0, True), "r1/target")
    assert f.at_goal and f.a is None
    out = motor.controller_integrate(ekm)(f, [])
    assert out == (0.0, 0.0)


def rec(key, payload):
    return Received(key, payload, "put", "application/msgpack", 0.0)


@pytest.mark.parametrize("payload", [
    b"\xc1garbage",
    msgpack.packb({"v": 99, "kind": "sense/range", "stamp": 0.0, "sender": "w", "index": 0, "alpha": 0.0, "d": None}),
    msgpack.packb([1, 2, 3]),
    msgpack.packb({"v": 1, "kind": "sense/range", "stamp": 0.0, "sender": "w", "index": 0, "alpha": 0.0}),
])
def test_malformed_message_is_dropped_counted_and_survived(model, payload):
    spec = obstacle.build_spec(CooperativeEKM(model), "r1", 0)
    key = K.sense_range("r1", 0)
    assert process_one(spec, rec(key, payload)) == []
    assert spec.drops.count(key) == 1
    good = encode(SenseRange(0.128, "world", 0, 0.0, 0.1))
    (out,) = process_one(spec, rec(key, good))
    assert out[0] == K.field_obstacle("r1", 0) and out[1].winner is not None
    assert spec.drops.total == 1


def test_motor_survives_a_malformed_field_and_a_wrong_index(model):
    spec = motor.build_spec(motor.controller_integrate(CooperativeEKM(model)), "r1")
    key = K.field_obstacle("r1", 2)
    bad = encode(obstacle.ObstacleField(0.0, "x", 3, None, None))  # payload index 3 on key 2
    assert process_one(spec, rec(key, bad)) == []
    assert process_one(spec, rec(key, b"")) == []
    assert spec.drops.count(key) == 2
    good = encode(obstacle.ObstacleField(0.0, "x", 2, None, None))
    (out,) = process_one(spec, rec(key, good))
    assert out[0] == K.cmd_wheels("r1") and (out[1].v_l, out[1].v_r) == (0.0, 0.0)


def test_a_handler_error_counts_as_a_drop():
    from cekm_swarm.modules.shell import ModuleSpec

    def boom(msg, r):
        raise ValueError("boom")

    spec = ModuleSpec("target", "r1", K.sense_target("r1"), boom)
    key = K.sense_target("r1")
    assert process_one(spec, rec(key, encode(SenseTarget(0.0, "world", 0.1, 0.2, True)))) == []
    assert spec.drops.count(key) == 1 and "boom" in spec.drops.records()[0].first_reason
