"""The tracking target module and the tracking motor as pure functions (no Zenoh):
lockstep waits for exactly the shares the in-process runner uses, a dropped teammate
unblocks the tick, and the module + motor path equals ``TrackingRobot`` to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from cekm_swarm.controller.readings import range_readings
from cekm_swarm.controller.team import TeamView
from cekm_swarm.controller.tracking import TrackingRobot
from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.modules.motor import MotorState, tracking_integrate
from cekm_swarm.modules.tracking import TrackingModuleState, tracking_ekm
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import (MessageError, ObstacleField, SensePose, SenseTargets, Share, TrackingField, decode,
                                 encode)
from world import World, load_scenario
from world.tracking import tracking_sense


@pytest.fixture(scope="module")
def model():
    return default_model(progress=False)


def brain(model, robot="r1"):
    return TrackingRobot(robot, tracking_ekm(model, robot, 0.5), TeamView(robot))


def sense(t, pose=(1.0, 1.0, 0.0), targets=None):
    return SensePose(t, "world", pose), SenseTargets(t, "world", targets or {"t1": (0.3, 0.4)})


def share(robot, t, xy=(1.3, 1.0)):
    return Share(t, robot, (xy[0], xy[1], 0.0), {"t1": (1.2, 1.3)})


def test_tracking_field_round_trips_and_refuses_bad_fields():
    m = TrackingField(0.256, "r1/target", np.arange(4.0), np.zeros(4), ((1, 0.5, 0.2, 1.0),), {"t1": 0.25}, True)
    assert decode(K.field_tracking("r1"), encode(m)) == m
    with pytest.raises(MessageError, match="inputs\\[0\\].winner"):
        TrackingField(0.0, "r1/target", np.ones(4), np.ones(4), ((4, 0.0, 0.0, 1.0),), {}, False)
    with pytest.raises(MessageError, match="b"):
        TrackingField(0.0, "r1/target", np.ones(4), np.ones(3), (), {}, False)
    with pytest.raises(MessageError, match="alpha"):
        TrackingField(0.0, "r1/target", np.ones(4), np.ones(4), ((0, 4.0, 0.0, 1.0),), {}, False)
    with pytest.raises(MessageError, match="weights"):
        TrackingField(0.0, "r1/target", np.ones(4), np.ones(4), (), {"t1": float("nan")}, False)


def test_lockstep_waits_for_every_live_teammates_previous_share(model):
    st = TrackingModuleState(brain(model), ("r1", "r2", "r3"), lockstep=True)
    p, q = sense(0.0)
    assert st.put(p) == []
    out = st.put(q)  # tick 0: no share to wait for
    assert [k for k, _ in out] == [K.field_tracking("r1"), K.share("r1")]
    p, q = sense(0.256)
    st.put(p)
    assert st.put(q) == []  # waits for r2's and r3's shares of tick 0
    assert st.put(share("r2", 0.256)) == []  # an early share of this tick does not count
    assert st.put(share("r2", 0.0)) == []
    out = st.put(share("r3", 0.0))
    assert [k for k, _ in out] == [K.field_tracking("r1"), K.share("r1")]
    assert set(st.brain.view.shares) == {"r2", "r3"} and st.brain.view.shares["r2"].stamp == 0.0
    assert [s.stamp for s in st.pending["r2"]] == [0.256]  # kept for the next tick


def test_a_republished_tick_is_answered_again_and_a_restart_waits_for_no_share(model):
    st = TrackingModuleState(brain(model), ("r1", "r2"), lockstep=True)
    p, q = sense(0.512)  # a (re)started module: its first tick waits for no share
    st.put(p)
    first = st.put(q)
    assert [k for k, _ in first] == [K.field_tracking("r1"), K.share("r1")]
    again = st.put(p)
    assert again == [(K.field_tracking("r1"), first[0][1])]
    p, q = sense(0.768)
    st.put(p)
    assert st.put(q) == []  # from now on it waits for r2's share of 0.512


def test_a_dropped_teammate_unblocks_the_tick_and_leaves_the_fields(model):
    st = TrackingModuleState(brain(model), ("r1", "r2", "r3"), lockstep=True)
    st.put(sense(0.0)[0])
    st.put(sense(0.0)[1])
    st.put(share("r2", 0.0))
    st.put(share("r3", 0.0))
    p, q = sense(0.256)
    st.put(p)
    st.put(q)
    st.put(share("r2", 0.256))
    p, q = sense(0.512)
    st.put(p)
    assert st.put(q) == []  # r3's share of 0.256 is missing
    out = st.teammate_alive("r3", False)
    assert [k for k, _ in out] == [K.field_tracking("r1"), K.share("r1")]
    assert "r3" not in st.brain.view.shares and st.drops[-1]["dropped"] == "r3"
    assert st.put(share("r3", 0.512)) == [] and st.ignored_shares == 1


def test_module_and_motor_equal_the_in_process_robot_to_the_bit(model):
    """Two robots of tracking.toml for a few seconds: the ref robots as the in-process
    runner drives them, the module states and motor states fed the decoded messages."""
    sc = load_scenario("tracking")
    world = World(sc, seed=5)
    robots = list(world.robot_ids)
    ref = {r: brain(model, r) for r in robots}
    mods = {r: TrackingModuleState(brain(model, r), tuple(robots), lockstep=True) for r in robots}
    motors = {r: MotorState(tracking_integrate(mods[r].brain.controller), lockstep=True) for r in robots}
    angles, body = world.sensor_angles, world.body_radius
    wire = []  # shares in flight between the modules
    for tick in range(40):
        t = round(tick * 0.128, 9)
        due = tick % 2 == 0
        cmds, shares = {}, {}
        for r in robots:
            ranges = range_readings(world.range_readings(r), angles, body)
            ref[r].on_ranges(t, ranges)
            if due:
                pm, tm = tracking_sense(world, r, t)
                shares[r] = ref[r].on_sense(pm, tm)
                for key, msg in mods[r].put(pm) + mods[r].put(tm):
                    msg = decode(key, encode(msg))
                    if isinstance(msg, TrackingField):
                        motors[r].put(msg)
                    else:
                        wire.append(msg)
            want = ref[r].command()
            obs = ref[r].controller.ekm.localize_obstacles(ranges, t)
            got = []
            for ob in obs:
                got += motors[r].put(ObstacleField(t, f"{r}/obstacle-{ob.index}", ob.index, ob.winner, ob.b))
            assert got == [(t, *want)], (r, t)
            cmds[r] = want
        for sender, msg in shares.items():
            for r in robots:
                if r != sender:
                    ref[r].receive(sender, msg)
        for msg in wire:  # delivered after every robot computed, in any order
            for r in reversed(robots):
                mods[r].put(msg, msg.sender)
        wire.clear()
        for r, (vl, vr) in cmds.items():
            world.set_wheels(r, vl, vr)
        world.advance(0.128)
