"""What the world's recorder takes from other sessions (world.recorder.RecordFilter)."""

import numpy as np

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import DropCounter, ObstacleField, WheelCommand, encode
from cekm_swarm.ticks import tick_time
from world.recorder import RecordFilter


def test_only_this_runs_keys_with_decodable_messages_and_believable_stamps_are_recorded():
    drops = DropCounter("test")
    f = RecordFilter(K, ["r1"], drops)
    now = tick_time(100)
    cmd = encode(WheelCommand(tick_time(99), "r1/motor", 0.1, 0.1, 3))
    assert f.check(K.cmd_wheels("r1"), cmd, now) == tick_time(99)
    field = encode(ObstacleField(now, "r1/obstacle-2", 2, 1, np.ones(4)))
    assert f.check(K.field_obstacle("r1", 2), field, now) == now
    refused = [
        (K.cmd_wheels("r2"), cmd),  # a robot this run does not have
        ("cekm/fuzz/1", cmd),  # not a key of the key space
        (K.cmd_wheels("r1"), b"\xc1"),  # not msgpack
        (K.cmd_wheels("r1"), encode(WheelCommand(1e18, "x", 0.0, 0.0, 0))),  # far future
        (K.cmd_wheels("r1"), encode(WheelCommand(tick_time(101), "x", 0.0, 0.0, 0))),  # ahead of the world's clock
        (K.cmd_wheels("r1"), encode(WheelCommand(tick_time(50), "x", 0.0, 0.0, 0))),  # an old tick
        (K.cmd_wheels("r1"), encode(WheelCommand(now - 0.05, "x", 0.0, 0.0, 0))),  # not a tick's time
    ]
    for key, payload in refused:
        assert f.check(key, payload, now) is None, key
    assert drops.total == len(refused)
    assert drops.count(K.cmd_wheels("r1")) == 5


def test_the_reason_a_key_is_not_recorded_says_what_the_key_is():
    """With the run's graph: outside messages on the world's own readings are not recorded
    (the reason was "not a key of this run's world or of its graph's nodes", though the
    world publishes them); a key no node sends on, a robot of another run and a key
    outside the key space each say so."""
    drops = DropCounter("test")
    f = RecordFilter(K, ["r1"], drops, declared={K.cmd_wheels("r1"): "cmd/wheels"})
    now = tick_time(100)
    cmd = encode(WheelCommand(tick_time(99), "r1/motor", 0.1, 0.1, 3))
    assert f.check(K.cmd_wheels("r1"), cmd, now) == tick_time(99)
    cases = {
        K.sense_range("r1", 0): "a key only the world publishes",
        K.sense_unchanged("r1"): "a key only the world publishes",
        K.field_obstacle("r1", 2): "not a key this run's graph's nodes send on",
        K.cmd_wheels("r2"): "robot 'r2' is not a robot of this run",
        "cekm/fuzz/1": "robot 'fuzz' is not a robot of this run",
        "other/r1/cmd/wheels": "key outside this run's key space",
    }
    for key in cases:
        for _ in range(2):  # the second time from the memo
            assert f.check(key, cmd, now) is None, key
    first = {r.source: r.first_reason for r in drops.records()}
    assert first.keys() == cases.keys() and drops.total == 2 * len(cases)
    for key, reason in cases.items():
        assert first[key].startswith(reason), (key, first[key])
    assert "world or of its graph" not in " ".join(first.values())
