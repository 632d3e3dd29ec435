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
from cekm_swarm.modules.shell import process_one, respond
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import SenseRange, SenseTarget, decode, encode
from cekm_swarm.runtime.bridge import Received
from world import World, load_scenario
from world.episode import Episode
from world.sense import sense_messages


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


@pytest.mark.parametrize("payload", [
    b"\xc1garbage",
    msgpack.packb({"v": 99, "kind": "sense/range", "stamp": 0.0, "sender": "w", "index": 0, "alpha": 0.0, "d": None}),
    msgpack.packb([1, 2, 3]),
    msgpack.packb({"v": 1, "kind": "sense/range", "stamp": 0.0, "sender": "w", "index": 0, "alpha": 0.0}),
    msgpack.packb({"v": 1, "kind": "sense/range", "stamp": 0.0, "sender": "w", "index": 1, "alpha": 0.0, "d": 0.2}),
])
def test_a_malformed_message_passes_the_fast_path_by_and_is_dropped_and_counted(model, payload):
    spec = obstacle.build_spec(CooperativeEKM(model), "r1", 0)
    key = K.sense_range("r1", 0)
    assert spec.fast(key, payload) is None
    assert respond(spec, key, payload) == []
    assert spec.drops.count(key) == 1


def test_obstacle_fast_path_sends_the_bytes_of_the_general_path(model):
    """Every reading of a lone_obstacle run and of a sweep of ranges and directions (the
    world's 5 mm steps and arbitrary floats, nothing seen, integer-valued stamps the fast
    path leaves to the general one): the published bytes are those of the general path."""
    ekm = CooperativeEKM(model)
    world = World(load_scenario("lone_obstacle"))
    episode = Episode(world)
    payloads = {}
    for _ in range(40):
        (rd,) = episode.readings()
        for key, msg in sense_messages(K, rd, world.sensor_angles, world.body_radius):
            if isinstance(msg, SenseRange):
                payloads.setdefault(msg.index, []).append(encode(msg))
        episode.apply({"r1": (0.1, 0.12)})
        episode.advance()
    rng = np.random.default_rng(3)
    for j in (0, 5, 11):
        for k in range(40, 250):  # stamps go on from the run's (a module drops a stamp far from its newest)
            d = None if k % 10 == 0 else float(rng.choice([round(rng.uniform(0.05, 0.6), 3), rng.uniform(0.05, 0.6)]))
            payloads[j].append(encode(SenseRange(round(k * 0.128, 9), "world", j, float(rng.uniform(-3, 3)), d)))
        payloads[j].append(msgpack.packb({"v": 1, "kind": "sense/range", "stamp": 32, "sender": "world", "index": j,
                                          "alpha": 0.5, "d": 0.25}))
    taken = 0
    for j, msgs in payloads.items():
        fast = obstacle.build_spec(ekm, "r1", j)
        slow = obstacle.build_spec(ekm, "r1", j)
        slow.fast = None
        key = K.sense_range("r1", j)
        for p in msgs:
            taken += fast.fast(key, p) is not None
            assert respond(fast, key, p) == respond(slow, key, p)
        assert fast.drops.total == 0
    assert taken == sum(map(len, payloads.values())) - 3  # all but the integer stamps took the fast path


def test_target_fast_path_sends_the_bytes_of_the_general_path(model):
    """Target readings over the sensing range, out of range, at the goal (d = 0) and one
    with an integer stamp: the fast path takes the visible ones short of the goal, and the
    published bytes are the general path's in every case."""
    ekm = CooperativeEKM(model)
    fast = target.build_spec(ekm, "r1")
    slow = target.build_spec(ekm, "r1")
    slow.fast = None
    key = K.sense_target("r1")
    rng = np.random.default_rng(5)
    payloads = [encode(SenseTarget(round(k * 0.256, 9), "world", float(rng.uniform(-math.pi, math.pi)),
                                   float(rng.choice([rng.uniform(0.01, 3.0), round(rng.uniform(0.01, 3.0), 3)])), True))
                for k in range(313)]
    odd = [encode(SenseTarget(80.0, "world", 0.0, 0.0, False)), encode(SenseTarget(80.0, "world", 0.3, 0.0, True)),
           msgpack.packb({"v": 1, "kind": "sense/target", "stamp": 80, "sender": "world", "alpha": 0.5, "d": 1.0,
                          "visible": True})]
    for p in payloads + odd:
        assert respond(fast, key, p) == respond(slow, key, p)
    assert fast.drops.total == 0
    fresh = target.build_spec(ekm, "r1")
    assert all(fresh.fast(key, p) is not None for p in payloads)
    assert all(fresh.fast(key, p) is None for p in odd)


@pytest.mark.parametrize("lockstep,integrate_on", [(True, "tick"), (False, "tick"), (False, "every")],
                         ids=["lockstep", "realtime-tick", "realtime-every"])
def test_motor_fast_path_sends_the_bytes_of_the_general_path(model, lockstep, integrate_on):
    """The fields of a lone_obstacle run (from the obstacle and target modules), fed to a
    motor module with and to one without its fast path: the same commands, byte for byte."""
    ekm = CooperativeEKM(model)
    world = World(load_scenario("lone_obstacle"))
    episode = Episode(world)
    integrate = motor.controller_integrate(ekm)
    fast = motor.build_spec(integrate, "r1", lockstep=lockstep, integrate_on=integrate_on)
    slow = motor.build_spec(integrate, "r1", lockstep=lockstep, integrate_on=integrate_on)
    slow.fast = None
    took = [0]
    inner = fast.fast

    def counted(key, payload):
        out = inner(key, payload)
        took[0] += out is not None
        return out

    fast.fast = counted
    obs = {j: obstacle.build_spec(ekm, "r1", j) for j in range(12)}
    tgt = target.build_spec(ekm, "r1")
    sent = n_fields = 0
    for _ in range(60):
        (rd,) = episode.readings()
        fields = []
        for key, msg in sense_messages(K, rd, world.sensor_angles, world.body_radius):
            spec = obs[msg.index] if isinstance(msg, SenseRange) else tgt
            fields += respond(spec, key, encode(msg))
        command = None
        n_fields += len(fields)
        for key, payload in fields:
            out = respond(fast, key, payload)
            assert out == respond(slow, key, payload)
            if out:
                command = decode(out[-1][0], out[-1][1])
                sent += 1
        assert fast.drops.total == 0
        assert command is not None
        episode.apply({"r1": (command.v_l, command.v_r)})
        episode.advance()
    assert sent == (60 * 12 + 30 if integrate_on == "every" else 60)  # one command a tick, or one a field
    assert took[0] == n_fields  # every field of the run took the fast path


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


def test_motor_drops_a_field_that_does_not_fit_the_lattice(model):
    """A well-formed field with a vector of another length is dropped and counted, on the
    fast and the general path alike, and never reaches Eq. 9."""
    n = model.w.shape[0]
    spec = motor.build_spec(motor.controller_integrate(CooperativeEKM(model)), "r1", lockstep=True, neurons=n)
    for j, length in enumerate([n + 1, n - 1, 10]):
        key = K.field_obstacle("r1", j)
        payload = encode(obstacle.ObstacleField(0.128, "x", j, 3, np.ones(length)))
        assert respond(spec, key, payload) == []
        assert spec.drops.count(key) == 1, spec.drops.records()
    assert spec.state.pending == {}
