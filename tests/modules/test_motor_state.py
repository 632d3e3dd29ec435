"""The motor module's bookkeeping without Zenoh or the controller: lockstep completeness,
repeats for re-published ticks, staleness in real time."""

import numpy as np
import pytest

from cekm_swarm.modules.motor import MotorState, stamp_of
from cekm_swarm.protocol import ObstacleField, TargetField

N = 12


def fake_integrate(calls):
    def integrate(target, obstacles):
        calls.append((target, [o.index for o in obstacles], [o.stamp for o in obstacles]))
        return (0.0 if target is None else float(target.winner), float(len(obstacles)))
    return integrate


def obstacle(t, j, seen=True):
    return ObstacleField(t, f"r1/obstacle-{j}", j, 1 if seen else None, np.ones(4) if seen else None)


def target(t, winner=2):
    return TargetField(t, "r1/target", winner, np.ones(8), 0.1, 0.5)


def test_lockstep_sends_once_when_the_even_tick_is_complete():
    calls = []
    m = MotorState(fake_integrate(calls), lockstep=True)
    t = stamp_of(0)
    for j in range(N):
        assert m.put(obstacle(t, j)) == []
    assert m.missing(t) == ["target"]
    out = m.put(target(t))
    assert out == [(t, 2.0, 12.0)]
    assert calls[-1][1] == list(range(N))  # obstacles combined in index order
    assert m.commands == 1


def test_lockstep_odd_tick_uses_the_latest_target_field():
    calls = []
    m = MotorState(fake_integrate(calls), lockstep=True)
    t0, t1, t2 = stamp_of(0), stamp_of(1), stamp_of(2)
    m.put(target(t0))
    for j in range(N):
        m.put(obstacle(t0, j))
    # tick 1 (odd): no target reading; complete with the 12 obstacle fields, arriving in any order
    out = []
    for j in reversed(range(N)):
        out += m.put(obstacle(t1, j))
    assert out == [(t1, 2.0, 12.0)]
    assert calls[-1][0].stamp == t0
    # tick 2 (even): the old target field is not enough
    for j in range(N):
        assert m.put(obstacle(t2, j)) == []
    assert m.missing(t2) == ["target"]
    assert m.put(target(t2, winner=5)) == [(t2, 5.0, 12.0)]


def test_lockstep_waits_for_a_missing_obstacle_field_and_repeats_on_republish():
    m = MotorState(fake_integrate([]), lockstep=True)
    t0 = stamp_of(0)
    m.put(target(t0))
    for j in range(N):
        if j != 7:
            assert m.put(obstacle(t0, j)) == []
    assert m.missing(t0) == ["obstacle-7"]
    assert m.put(obstacle(t0, 7)) == [(t0, 2.0, 12.0)]
    # the world re-publishes tick 0: every re-sent field is answered with the same command
    assert m.put(obstacle(t0, 3)) == [(t0, 2.0, 12.0)]
    assert m.repeats == 1 and m.commands == 1
    # a late field of an older tick changes nothing
    assert m.put(obstacle(stamp_of(0), 3)) == [(t0, 2.0, 12.0)]


def test_lockstep_keeps_fields_per_tick_so_a_stray_stamp_displaces_nothing():
    """A field of a later tick (a peer's, or early) arriving before the current tick's own
    does not hide the current tick's field; a field of a tick already answered is dropped
    and counted."""
    calls, dropped = [], []
    m = MotorState(fake_integrate(calls), lockstep=True, drop=lambda msg, why: dropped.append((msg.stamp, why)))
    t0, t1, t5 = stamp_of(0), stamp_of(1), stamp_of(5)
    m.put(target(t0))
    m.put(obstacle(t5, 0))  # ahead: kept for its own tick
    out = []
    for j in range(N):
        out += m.put(obstacle(t0, j))
    assert out == [(t0, 2.0, 12.0)] and calls[-1][2] == [t0] * N
    for j in range(N):
        out += m.put(obstacle(t1, j))
    assert out[-1] == (t1, 2.0, 12.0)
    assert m.put(obstacle(t0, 3)) == [] and dropped == [(t0, dropped[0][1])]
    assert "answered" in dropped[0][1]
    # the target reading tick 1 used, re-published while the world waits for tick 2: not a drop
    assert m.put(target(t0)) == [] and len(dropped) == 1
    assert m.missing(t5) == ["target"] + [f"obstacle-{j}" for j in range(1, N)]


def test_realtime_every_integrates_on_every_field_with_the_latest_of_each():
    calls = []
    m = MotorState(fake_integrate(calls), integrate_on="every")
    assert m.put(obstacle(0.0, 0)) == [(0.0, 0.0, 1.0)]  # no target yet: the robot stops (c = 0 via integrate)
    assert m.put(target(0.0)) == [(0.0, 2.0, 1.0)]
    assert m.put(obstacle(0.0, 1)) == [(0.0, 2.0, 2.0)]
    assert m.commands == 3


