"""The world's side of held readings: a reading the plan lets it hold is left out while it
equals the last one sent, and the robot's ``sense/unchanged`` names it with the time it
was sent; it is sent anyway after HOLD_TICKS ticks out, and a stalled tick published
again sends every reading."""

from __future__ import annotations

from collections import Counter

from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import DropCounter, Unchanged, decode
from cekm_swarm.ticks import tick_time
from world import World, load_scenario
from world.publisher import HOLD_TICKS, TickPublisher
from world.recorder import RecordFilter
from world.run_episode import make_episode


class Wire:
    """Stands in for the world's publishers: what was put, per tick."""

    def __init__(self):
        self.sent: list[tuple[str, bytes]] = []

    def put(self, key, payload):
        self.sent.append((key, payload))


def publisher(hold=True):
    world = World(load_scenario("lone_obstacle"))
    episode = make_episode(world, "navigation")
    plan = check_graph("cekm-tuned-navigation").plan(("r1",), "navigation")
    held = {"r1": set(plan.held_readings("r1"))} if hold else None
    pub = TickPublisher(K, world, episode, {"r1": set(plan.world_keys("r1"))},
                        RecordFilter(K, ["r1"], DropCounter("test", keys=K)), held)
    pub.pubs = Wire()
    return pub, episode


def tick(pub, episode):
    """One tick of a robot standing still (its readings do not change)."""
    before = len(pub.pubs.sent)
    readings = episode.readings()
    pub.publish(readings)
    episode.apply({"r1": (0.0, 0.0)})
    episode.advance()
    return readings, [(k, decode(k, p)) for k, p in pub.pubs.sent[before:]]


def test_a_robot_standing_still_gets_its_unchanged_readings_named_not_sent():
    pub, ep = publisher()
    _, first = tick(pub, ep)
    ranges = {K.sense_range("r1", j) for j in range(12)}
    assert ranges <= {k for k, _ in first} and K.sense_unchanged("r1") not in {k for k, _ in first}
    _, second = tick(pub, ep)
    keys = [k for k, _ in second]
    assert keys[0] == K.sense_unchanged("r1")  # before the readings
    unchanged = second[0][1]
    assert isinstance(unchanged, Unchanged) and unchanged.stamp == tick_time(1)
    left_out = {f"cekm/r1/{k}" for k in unchanged.keys}
    assert left_out and not left_out & set(keys)  # named, not sent
    assert set(unchanged.since) == {0.0}
    # whatever changed (noise on a reading in range) is sent, and nothing is both
    assert (ranges - left_out) <= set(keys)
    assert pub.left_out == len(left_out)


def test_a_held_reading_is_sent_again_after_hold_ticks_and_on_a_republish():
    pub, ep = publisher()
    sent_at: dict[str, list[int]] = {}
    for k in range(3 * (HOLD_TICKS + 1)):
        _, out = tick(pub, ep)
        for key, _ in out:
            sent_at.setdefault(key, []).append(k)
    for j in range(12):
        ticks = sent_at[K.sense_range("r1", j)]
        gaps = [b - a for a, b in zip(ticks, ticks[1:], strict=False)]
        assert max(gaps) <= HOLD_TICKS + 1, (j, ticks)
    quiet = [j for j in range(12) if len(sent_at[K.sense_range("r1", j)]) <= 4]
    assert quiet  # most sensors see nothing: sent once every HOLD_TICKS + 1 ticks only
    before = len(pub.pubs.sent)
    pub.recorder = type("Log", (), {"write": lambda self, *a: None})()
    pub.republish(ep.readings(), ["r1"])
    again = {k for k, _ in pub.pubs.sent[before:]}
    assert {K.sense_range("r1", j) for j in range(12)} <= again


def test_held_readings_are_sent_again_each_in_its_own_tick_of_the_cycle():
    pub, ep = publisher()
    tick(pub, ep)  # tick 0 sends everything
    sent_at: dict[str, list[int]] = {}
    for k in range(1, 2 * HOLD_TICKS + 1):
        _, out = tick(pub, ep)
        for key, _ in out:
            sent_at.setdefault(key, []).append(k)
    quiet = [K.sense_range("r1", j) for j in range(12) if len(sent_at.get(K.sense_range("r1", j), [])) <= 2]
    assert len(quiet) >= 6
    for key in quiet:  # a standing robot's unchanged reading: once a cycle, in its own phase
        assert [k % HOLD_TICKS for k in sent_at[key]] == [pub.phase[key]] * 2, (key, sent_at[key])
    per_tick = Counter(pub.phase.values())  # the cycle's ticks in turn: one key a tick here
    assert sorted(per_tick) == list(range(len(pub.phase))) and set(per_tick.values()) == {1}


def test_a_robot_whose_node_rejoined_gets_every_reading_next_tick():
    pub, ep = publisher()
    for _ in range(3):
        _, out = tick(pub, ep)
    ranges = {K.sense_range("r1", j) for j in range(12)}
    assert not ranges <= {k for k, _ in out}  # held: some left out
    pub.rejoined("r1")
    _, out = tick(pub, ep)
    assert ranges <= {k for k, _ in out}
    _, out = tick(pub, ep)
    assert not ranges <= {k for k, _ in out}  # and held again after


def test_without_holding_every_reading_is_sent_every_tick():
    pub, ep = publisher(hold=False)
    for _ in range(3):
        _, out = tick(pub, ep)
        assert {K.sense_range("r1", j) for j in range(12)} <= {k for k, _ in out}
        assert K.sense_unchanged("r1") not in {k for k, _ in out}