def test_realtime_drops_a_stale_obstacle_field_and_counts_it_once():
    calls = []
    m = MotorState(fake_integrate(calls), integrate_on="every")
    for k in range(3):
        t = stamp_of(k)
        m.put(target(stamp_of(k - k % 2)))
        for j in range(N):
            if not (j == 4 and k > 0):  # sensor 4's module died after tick 0
                m.put(obstacle(t, j))
    # at tick 2 sensor 4's field is 0.256 s old: at the limit, still used
    assert 4 in calls[-1][1]
    m.put(obstacle(stamp_of(3), 0))
    assert 4 not in calls[-1][1] and len(calls[-1][1]) == N - 1
    m.put(obstacle(stamp_of(3), 1))
    assert m.stale_drops == {"obstacle-4": 1}
    # the restarted module's fresh field is used again
    m.put(obstacle(stamp_of(3), 4))
    assert 4 in calls[-1][1]


def test_realtime_stale_target_means_no_target():
    calls = []
    m = MotorState(fake_integrate(calls), integrate_on="every")
    m.put(target(0.0))
    m.put(obstacle(stamp_of(4), 0))  # 0.512 s later: at the limit
    assert calls[-1][0] is not None
    m.put(obstacle(stamp_of(5), 0))
    assert calls[-1][0] is None
    assert m.stale_drops == {"target": 1}


def feed_tick(m, k, skip=(), with_target=True):
    """Tick k's fields in a real-time order: obstacles, then (target ticks) the target; the commands sent."""
    t, out = stamp_of(k), []
    for j in range(N):
        if j not in skip:
            out += m.put(obstacle(t, j))
    if with_target and k % 2 == 0:
        out += m.put(target(t))
    return out


def test_realtime_tick_sends_one_command_once_the_ticks_fields_are_in():
    calls = []
    m = MotorState(fake_integrate(calls))
    assert feed_tick(m, 0) == [(0.0, 0.0, 1.0)]  # start-up: no source known yet, the first field is the tick
    for k in (1, 2, 3):
        t = stamp_of(k)
        assert feed_tick(m, k) == [(t, 2.0, 12.0)]
        assert calls[-1][2] == [t] * N  # every obstacle field of this tick
    # on a target tick the command waits for the target field too
    t4 = stamp_of(4)
    assert sum((m.put(obstacle(t4, j)) for j in range(N)), []) == []
    assert m.put(target(t4, winner=7)) == [(t4, 7.0, 12.0)]
    assert m.commands == 5  # ticks 0-4, one each


def test_realtime_tick_sends_the_last_tick_when_the_next_one_begins_first():
    calls = []
    m = MotorState(fake_integrate(calls))
    feed_tick(m, 0)
    feed_tick(m, 1)
    assert feed_tick(m, 2, skip={4}) == []  # obstacle 4's field of tick 2 is late: no command yet
    t2, t3 = stamp_of(2), stamp_of(3)
    assert m.put(obstacle(t3, 0)) == [(t2, 2.0, 12.0)]  # tick 3 began: tick 2's command, with 4's older field
    assert calls[-1][2][4] == stamp_of(1)
    # the late field of tick 2 arrives now: kept (it is 4's newest), no command of its own
    assert m.put(obstacle(t2, 4)) == []
    assert sum((m.put(obstacle(t3, j)) for j in range(1, N)), []) == [(t3, 2.0, 12.0)]


def test_realtime_tick_stops_waiting_for_a_dead_source_after_its_staleness_limit():
    calls = []
    m = MotorState(fake_integrate(calls))
    for k in range(3):
        feed_tick(m, k)
    # obstacle 4's module dies after tick 2: ticks 3 and 4 wait for it, each sent when the next begins
    assert feed_tick(m, 3, skip={4}) == []
    assert feed_tick(m, 4, skip={4}) == [(stamp_of(3), 2.0, 12.0)]
    # tick 5: 4's last field (tick 2) is past 0.256 s: not waited for, the tick is sent at once without it
    assert feed_tick(m, 5, skip={4}) == [(stamp_of(4), 2.0, 12.0), (stamp_of(5), 2.0, 11.0)]
    assert m.stale_drops == {"obstacle-4": 1}


def test_realtime_tick_refused_field_keeps_the_command_it_released():
    dropped = []
    m = MotorState(fake_integrate([]), drop=lambda msg, why: dropped.append(why))
    feed_tick(m, 0)
    feed_tick(m, 1, skip={3})
    m.put(obstacle(stamp_of(2), 3))  # obstacle 3 is at tick 2 now
    # tick 2 began with tick 1 unsent: obstacle 3's stale tick-1 field releases tick 1's command and is refused
    assert m.put(obstacle(stamp_of(1), 3)) == []
    out = m.put(obstacle(stamp_of(3), 5))
    assert out == [(stamp_of(2), 2.0, 12.0)] and len(dropped) == 1


@pytest.mark.parametrize("k", [0, 1, 2, 3, 100, 101])
def test_target_stamp_for_a_tick(k):
    m = MotorState(fake_integrate([]))
    assert m.target_stamp_for(stamp_of(k)) == stamp_of(k - k % 2)
